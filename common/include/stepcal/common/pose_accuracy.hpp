// How accurate a corrected pose is (docs/method.md, "The accuracy bound"): the covariance of its
// position and orientation error from the fitted parameters' covariance (the model file's
// AccuracyFactors propagated through the pose's Jacobian), the GPR's predictive variance and the
// noise of a measurement, and from it a 95 % bound on the position and the orientation error.
// The runtime states it with every answer; `stepcal validate` judges it on held-out rows.
#pragma once

#include <limits>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal {

/// A corrected pose's accuracy as the model states it: what a measurement of the pose will
/// show against the prediction. NaN throughout for a model without AccuracyFactors.
struct PoseAccuracy {
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  double position_rms_m = kUnknown;       ///< √tr Σ_p: RMS of the position error's length, m
  double position_bound_m = kUnknown;     ///< 95 % of position errors are shorter, m
  double orientation_rms_rad = kUnknown;  ///< √tr Σ_ω, rad
  double orientation_bound_rad = kUnknown;  ///< 95 % of rotation errors are smaller, rad
};

/// What the GPR adds at the pose (none without a GPR: zeros).
struct GprUncertainty {
  Vec6 std = Vec6::Zero();  ///< its predictive latent 1-σ per output (the call's gpr_std)
  Vec6 noise = Vec6::Zero();  ///< its white noise 1-σ per output at this input, raw units
  /// Whether its outputs are in the tracker's axes (a GPR per payload force) rather than the
  /// tip's.
  bool tracker_axes = false;
};

/// The GPR's share at input x_raw, given the std (bound) its prediction there gave and its white
/// noise per output at unit output gain (raw units; the runtime's, set at load from the GPR's
/// held-out residuals: RuntimeModel::gpr_noise), times the output gain at x_raw.
GprUncertainty gprUncertainty(const GprPredictor& gpr, const Vec6& noise, const double* x_raw,
                              const Vec6& std) noexcept;

/// The 95 % point of the length of a zero-mean Gaussian 3-vector with covariance S: the
/// generalised χ² matched in its first two moments to g χ²_h (g = tr S² / tr S, h = (tr S)² /
/// tr S², 1 ≤ h ≤ 3), χ²_h's 95 % point interpolated between its values at h = 1, 2, 3. Exact
/// for an isotropic S (h = 3) and for a rank-one S (h = 1).
double lengthBound95(const Mat3& S) noexcept;

/// The fitted parameters' share of a pose's covariance (tip position, orientation; tracker
/// axes): G Gᵀ, G the pose's Jacobian w.r.t. the parameters times their factors: the initial
/// poses' (parameterJacobian of `chain` evaluated in `at_link_angles`), the compliances' (the tip
/// point Jacobian's column j times τ_j); plus mechanism_covariance, when given (the mechanisms'
/// share, addMechanismCovariance, mechanism_accuracy.hpp). Zero beside mechanism_covariance for
/// a model without AccuracyFactors. Allocation-free.
Mat6 parameterCovariance(const CalibratedModel& model, const KinematicChain& chain,
                         const ChainWorkspace& at_link_angles, const JointVector& torque_nm,
                         const Mat6* mechanism_covariance = nullptr) noexcept;

/// The pose's accuracy from its parameters' covariance (parameterCovariance) plus the GPR's
/// latent variance and the measurement's: per axis, the larger of the factors' stated noise and
/// the GPR's white noise (in the tip's axes R_TrackerTip, or the tracker's for a GPR per payload
/// force). Allocation-free.
PoseAccuracy poseAccuracy(const AccuracyFactors& factors, const Mat6& parameter_covariance,
                          const Mat3& R_TrackerTip, const GprUncertainty& gpr) noexcept;

}  // namespace stepcal
