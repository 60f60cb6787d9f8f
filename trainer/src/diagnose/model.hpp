// The model a diagnosis builds (internal to stepcal::trainer): a global physical model (geometry,
// compliance, every mechanism that holds at any pose) and transmission profiles on top of it.
//
// The two are fitted together: the global part explains all it can with physics that holds
// everywhere (no ridge), the profiles, with their ridges, what is left jointly with a change of
// the geometry, each only on the joint angles it was fitted on (its coverage gate, 1 on every fit
// row). That change of the geometry is split by profile: joint j's share δ_j is the geometry's
// least-squares answer to joint j's profile on the fit rows, with the opposite sign
// (δ_j = −G⁺ B_j c_j, so Σ_j δ_j is the joint fit's change of the geometry), and it is switched
// by joint j's gate (profile_geometry, mechanisms.hpp). Where a profile fades out, its share of
// the geometry goes with it: a row outside every profile sees exactly the global model.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fit_rows.hpp"
#include "stepcal/common/mechanisms.hpp"

namespace stepcal::trainer::diagnosis {

/// A transmission profile with its ridge (λ Σ (a_k² + b_k²) is added to the weighted squared
/// residual when it is fitted) and its share of the geometry.
struct Profile {
  Mechanism mechanism;  ///< kind transmission_error: joint, order, parameters, σ, coverage
  double ridge = 0.0;   ///< λ, weighted-residual units per rad²
  /// δ_j of the initial poses that goes with the profile (6(n+1); empty: none yet), its 1-σ.
  Eigen::VectorXd geometry, geometry_sigma;
  /// cᵀ Σ_c⁻¹ c, the coefficients' squared Mahalanobis distance from zero (Σ_c their covariance):
  /// 2·order where they lie one σ from it. Its harmonics may each lie within one σ where its
  /// values over the angles it covers are far from zero (on an arc they trade with each other).
  double size_chi2 = 0.0;
  /// Σ_c, 2·order × 2·order, from the joint fit that gave the coefficients and their σ (empty:
  /// none; its diagonal is σ² while they are that fit's).
  Eigen::MatrixXd coefficient_covariance;
};

struct DiagnosisModel {
  PhysicalModel global;                ///< no transmission_error or profile_geometry in it
  std::vector<bool> compliance_free;   ///< per joint: its compliance is fitted
  bool masses_from_urdf = false;       ///< self_weight's masses are the URDF's, not fitted
  std::vector<Profile> profiles;
  /// Set when the global part's σ are not yet those of its last refit (refitGlobal leaves them to
  /// globalSigma: its linearisation costs an evaluation of the model per row and parameter, and
  /// a joint step after the refit sets them anyway): whether that refit held the profiles.
  std::optional<bool> sigma_pending;

