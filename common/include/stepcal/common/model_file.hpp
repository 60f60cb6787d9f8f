// The calibrated model file: everything the runtime needs to correct poses (docs/method.md eq. 32,
// T_C2 = T_C(q) · T_STIF(q, F) · T_GPR(q, F)), written once by the offline trainer.
//
// Layout (format version 4). Integers and doubles are little-endian, doubles IEEE-754 binary64:
//
//   header   24 B  magic "STEPCAL\0", u32 format version, u32 flags (0), u64 file size in bytes
//   sections       each u32 tag (FourCC), u32 reserved (0), u64 payload length, payload;
//                  these seven, in this order, then ACCU when the model has it:
//     "CHAN"  u32 n; n × {str name, f64 twist (v, ω)[6], f64 lower_rad, f64 upper_rad};
//             n+1 × pose T_{k,k+1}(0); u32 f; f × {str name, u32 parent, pose X_ParentFrame}
//     "NOMI"  the nominal chain, encoded as CHAN; same n and joint names as CHAN
//     "REGI"  pose X_TrackerBase; f64 gravity_Base[3]; i32 sensor_frame
//     "COMP"  u32 c (0 or n); f64 compliance_rad_per_nm[c]; f64 compliance_sigma_rad_per_nm[c]
//     "MECH"  u32 k (≤ 64); k × {u32 kind, i32 joint, i32 source_joint, i32 order, u32 p,
//             f64 parameters[p], f64 sigma[p], u32 a (≤ 32), f64 coverage arcs (start, length)
//             [2a], f64 coverage fade} (mechanisms.hpp: kinds, joints 0-based, −1 = none,
//             parameter layouts, AngleCoverage); each passes mechanismProblem; at most one
//             self_weight, sensor_bias and thermal_expansion, at most one transmission_error
//             and one profile_geometry per joint; a profile_geometry needs its joint's
//             transmission_error, sensor_bias a sensor frame (REGI), self_weight a nonzero
//             gravity (REGI)
//     "GPR "  u32 m, D, P (all 0 = no residual step); f64 input_offset[D], input_scale[D],
//             output_mean[P], output_scale[P], length_scales[D], signal_sigma, noise_sigma;
//             inputs_normalised, targets_standardised, alpha as m rows each
//     "PROV"  str campaign_hash, created_utc, trainer_version, campaign_path; u32 v;
//             v × {str method, f64 load_kg, i32 rows, f64 mean_position_m, max_position_m,
//             mean_orientation_rad}
//     "ACCU"  (optional; absent in files written before it, which load as before) u32 layout
//             version (2); f64 position_noise_m, orientation_noise_rad; u32 g (0 or 6(n+1)),
//             u32 r (≤ g); f64 geometry_factor[g × r]; u32 c (0 or n); f64
//             compliance_factor[c × c]; u32 k (≤ the mechanisms); k × {u32 mechanism (a
//             transmission_error's index in MECH, ascending), u32 r (≤ 2·order), f64
//             factor[2·order × r]} (AccuracyFactors; layout 1, without the profiles' factors,
//             is refused with a hint to re-run `stepcal calibrate` / `stepcal diagnose`)
//   trailer   4 B  u32 CRC-32 (IEEE 802.3) of every preceding byte
//
// pose = 12 f64, row-major [R | p]; str = u32 byte count (≤ 4096) then the bytes, no terminator.
// Every double is finite, except that a continuous joint's limits are −inf … inf.
// The GPR's Cholesky factor is not stored: the runtime refactors K + σ_n² I from the inputs and
// hyperparameters at load, and the loader checks α against the stored targets instead.
// Versions 1 (no MECH), 2 (transmission errors as single harmonics, no coverage) and 3
// (nonlinear stiffness and torsion curves without linear_above_nm) are refused with a hint to
// re-run `stepcal calibrate` / `stepcal diagnose`; there is no reader of old versions.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal {

/// Model file format version this build writes and reads.
inline constexpr uint32_t kModelFormatVersion = 4;
/// Largest number of mechanisms a model file holds.
inline constexpr uint32_t kMaxMechanisms = 64;

/// Gaussian-process residual model: shared squared-exponential ARD kernel over normalised
/// inputs, standardised outputs (docs/method.md eq. 27, 30).
struct GprParameters {
  Eigen::MatrixXd inputs_normalised;          ///< m × D training inputs after normalisation
  Eigen::VectorXd input_offset, input_scale;  ///< D: x_norm = (x_raw − offset) / scale
  Eigen::VectorXd output_mean, output_scale;  ///< P: y_raw = mean + scale ⊙ y_std
  Eigen::VectorXd length_scales;              ///< D, normalised input units
  double signal_sigma = 0, noise_sigma = 0;   ///< standardised output units
  Eigen::MatrixXd targets_standardised;       ///< m × P, lets the loader check α
  Eigen::MatrixXd alpha;                      ///< m × P, (K + σ_n² I)⁻¹ Y (eq. 30)
  /// 0: the paper's GPR, its output the residual itself (eq. 30). > 0, N: a GPR of the residual
  /// per payload force, its output times ‖f‖ / payload_force_reference_n, f the force of the
  /// wrench (inputs D−6 .. D−4), so its correction is exactly zero at zero load (eq. 30a).
  double payload_force_reference_n = 0;
};

/// One line of the accuracy table measured on held-out poses when the model was trained.
struct ValidationFigure {
  std::string method;  ///< e.g. "POE + stiffness + GPR"
  double load_kg = 0;
  int rows = 0;
  double mean_position_m = 0, max_position_m = 0, mean_orientation_rad = 0;
};

