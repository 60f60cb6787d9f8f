// The whole offline calibration of a campaign, step by step, with its accuracy tables.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/trainer/accuracy.hpp"
#include "stepcal/trainer/geometric.hpp"
#include "stepcal/trainer/gpr.hpp"
#include "stepcal/trainer/stiffness.hpp"

namespace stepcal::trainer {

struct CalibrationOptions {
  GeometricOptions geometric;
  StiffnessOptions stiffness;
  GprOptions gpr;
  /// Largest GPR training set; more residual rows are thinned evenly (keeps fit and the
  /// runtime's prediction time bounded: both grow with it).
  int gpr_max_points = 400;
};

/// One-sided 1 % point of the standard normal: a residual GP is taken when the signed-rank z of
/// its rows' cross-validated reduction exceeds it (its hyperparameters were chosen on the same
/// rows, so its cross-validated error is optimistic: a GP fitted to pure noise still shows a few
/// per cent of "gain").
inline constexpr double kGprTakenZ = 2.326;

/// A fitted residual GP and what it was trained on.
struct ResidualModel {
  GaussianProcess gp;
  GprFitReport report;
  int training_rows = 0;
  std::string training_set;  ///< "residual", or "geometry" when the campaign has no residual rows
  /// Its k-fold cross-validated squared error and that of no correction (the residual itself),
  /// per row the squares over the tracker's stated noise² summed over the outputs, mean over the
  /// rows; and the one-sided signed-rank z of the rows' reduction.
  double cv_error = 0.0, uncorrected_error = 0.0, z_statistic = 0.0;
  /// Whether the GP is taken: it reduces the held-out error significantly (z above the
  /// one-sided 1 % point, kGprTakenZ). Not taken, the layer is the model under it (its rows equal
  /// that model's) and no model file holds it.
  bool taken = true;
};

/// Everything the trainer found, for reports and the model file.
struct CalibrationOutcome {
  KinematicChain nominal_Base;     ///< the campaign's robot description
  int sensor_frame = -1;           ///< index of sensor_link in the chain's frames, −1 = none
  Pose X_TrackerBase_nominal;      ///< tracker registered to the nominal chain (closed form)
  GeometricResult frames;          ///< tracker and tool frames fitted, joints nominal
  GeometricResult poe;             ///< step 1: full local POE (docs/method.md eq. 7–9)
  /// With several sessions: per joint frame, whether one value serves them all (where the robot
  /// changed between them). The step-1 fit (poe) gives each session its own value of the frames
  /// named here (GeometricResult::own_frames), the others shared; the first session's are the
  /// model file's.
  std::vector<SessionDifference> session_differences;
  bool has_stiffness = false;      ///< step 2 ran (stiffness pairs and a sensor exist)
  StiffnessResult stiffness;       ///< step 2 (docs/method.md eq. 19–22)
  /// With several sessions: per joint, whether one compliance serves them all (step 2 keeps it
  /// shared); not tested with one session.
  ComplianceDifferences compliance_differences;
  std::vector<StiffnessValidation> stiffness_validation;  ///< on validation pairs, per load
  std::optional<ResidualModel> gpr;           ///< step 3 on the POE + stiffness residual
  /// The model file's accuracy factors (model_file.hpp): step 1's and step 2's covariance
  /// factors, the tracker's noise, raised to the physical model's residual scatter on the
  /// residual rows when no GPR is taken.
  AccuracyFactors accuracy_factors;
  std::optional<ResidualModel> gpr_baseline;  ///< "POE + GPR": step 3 on the POE residual
  std::vector<AccuracySummary> accuracy;  ///< every method on every (set, load) group
  /// Per session of a merged campaign (Campaign::sessions), every method on its rows alone, in
  /// the order of accuracy; empty for a campaign of one folder.
  std::vector<std::vector<AccuracySummary>> session_accuracy;
  /// Per-row errors of each method, aligned with the campaign's rows (for plots).
  std::vector<std::pair<std::string, std::vector<RowError>>> row_errors;
  double seconds_geometry = 0.0, seconds_stiffness = 0.0, seconds_gpr = 0.0;  ///< wall time
  double floor_position_m = 0.0;   ///< mean error the tracker noise alone gives
  double floor_orientation_rad = 0.0;
};

/// Method names in report order.
inline const char* const kMethodNominal = "nominal";
inline const char* const kMethodFrames = "frames";
inline const char* const kMethodPoe = "poe";
inline const char* const kMethodPoeStiffness = "poe+stiffness";
inline const char* const kMethodPoeGpr = "poe+gpr";
inline const char* const kMethodPoeStiffnessGpr = "poe+stiffness+gpr";
/// The physical model extended by `stepcal diagnose` (diagnose.hpp), and with its GPR.
inline const char* const kMethodExtended = "extended";
inline const char* const kMethodExtendedGpr = "extended+gpr";

/// GPR input of a row: x = (q [rad], wrench in sensor axes [N, N·m]) ∈ R^(n+6) (docs/method.md, step 3).
Eigen::VectorXd gprInput(const Measurement& row);

/// A row's temp_c, °C; NaN when it has none.
double rowTemperature(const Measurement& row);

/// Pose predictor of a physical model: the chain at the link angles of its compliance and
/// mechanisms (mechanisms.hpp; docs/method.md eq. 24).
PoseModel physicalPoseModel(PhysicalModel physical);

/// The model times the GP's predicted residual twist: T · exp(ξ̂) (docs/method.md eq. 32). gp must
/// outlive the predictor.
PoseModel withResidual(PoseModel base, const GaussianProcess& gp);
/// The model with a residual GP's correction where it was taken (ResidualModel::taken), else the
/// model itself. residual must outlive the predictor.
PoseModel withResidual(PoseModel base, const ResidualModel& residual);

/// What the residual GP learns: the residual twist itself (the paper's step 3), or the residual
/// per payload force, learnt on the loaded rows alone and applied times ‖f‖ / f_ref (docs/method.md
/// eq. 30a): a load effect linear in the payload is then a function of the pose alone, and the
/// correction at zero load is exactly zero.
enum class ResidualTarget { kResidual, kPerPayloadForce };

/// Step 3: residual twists ξ = log(T_model⁻¹ T_measured)^∨ (eq. 25) on the training rows,
/// thinned evenly to options.gpr_max_points; rows without orientation cannot give a 6-D twist
/// (per payload force: nor rows without a load, load_kg = 0 or no force read).
/// The tracker's stated noise bounds the GP's σ_n from below (GprOptions::output_noise_sigma:
/// position σ on v, orientation σ on ω, unless options.gpr gives its own) and weighs the
/// choice whether it is taken (ResidualModel::taken), judged on the residual itself.
/// Throws InputError when fewer than 2 rows are usable.
ResidualModel fitResidual(const PoseModel& model, const std::vector<const Measurement*>& rows,
                          const std::string& set_name, const TrackerNoise& noise,
                          const CalibrationOptions& options,
                          ResidualTarget target = ResidualTarget::kResidual);

/// Builds the campaign's chain from its URDF (base_link → tip_link, sensor_link attached as
/// frame 0, flange_link, if named, after it as the frame kFlangeFrameName). Throws InputError
/// naming the robot file when it does not fit the campaign.
KinematicChain campaignChain(const Campaign& campaign, int* sensor_frame = nullptr);

/// Runs every calibration step that exists on the campaign. A merged campaign (mergeCampaigns)
/// is one robot measured in several sessions: one geometry of the joints and one compliance, each
/// session with its own tracker registration and tool (GeometricResult::sessions), the GPR on the
/// residual rows of all. Throws InputError.
CalibrationOutcome calibrateCampaign(const Campaign& campaign, const CalibrationOptions& options = {});

/// The model file's contents for a calibrated campaign, with provenance (campaign hash,
/// creation time, trainer version, validation figures of every method).
CalibratedModel modelFromOutcome(const Campaign& campaign, const CalibrationOutcome& outcome);

/// Pose predictors for a model file's layers, in order: "poe" (the chain), then
/// "poe+stiffness" and "poe[+stiffness]+gpr" where the model holds those steps; for an extended
/// model (one with mechanisms), "extended" and "extended+gpr" (its chain was fitted with its
/// mechanisms and compliance, so it has no layer of its own).
std::vector<std::pair<std::string, PoseModel>> modelLayers(const CalibratedModel& model);

/// FNV-1a 64 of the campaign's robot description and rows as read, in hex: two campaigns
/// with the same hash hold the same data.
std::string campaignHash(const Campaign& campaign);

}  // namespace stepcal::trainer