  /// The whole physical model: global + each profile with its profile_geometry.
  PhysicalModel combined() const;
};

/// A scalar global parameter: a joint's compliance (mechanism −1) or a mechanism's parameter.
struct Parameter {
  int mechanism = -1;
  int index = 0;
  double step = 0.0;  ///< finite-difference step of typical size, SI
};

/// Moves a parameter by delta.
void shift(PhysicalModel& model, const Parameter& p, double delta);

/// A step that moves the link angles by ~1e-4 rad or the tip by ~0.1 mm.
double typicalStep(const Mechanism& m, int index);

/// The fitted parameters of a global mechanism (thermal's reference temperature and backlash's
/// smoothing are chosen, not fitted; nonlinear stiffness's τ₀ only once its compliance is
/// nonzero; a torsion curve's lost motion and extra compliances, and each fade torque once its
/// compliance is nonzero, its smoothing chosen; a curve's τ_lin is the rows' largest torque;
/// self_weight's masses not when they come from the URDF).
std::vector<int> freeParameters(const Mechanism& m, bool masses_from_urdf);

/// Whether a parameter is the shape of a joint's curve, not its size: a nonlinear stiffness's τ₀,
/// a torsion curve's knee torque. The curve is nonlinear in it alone.
bool isShape(const PhysicalModel& model, const Parameter& p);

/// The parameters of a mechanism whose physics needs them ≥ 0: a lost motion, an extra
/// compliance (backlash, nonlinear_stiffness, each of a torsion_curve's).
std::vector<int> signConstrained(const Mechanism& m);

/// One linear bound the physics puts on a mechanism's parameters, Σ coefficient · p[index] ≥ 0:
/// a size (lost motion, extra compliance) ≥ 0; a lumped link mass ≥ 0 and its centre of mass
/// within the link's reach (|h_a| ≤ m L per axis of the link's frame).
struct PhysicalBound {
  std::vector<std::pair<int, double>> terms;
  double tolerance = 0.0;  ///< how far below zero is rounding, not physics, in its units
  /// What m says when it breaks the bound, e.g. "link 3 mass −115 kg".
  std::function<std::string(const Mechanism& m)> broken;
  double value(const Mechanism& m) const;
};

/// Every bound of m's physics: its kind's (KindFit::bounds; a link's reach from the chain's
/// initial poses), else each sign-constrained parameter ≥ 0.
std::vector<PhysicalBound> physicalBounds(const Mechanism& m, const KinematicChain& chain);

/// What makes m physically impossible under bounds (the bound it breaks furthest, in units of
/// its tolerance), "" when it breaks none.
std::string brokenBound(const Mechanism& m, const std::vector<PhysicalBound>& bounds);

/// m moved onto its bounds where it breaks them (KindFit::make_feasible; else each
/// sign-constrained parameter below zero set to zero): a bounded step starts from a feasible point.
void makeFeasible(Mechanism& m, const KinematicChain& chain);

/// A torsion_curve in its simplest kind: lost motion alone is a backlash; other mechanisms as
/// they are.
Mechanism simplestTorqueDeflection(Mechanism m);

/// Every fitted global parameter: free compliances, then each mechanism's free parameters.
std::vector<Parameter> globalParameters(const DiagnosisModel& model);

/// Forward-difference columns d(modelled)/d(p) of the parameters in the residual's weighting, on
/// fit rows [begin, end), on the calling thread (r0: the model's residual on their equations):
/// equations × parameters.
Eigen::MatrixXd parameterColumns(const PhysicalModel& model, const std::vector<Parameter>& params,
                                 const FitRows& fit, size_t begin, size_t end,
                                 const Eigen::VectorXd& r0);

/// Ridge of the geometry's columns in the profiles' fit, relative to their squared norm: only
/// keeps the geometry's unobservable combinations (docs/method.md, step 1: rank 30 of 42) at zero.
inline constexpr double kProfileGeometryRidge = 1e-9;

/// 1-σ of the weak prior on lumped link masses (kg and kg·m per parameter) when the URDF gives
/// none: only their gravity torques are identifiable, the prior keeps the rest near zero.
inline constexpr double kSelfWeightPriorSigma = 50.0;

/// A parameter whose physics bounds it below by zero (a free compliance; a lost motion or an extra
/// compliance, signConstrained) and which the refit holds there: the rows push it below.
struct HeldAtBound {
  Parameter parameter;
  double unbounded = 0.0;  ///< where the final linearisation's step without bounds takes it, SI
};

struct GlobalFit {
  Eigen::VectorXd r;  ///< weighted residual of the global model (no profiles)
  double cost = 0.0;  ///< r² plus the priors
  std::vector<HeldAtBound> held;  ///< in the order of globalParameters
};

/// Joint Gauss–Newton refit of the global model on every fit row (geometry δ, free compliances,
/// mechanisms; truncated SVD; priors on lumped masses), the profiles left out or (hold_profiles)
/// held at their values. Each step is the linearisation's least-squares step under the bounds
/// the physics sets (solveReducedBounded): a free compliance, a lost motion and an extra
/// compliance stay ≥ 0 (one below zero is first set to zero), so that a joint's curve stays
/// monotone at every torque. Along the valley where a nonlinear stiffness fading far beyond the
/// rows' torques trades with its joint's compliance (c τ τ₀/(τ₀ + |τ|) → c τ − (c/τ₀) τ|τ|), the
/// refit stops where the joint's compliance reaches zero instead of running to τ₀ → ∞, C → −∞.
/// Says which bounded parameters it ends held at zero (GlobalFit::held). The global mechanisms'
/// σ are left zero and sigma_pending set.
GlobalFit refitGlobal(DiagnosisModel& model, const FitRows& fit, int iterations,
                      bool hold_profiles = false);

/// When sigma_pending: the σ of the global part's last refit, from its final linearisation, into
/// its mechanisms and compliance_sigma (n entries).
void globalSigma(DiagnosisModel& model, const FitRows& fit, JointVector& compliance_sigma);

}  // namespace stepcal::trainer::diagnosis
