// The cell around the calibrated robot (docs/cell.md): its tool's centre point (TCP) and its work
// objects, fitted from poses the calibrated model predicts. The model's forward is the caller's
// (the CLI takes the runtime's, with its compliance and GPR); here only the geometry of the
// fits and their 1-σ. Every fit is a result, never an abort: too few or too similar poses say so.
#pragma once

#include <string>
#include <vector>

#include "stepcal/common/types.hpp"

namespace stepcal::trainer {

/// The least-varied direction of a tool fit's orientations is taken as too weak below this
/// spread (the angle by which two orientations would have to differ to see it as well): the TCP
/// along it is then known only to the touch scatter over sin(angle / 2).
inline constexpr double kLeastOrientationSpread_rad = 0.3490658503988659;  // 20°

/// The TCP as a point on the measured target (the model's tip), with its 1-σ.
struct ToolPointFit {
  Vec3 p_TcpInTip_m = Vec3::Zero();
  Mat3 covariance_TcpInTip_m2 = Mat3::Zero();
  /// The four-point method's touched point, tracker frame (zero for tracker rows).
  Vec3 p_FixedInTracker_m = Vec3::Zero();
  int points = 0;
  int redundancy = 0;          ///< equations − unknowns
  double rms_residual_m = 0;   ///< root mean square of the residuals' norms
  /// Per-axis scatter of one point, m: the residuals' √(RSS / redundancy), or the stated σ when
  /// larger (or when there is no redundancy). The covariance is the design's times its square.
  double point_sigma_m = 0;
  /// The spread of the orientations in their least-varied direction (see
  /// kLeastOrientationSpread_rad), and that direction in the target's axes.
  double least_spread_rad = 0;
  Vec3 least_spread_direction = Vec3::UnitZ();
  bool well_conditioned = true;
  std::string note;            ///< empty, or what is wrong and what to do
};

/// TCP from tracker measurements of a reflector at it: p_i = X_TrackerTip_i · p_TcpInTip (each
/// pose the model's at the row's joints). At least 2 rows; stated_sigma_m: the tracker's and the
/// model's per-axis σ at one point.
ToolPointFit fitToolFromTracker(const std::vector<Pose>& X_TrackerTip,
                                const std::vector<Vec3>& p_TcpInTracker_m, double stated_sigma_m);

/// The four-point method: one fixed point touched in several orientations,
/// X_TrackerTip_i · p_TcpInTip = p_Fixed for all i, solved jointly by linear least squares.
/// At least 3 touches (4 recommended); orientations too similar give a fit that says so.
ToolPointFit fitToolFromFixedPoint(const std::vector<Pose>& X_TrackerTip, double stated_sigma_m);

/// The TCP's axes measured: a 6-D target at the TCP (a T-Mac, an SMR nest with orientation)
/// gives R_TrackerTcp at each pose, the model R_TrackerTip; R_TipTcp is their mean, with its 1-σ.
struct ToolOrientationFit {
  Mat3 R_TipTcp = Mat3::Identity();
  /// Covariance of the rotation ω about the TCP's own axes, R = R̂ · exp(ω), rad².
  Mat3 covariance_rad2 = Mat3::Zero();
  int points = 0;
  double rms_residual_rad = 0;  ///< root mean square of the rows' angles from the mean
  /// Per-axis scatter of one row, rad: the residuals' √(Σ|ω_i|² / (3(n − 1))), or the stated σ
  /// when larger (or with one row). The covariance is its square over n.
  double row_sigma_rad = 0;
  std::string note;  ///< empty, or what is wrong
};

/// R_TipTcp from the model's target poses and the measured TCP orientations (tracker frame):
/// the chordal mean of R_TrackerTip_iᵀ · R_TrackerTcp_i projected onto SO(3). stated_sigma_rad:
/// one row's per-axis σ from the tracker and the model.
ToolOrientationFit fitToolOrientation(const std::vector<Pose>& X_TrackerTip,
                                      const std::vector<Mat3>& R_TrackerTcp,
                                      double stated_sigma_rad);

/// A work object's frame X_TrackerFrame fitted to points measured in the tracker frame, with the
/// 1-σ of its origin (along the frame's own axes, m) and of its rotation (about them, rad).
struct FrameFit {
  Pose X_TrackerFrame = Pose::Identity();
  /// Covariance of (origin shift, rotation) in the frame's own axes: X = X̂ · (δp, exp(δω)).
  Mat6 covariance = Mat6::Zero();
  int points = 0;
  int redundancy = 0;
  double rms_residual_m = 0;
  double point_sigma_m = 0;    ///< as ToolPointFit's
  std::string note;            ///< empty, or what is wrong
};

/// A measured point and, when it was touched with a fitted TCP, how it moves with that TCP.
struct FramePoint {
  Vec3 p_InTracker_m = Vec3::Zero();
  /// dp/dp_TcpInTip: the rotation of the touch's target (zero for a point the tracker measured).
  Mat3 dPointdTcp = Mat3::Zero();
};

/// The three-point method: the frame's origin, a point on its +x axis and a point in its xy
/// plane (+y side). covariance_TcpInTip_m2: the TCP's (zero for tracker points), carried into the
/// frame's σ beside each point's stated_sigma_m.
FrameFit fitFrameFromThreePoints(const FramePoint& origin, const FramePoint& on_x,
                                 const FramePoint& in_xy, double stated_sigma_m,
                                 const Mat3& covariance_TcpInTip_m2);

/// Least squares (Kabsch/Horn by SVD): X_TrackerFrame minimising Σ ‖p_i − X · n_i‖², from n ≥ 3
/// points p_i with known nominal coordinates n_i in the frame (not all on a line).
FrameFit fitFrameToFiducials(const std::vector<FramePoint>& measured,
                             const std::vector<Vec3>& p_NominalInFrame_m, double stated_sigma_m,
                             const Mat3& covariance_TcpInTip_m2);

}  // namespace stepcal::trainer
