// Step 1: geometric calibration with the local product-of-exponentials error model.
//
// All geometric error is put into the n+1 initial pose matrices (docs/method.md eq. 7–9):
// T_{k,k+1}(0) ← T_{k,k+1}(0)·exp(δt_k). Each measured row contributes its tip position
// error (3 rows) and, when measured, its rotation error (3 rows), each weighted by the
// tracker's stated 1-σ noise, so the lever arm to a distant tracker does not leak rotation
// noise into position (docs/method.md, step 1, "Weight by the instrument"). Gauss–Newton with
// a truncated-SVD pseudo-inverse: unobservable parameter combinations get no update and are
// reported.
#pragma once

#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"

namespace stepcal::trainer {

/// Which initial poses are identified.
enum class GeometricScope {
  kFramesOnly,  ///< tracker (T_{0,1}) and tool (T_{n,n+1}) only: registration of both frames
  kFullPoe,     ///< every initial pose: the full local-POE model (docs/method.md eq. 7)
};

struct GeometricOptions {
  GeometricScope scope = GeometricScope::kFullPoe;
  int max_iterations = 20;
  /// Converged when the weighted cost drops by less than this fraction in one iteration.
  double relative_cost_tolerance = 1e-9;
  /// Singular values below this fraction of the largest count as unobservable.
  double rank_tolerance = 1e-9;
  /// With several sessions: the joint frames T_{k,k+1} (1 ≤ k < n) each session fits its own, as
  /// its tracker registration and tool; empty: every joint frame shared.
  std::vector<int> own_frames;
};

/// Fit statistics of one Gauss–Newton iteration (before its update).
struct IterationRecord {
  int iteration = 0;
  double rms_position_m = 0.0;     ///< RMS tip position error of the fit rows
  double rms_orientation_rad = 0.0;  ///< RMS rotation error of rows with orientation
  double weighted_cost = 0.0;      ///< Σ ((error)/σ)², dimensionless
};

/// A parameter combination that the data cannot observe.
struct UnobservableCombination {
  std::string description;  ///< e.g. "rotation about joint_2's axis (joint zero)"
  bool structural = false;  ///< true: no data can observe it (a redundancy of the model)
};

/// Rank and conditioning of the (weighted, column-normalised) identification matrix.
struct Observability {
  int parameter_count = 0;
  int rank = 0;
  double condition_number = 0.0;  ///< σ_max / σ_min over the retained singular values
  std::vector<UnobservableCombination> unobservable;
};

/// One session of measurements: a campaign measured from its own tracker station, perhaps with
/// the target remounted. Its tracker registration T_{0,1} and its tool T_{n,n+1} are its own; the
/// joint frames between them are the robot's, one for every session.
struct GeometricSession {
  std::vector<const Measurement*> rows;  ///< its fit rows
  TrackerNoise noise;                    ///< its tracker's stated noise (weights its rows)
};

/// A session's frames and fit after the calibration.
struct SessionFrames {
  KinematicChain chain_Tracker;  ///< the calibrated robot in this session's tracker frame, its tool
  Pose X_TrackerBase;            ///< closed-form registration (base_link in tracker), before the fit
  int fit_rows = 0;
  double rms_position_m = 0.0;       ///< RMS tip position error of its fit rows, final
  double rms_orientation_rad = 0.0;  ///< RMS rotation error of its rows with orientation, final
};

struct GeometricResult {
  KinematicChain chain_Tracker;  ///< calibrated chain, root = tracker frame (the first session's)
  Pose X_TrackerBase;            ///< closed-form registration (base_link in tracker), first session
  std::vector<SessionFrames> sessions;  ///< one per session, in the order given
  std::vector<IterationRecord> history;  ///< one entry per iteration, then the final state
  int iterations = 0;            ///< Gauss–Newton updates applied
  bool converged = false;
  Observability observability;
  int fit_rows = 0;
  /// The joint frames T_{k,k+1} each session has its own (GeometricOptions::own_frames), the
  /// others shared; empty with one session.
  std::vector<int> own_frames;
  /// Covariance factor F of the first session's 6(n+1) initial-pose parameters (the rows in
  /// parameterJacobian's order), Σ = F Fᵀ, 6(n+1) × rank: the fit's (JᵀJ)⁺ on the directions it
  /// observes (rows weighted by the stated noise), times the reduced χ² when above 1.
  Eigen::MatrixXd covariance_factor;
};

/// Calibrates the chain (rooted at base_link) on the given rows. Throws InputError when the
/// rows are too few or their joint count disagrees with the chain.
GeometricResult calibrateGeometry(const KinematicChain& nominal_Base,
                                  const std::vector<const Measurement*>& rows,
                                  const TrackerNoise& noise, const GeometricOptions& options = {});

/// Calibrates one robot on several sessions at once: shared joint frames, each session's own
/// tracker registration and tool. One session is calibrateGeometry on its rows. Throws InputError
/// (naming the session, from 1) when a session's rows are too few or their joint count disagrees.
GeometricResult calibrateGeometry(const KinematicChain& nominal_Base,
                                  const std::vector<GeometricSession>& sessions,
                                  const GeometricOptions& options = {});

/// A session's value of a joint frame T_{k,k+1} against the first session's, in the terms of the
/// joint k+1 whose initial pose it is, with 1-σ from the fit with this frame each session's own
/// on every row (the tracker's stated noise, times the reduced χ² when above 1). Only what the
/// rows determine: a direction in which the frame trades with the session's own registration or
/// tool (joint 1's zero, joint n's zero, a translation along their axes) is left out.
struct FrameDifference {
  /// Whether the joint's zero is determined: false when it trades with the session's own tool
  /// (the last joint) and the rows cannot tell them apart.
  bool zero_determined = true;
  /// The rotation about joint k+1's axis: the session's link angle minus the first's at the same
  /// reading (its zero offset), rad; and its 1-σ, rad.
  double zero_offset_rad = 0.0, zero_offset_sigma_rad = 0.0;
  /// The rest of the frame's rotation (about axes across the joint's), its size and 1-σ, rad.
  double other_rotation_rad = 0.0, other_rotation_sigma_rad = 0.0;
  /// The rest of the frame's translation, its size and 1-σ, m.
  double translation_m = 0.0, translation_sigma_m = 0.0;
  /// Directions of the difference the rows do not determine (left out of the sizes above).
  int undetermined_directions = 0;
};

/// Whether one value of a joint frame serves every session, judged on rows held out.
struct SessionDifference {
  int frame = 0;         ///< the initial pose T_{k,k+1}, 1 ≤ k < n
  std::string name;      ///< e.g. "T(joint_2->joint_3)"
  std::string joint;     ///< joint k+1, whose initial pose the frame is: its zero turns the frame
  /// Mean held-out position error of the rows with every joint frame shared minus with this one
  /// each session's own, m (positive: the own frames predict better).
  double held_out_gain_m = 0.0;
  /// Mean held-out position error of the rows with every joint frame shared, m (the same for
  /// every frame): the gain's share of it says whether the difference matters.
  double shared_held_out_m = 0.0;
  double z_statistic = 0.0;  ///< one-sided signed-rank z of the rows' held-out squared errors
  bool significant = false;  ///< z above the one-sided 1 % point (kSessionDifferenceZ)
  /// Whether the final fit keeps this frame each session's own (keepsOwnFrame): significant and
  /// its held-out gain at least kSessionDifferenceLeastShare of the held-out error.
  bool kept_per_session = false;
  /// Per session, its own frame against the first session's, fitted on every row: log(T₁⁻¹ T_s)
  /// (v [m], ω [rad]); the first is zero.
  /// Part of it trades with the session's own registration and tool (a difference the rows
  /// barely see can be large): the held-out gain, not its size, says whether it matters.
  std::vector<Vec6> differences;
  /// Per session, the same in the joint's terms with 1-σ (FrameDifference); the first is zero.
  std::vector<FrameDifference> against_first;
};

/// One-sided 1 % point of the standard normal: a frame's difference between sessions is named
/// when the held-out reduction's signed-rank z exceeds it.
inline constexpr double kSessionDifferenceZ = 2.326;

/// Least share of the held-out error with every frame shared that a frame's own values per session
/// must remove to be kept per session in the final fit. Significance alone is not enough: with
/// thousands of rows, a frame that absorbs a cause the geometry cannot take differently in each
/// session is significant for a gain of a few µm, and keeping it per session undoes the pooling.
/// Measured: a joint zero moved 300 µrad between two twin campaigns removes ~70 % of the
/// held-out error (72 % held out; 0.0577 → 0.0174 mm on the moved campaign's validation rows); on
/// the real UR10 the significant frames of any three of its four series remove at most 8.6 %
/// (0.003–0.038 mm of ~0.45 mm; re-measured by tools/ur10_sessions.sh: 0.01–8.3 % of
/// 0.40–0.45 mm). 20 % lies far from both: a change of the robot removes most of the error.
inline constexpr double kSessionDifferenceLeastShare = 0.20;

/// The held-out gain's share of the held-out error with every frame shared (0 when that is 0).
double heldOutShare(const SessionDifference& difference);

/// Whether the final fit keeps a frame each session's own: significant, and its held-out gain at
/// least kSessionDifferenceLeastShare of the held-out error with every frame shared.
bool keepsOwnFrame(const SessionDifference& difference);

/// Per joint frame, whether the sessions need their own value: k-fold cross-validation over each
/// session's poses (pose_id), every frame shared against this one each session's own. Empty
/// with one session, or when a session has fewer than 2·folds poses. Throws as calibrateGeometry.
std::vector<SessionDifference> testSessionDifferences(const KinematicChain& nominal_Base,
                                                      const std::vector<GeometricSession>& sessions,
                                                      const GeometricOptions& options = {},
                                                      int folds = 5);

/// Names of the 6(n+1) parameters, e.g. "T(joint_1→joint_2).ωy".
std::vector<std::string> parameterNames(const KinematicChain& chain);

}  // namespace stepcal::trainer