/// Where a model came from, so a runtime can say which campaign and trainer built it.
struct ModelProvenance {
  std::string campaign_hash;  ///< hex digits, empty = unknown
  std::string created_utc;    ///< ISO 8601
  std::string trainer_version;
  std::string campaign_path;
  std::vector<ValidationFigure> validation;
};

/// A transmission profile's coefficients' covariance as its factor: Σ_c = F Fᵀ. Fitted on an arc,
/// its harmonics trade with each other, so each alone is far less certain than the profile's
/// values on the arc; their σ taken as independent would state that too.
struct ProfileCovarianceFactor {
  uint32_t mechanism = 0;  ///< index into CalibratedModel::mechanisms: a transmission_error
  Eigen::MatrixXd factor;  ///< 2·order × r (r ≤ 2·order), rad; rows as its parameters
};

/// What the runtime needs to state how accurate a corrected pose is (docs/method.md, "The
/// accuracy bound"): the fitted parameters' covariance as factors F with Σ = F Fᵀ, so that a
/// pose's covariance is (J F)(J F)ᵀ with J its Jacobian w.r.t. the parameters, and the noise of
/// a measurement of the pose.
struct AccuracyFactors {
  /// Layout version of the ACCU section this build writes and reads.
  static constexpr uint32_t kLayoutVersion = 2;
  /// 1-σ per axis of a measured position and orientation (m, rad): the tracker's stated
  /// noise, raised to the model's residual scatter on the fit rows no GPR takes (none taken:
  /// every fit row; a GPR per payload force, which moves no unloaded row: the unloaded ones). A
  /// GPR's own white noise per output is added at run time (RuntimeModel::gpr_noise).
  double position_noise_m = 0.0, orientation_noise_rad = 0.0;
  /// 6(n+1) × r (or empty): the initial poses' right-perturbations δt_k (docs/method.md eq. 7,
  /// the rows ordered as parameterJacobian's columns), covariance F Fᵀ, r the fit's rank; the
  /// directions the rows do not observe carry none (they were left at their nominal values).
  Eigen::MatrixXd geometry_factor;
  /// n × n (or empty): the joint compliances' covariance factor, rad/(N·m); zero rows for the
  /// joints taken as rigid.
  Eigen::MatrixXd compliance_factor;
  /// The transmission profiles whose coefficients' covariance the fit gave, in ascending order of
  /// mechanism; a profile without one states its coefficients' σ as independent.
  std::vector<ProfileCovarianceFactor> profile_factors;
};

/// Everything the runtime needs to correct a pose.
struct CalibratedModel {
  /// Calibrated initial poses (tracker-rooted), joint twists, limits, names and attached frames
  /// (including the sensor frame).
  KinematicChain chain_Tracker;
  /// The robot description as the controller knows it: base-rooted, tool = the nominal tool
  /// frame, sensor frame attached. Its FK at the corrected joint targets is the pre-distorted
  /// pose the runtime sends. Same dof and joint names as chain_Tracker.
  KinematicChain nominal_Base;
  Pose X_TrackerBase = Pose::Identity();  ///< tracker registration
  int sensor_frame = -1;                  ///< index into chain_Tracker.frames(), −1 = no sensor
  Vec3 gravity_Base = Vec3::Zero();       ///< m/s²
  /// Empty = no compliance step; else n entries, C_θ = K_θ⁻¹ (eq. 19–22), rad/(N·m).
  JointVector compliance_rad_per_nm;
  JointVector compliance_sigma_rad_per_nm;  ///< 1-σ, same size, rad/(N·m)
  /// Mechanisms found by `stepcal diagnose` (empty: geometry and compliance only).
  std::vector<Mechanism> mechanisms;
  std::optional<GprParameters> gpr;         ///< absent = no residual step
  ModelProvenance provenance;
  /// Absent: a model written before the accuracy bound (no bound is stated).
  std::optional<AccuracyFactors> accuracy;
};

/// Empty when model.mechanisms[index] is well formed in this model: mechanismProblem for the
/// model's dof; not a second self_weight, sensor_bias or thermal_expansion after one among
/// mechanisms[0 .. index); sensor_bias only with a sensor frame, self_weight only with a nonzero
/// gravity. Else what is wrong and what was expected. parseModel and the runtime's load use it.
std::string mechanismInModelProblem(const CalibratedModel& model, size_t index);

/// The model's physical part (no GPR): calibrated chain, compliance (zeros when the model has
/// none), gravity in tracker axes, mechanisms.
PhysicalModel physicalModelOf(const CalibratedModel& model);

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320) of a byte range.
uint32_t crc32Ieee(const uint8_t* data, size_t size) noexcept;

/// Serialises to the fixed little-endian layout above. Throws InputError when the model has
/// inconsistent sizes or would not pass parseModel, so no file the runtime refuses is written.
std::vector<uint8_t> serializeModel(const CalibratedModel& model);

/// Parses bytes; throws InputError naming `source`, the byte offset and field, and what was
/// expected. Never crashes and never reads out of bounds, on any input.
CalibratedModel parseModel(const uint8_t* data, size_t size, const std::string& source);

/// Writes atomically (writeFileAtomically: temporary file in the same folder, fsync, rename,
/// signals held meanwhile), so a crash, a full disk or an interruption never leaves half a model
/// and a failure leaves the previous file as it was. Throws InputError.
void writeModelFile(const CalibratedModel& model, const std::string& path);

/// Reads and parses a model file. Throws InputError.
CalibratedModel readModelFile(const std::string& path);

}  // namespace stepcal
