// The diagnosis's fit rows as noise-weighted equations, the physical model's residual on them and
// its linearisation (internal to stepcal::trainer).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/mechanisms.hpp"

namespace stepcal::trainer::diagnosis {

/// The fit rows as noise-weighted equations: 3 position rows, then 3 rotation rows when measured.
struct FitRows {
  std::vector<const Measurement*> rows;
  std::vector<int> start;  ///< first equation of each row
  std::vector<int> fold;   ///< cross-validation fold of each row (all rows of a pose in one fold)
  std::vector<int> pose;   ///< pose group of each row
  int count = 0, poses = 0, folds = 0;
  double w_p = 1.0, w_r = 1.0;  ///< 1/σ of the tracker: 1/m, 1/rad
  int equations(size_t row) const { return rows[row]->has_orientation ? 6 : 3; }
};

/// The tracker's frame as it last stood, in the frame a registration_drift was fitted in (the
/// drift's mean over the fit rows): exp of the drift's mean over the last tenth of its time span
/// (a polynomial is least determined at its very end). The extended model's tracker frame.
Pose X_FittedLast(const Mechanism& drift);

/// What stands between the model and a row's measurement: the tracker's registration drift in
/// time order, and, where several campaigns are fitted together, each later campaign's own
/// tracker station and tool (session_frames; the first campaign's are the chain's own) and its
/// joints' zeros (campaign_joint_zero).
struct MeasurementFrames {
  const Mechanism* drift = nullptr;  ///< the model's registration_drift, if any
  std::vector<std::optional<StationAndTool>> sessions;  ///< per campaign index, where it has own
  std::vector<JointVector> zero_offset_rad;  ///< per campaign index: δ per joint (empty: none)
  /// The campaign's own station and tool of a row, null for the chain's own.
  const StationAndTool* ownFrames(const Measurement& row) const;
  /// The row's recorded joint angles in the first campaign's readings: q + δ of its campaign.
  JointVector commanded(const Measurement& row) const;
  /// The model's tip pose X (first campaign's tracker and tool) as the row's tracker measures it.
  Pose measured(const Measurement& row, const Pose& X_TipInTracker) const;
};
/// A model's measurement frames (pointers into model: valid while it lives and is unchanged).
MeasurementFrames measurementFramesOf(const PhysicalModel& model);

/// Throws InputError naming the file and line of the first row whose joint count is not n.
void requireJointCount(const Campaign& campaign, int n);

/// Folds are a fixed shuffle of the poses: the same campaign gives the same folds.
FitRows makeFitRows(const std::vector<const Measurement*>& rows, const TrackerNoise& noise,
                    int folds);

/// First equation of fit row i (fit.count for i = rows).
inline Eigen::Index equationOf(const FitRows& fit, size_t i) {
  return i < fit.rows.size() ? fit.start[i] : fit.count;
}

/// Fit rows [begin, end)'s equations of a vector with an entry per fit equation.
inline auto equationsOf(const Eigen::VectorXd& v, const FitRows& fit, size_t begin, size_t end) {
  const Eigen::Index first = equationOf(fit, begin);
  return v.segment(first, equationOf(fit, end) - first);
}

// Each function below has two forms: on every fit row, on the machine's cores, and on the chunk
// of fit rows [begin, end) alone, on the calling thread (its equations numbered from
// equationOf(fit, begin)). A row's values are the same in both.

/// The physical model on the fit rows: weighted residual (measured − modelled), and per row
/// the link angles θ [rad] and joint torques τ [N·m] of the model.
struct Evaluation {
  Eigen::VectorXd r;
  std::vector<JointVector> theta_rad, tau_nm;
};
Evaluation evaluate(const PhysicalModel& model, const FitRows& fit);
Evaluation evaluate(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end);
/// The weighted residual alone.
Eigen::VectorXd residuals(const PhysicalModel& model, const FitRows& fit);
Eigen::VectorXd residuals(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end);

/// d(modelled)/d(parameter) in the residual's weighting (r(x + dx) ≈ r − A dx): the 6(n+1)
/// initial-pose corrections (docs/method.md eq. 7) and each link angle θ_j (the tip's motion per
/// radian of joint j at the model's link angles; the torques' change with θ is left out).
struct Linearisation {
  Eigen::MatrixXd geometry;    ///< count × 6(n+1)
  Eigen::MatrixXd link_angle;  ///< count × n
};
Linearisation linearise(const PhysicalModel& model, const FitRows& fit, const Eigen::VectorXd& r);
/// r: the chunk's residual (its equations).
Linearisation linearise(const PhysicalModel& model, const FitRows& fit, size_t begin, size_t end,
                        const Eigen::VectorXd& r);
/// Finite-difference columns (r0 − r_k) / step_k of models k on fit rows [begin, end), on the
/// calling thread (r0: the residual they differ from, on those rows' equations; a column that
/// `needed` does not mark is left zero): equations × models. A row's models are evaluated one
/// after another, sharing the frames of their fixed point at θ₀ where they can (FirstPass): the
/// values of residuals.
Eigen::MatrixXd differenceColumns(const std::vector<const PhysicalModel*>& models,
                                  const std::vector<double>& steps,
                                  const std::vector<bool>& needed, const FitRows& fit,
                                  size_t begin, size_t end, const Eigen::VectorXd& r0);
/// evaluate and linearise of fit rows [begin, end) at once, on the calling thread: a row whose
/// links the model does not scale is linearised where it was evaluated (one evaluation of the
/// model for both; the same values).
void evaluateAndLinearise(const PhysicalModel& model, const FitRows& fit, size_t begin,
                          size_t end, Evaluation& evaluation, Linearisation& lin);

}  // namespace stepcal::trainer::diagnosis
