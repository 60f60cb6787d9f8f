// Step 2: joint compliance from loaded/unloaded pairs (docs/method.md eq. 13–22).
//
// A pair is two rows with the same pose_id, one unloaded and one loaded: the tracker sees the
// deflection Δp (tip position) and Δω (rotation), the sensor the payload's wrench. With the
// calibrated chain at q, Δθ = C_θ τ and τ = J_sᵀ W, so the deflection is linear in C_θ:
//   [Δp; Δω] = J_tip · diag(τ) · C_θ                           (eq. 19–20)
// solved by weighted least squares (eq. 21–22) over the joints the loads excite.
#pragma once

#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"

namespace stepcal::trainer {

/// An unloaded row and a loaded row commanded to the same joint angles.
struct DeflectionPair {
  const Measurement* unloaded = nullptr;
  const Measurement* loaded = nullptr;
};

/// Every (unloaded, loaded) pair among the rows: per pose_id (of a session: merged campaigns may
/// share names), the unloaded row (load_kg 0) with each loaded row. Throws InputError when a
/// pose_id has two unloaded rows or the pair's joint angles differ (not commanded to one pose).
std::vector<DeflectionPair> deflectionPairs(const std::vector<const Measurement*>& rows);

/// One joint's identified compliance.
struct JointCompliance {
  std::string joint;
  bool excited = false;  ///< false: the loads' torque on it is too small to identify C_θ
  double max_torque_nm = 0.0;        ///< largest |τ| over the pairs, N·m
  double compliance_rad_per_nm = 0.0;  ///< C_θ (0 when not excited)
  double compliance_sigma_rad_per_nm = 0.0;  ///< 1-σ
  double stiffness_nm_per_rad = 0.0;   ///< K_θ = 1/C_θ (0 when not excited)
  double stiffness_sigma_nm_per_rad = 0.0;  ///< 1-σ, first order
};

struct StiffnessOptions {
  /// A joint whose compliance comes out with a larger relative 1-σ than this is not
  /// identifiable from these loads: it is reported as such and taken as rigid.
  double max_relative_sigma = 0.25;
};

struct StiffnessResult {
  JointVector compliance_rad_per_nm;        ///< n entries, 0 for joints not excited
  JointVector compliance_sigma_rad_per_nm;  ///< n entries
  std::vector<JointCompliance> joints;
  /// n × n covariance of compliance_rad_per_nm, (rad/(N·m))² (zero rows and columns for the
  /// joints not identified): (BᵀB)⁺ of the weighted system, times the reduced χ² when above 1.
  Eigen::MatrixXd compliance_covariance;
  int pairs = 0;
  double rms_position_residual_m = 0.0;  ///< of the fitted deflections
};

/// Deviation of modelled from measured deflection, per load (the paper's check).
struct StiffnessValidation {
  double load_kg = 0.0;
  int pairs = 0;
  double mean_deviation_pct = 0.0;  ///< mean of |Δp_model − Δp_meas| / |Δp_meas| · 100
  double max_deviation_pct = 0.0;
  double mean_deflection_m = 0.0;   ///< mean measured |Δp|
};

/// Identifies C_θ on the pairs with the calibrated chain (rooted at the tracker) and its
/// sensor frame. Joints are dropped, least certain first, until every remaining one is
/// identified to options.max_relative_sigma. Throws InputError when there are no pairs, a
/// loaded row has no wrench or the loads excite no joint.
StiffnessResult identifyCompliance(const KinematicChain& chain_Tracker, int sensor_frame,
                                   const std::vector<DeflectionPair>& pairs,
                                   const TrackerNoise& noise, const StiffnessOptions& options = {});

/// One session's pairs and the calibrated chain of its tracker frame (geometric.hpp sessions).
struct StiffnessSession {
  const KinematicChain* chain_Tracker = nullptr;
  std::vector<DeflectionPair> pairs;
  TrackerNoise noise;
};

/// Identifies one C_θ for the robot from the pairs of several sessions, each with its own chain
/// and weights. Throws as identifyCompliance on one session; pairs of no session count as none.
StiffnessResult identifyCompliance(const std::vector<StiffnessSession>& sessions, int sensor_frame,
                                   const StiffnessOptions& options = {});

/// Whether one compliance of a joint serves every session, judged on pairs held out.
struct ComplianceDifference {
  std::string joint;
  int index = 0;                    ///< the joint's index in the chain, from 0
  double shared_rad_per_nm = 0.0;   ///< the compliance every session shares, fitted on every pair
  /// Mean held-out tip deflection error of the model it was tested against (the joints named
  /// before it each session's own, the others shared) minus with this joint's each session's own
  /// too, m (positive: the own compliances predict better).
  double held_out_gain_m = 0.0;
  double z_statistic = 0.0;  ///< one-sided signed-rank z of the pairs' held-out squared errors
  bool significant = false;  ///< z above the one-sided 1 % point (kComplianceDifferenceZ)
  /// Per tested session (ComplianceDifferences::sessions), its own compliance minus the first
  /// tested session's, fitted on every pair with this joint and the named ones each session's
  /// own, and its 1-σ
  /// (stated noise, times the reduced χ² when above 1), rad/(N·m); the first is zero.
  std::vector<double> difference_rad_per_nm, difference_sigma_rad_per_nm;
};

/// The held-out test of the sessions' compliances (testComplianceDifferences).
struct ComplianceDifferences {
  bool tested = false;
  std::string not_tested;       ///< why not, when not tested
  std::vector<int> sessions;    ///< the sessions tested, from 0: those with 2·folds loaded poses
  std::vector<int> untested_sessions;  ///< the others: too few loaded pairs, left out
  std::vector<ComplianceDifference> joints;  ///< one per joint the shared fit identified
};

/// One-sided 1 % point of the standard normal: a joint's compliance is named as differing between
/// sessions when the held-out reduction's signed-rank z exceeds it.
inline constexpr double kComplianceDifferenceZ = 2.326;

/// Per joint identified in shared (identifyCompliance of these sessions), whether the sessions need
/// their own compliance: k-fold cross-validation over each session's loaded poses, forward: every
/// compliance shared against one joint's each session's own, the most significant named and kept
/// its own while the others are tested again, until none is significant. Sessions with fewer than
/// 2·folds loaded poses are left out; fewer than two left: not tested (a result, not an error).
ComplianceDifferences testComplianceDifferences(const std::vector<StiffnessSession>& sessions,
                                                int sensor_frame, const StiffnessResult& shared,
                                                int folds = 5);

/// Modelled vs measured tip deflection on pairs, grouped by load.
std::vector<StiffnessValidation> validateCompliance(const KinematicChain& chain_Tracker,
                                                    int sensor_frame,
                                                    const JointVector& compliance_rad_per_nm,
                                                    const std::vector<DeflectionPair>& pairs);

}  // namespace stepcal::trainer
