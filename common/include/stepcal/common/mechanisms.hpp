// The physical model and its catalogue of mechanisms: what the robot does beyond rigid geometry
// and linear joint compliance. Found by `stepcal diagnose`, stored in the model file, applied
// by the runtime. Shared by the trainer and the runtime; evaluation is allocation-free.
//
// One pose of the physical model at commanded angles q [rad], a measured wrench W_meas and a
// temperature T, in this order:
//   θ₀ = q + Σ_coupling c q_i e_j + Σ_transmission g_j(q_j) Σ_k (a_k sin k q_j + b_k cos k q_j) e_j
//          + Σ_zero_drift k_j (T − T_ref) e_j                 (joint_zero_drift, T known)
//   W  = W_meas − b_sensor                                   (sensor_bias)
//   τ  = J_s(θ)ᵀ W_root(θ) + τ_self(θ)                       (self_weight: link gravity torques)
//   θ  = θ₀ + C τ + Σ_j d_j(τ_j) e_j                          (the fixed point, three passes)
//        d_j: joint j's torque–deflection beyond its linear compliance (torqueDeflection):
//             backlash b tanh(τ_j / τ_b), nonlinear stiffness c τ_j τ₀ / (τ₀ + |τ_j|), or a
//             torsion curve, lost motion and stiffening terms together; the last two carried on
//             above the largest torque they were fitted over with their slope there
//   X_TrackerTip = FK(θ) with the links' lengths × (1 + α (T − T_ref))   (thermal_expansion)
//                  and each initial pose T_k · exp(Σ_j g_j(q_j) δ̂_jk)          (profile_geometry)
//                  and joint j's frame turned about its origin by t_j(M_j)  (off_axis_compliance:
//                  M_j the load's moment about that origin; inside the fixed point, each pass's
//                  tilt from the pass's frames, applied to the next: the joint's initial pose
//                  T_{j-1} · exp(ω̂ θ_j) exp(t̂_j) exp(−ω̂ θ_j))
//                  and the tip shifted by R_RootMount · C · F_Mount    (tool_mount_compliance:
//                  F the load's force in the mount's axes, the sensor frame's or else the
//                  last joint's; at the fixed point's last frames, after its passes)
// A registration_drift is not the robot's: the tracker's frame moving during a campaign. The
// diagnosis fits it (X_TrackerTip measured = exp(ξ̂(s)) · X_TrackerTip, s the row's time order)
// so that it does not pass for a property of the arm; a model file never holds one, and no
// correction applies it.
// g_j is joint j's transmission profile's coverage gate: 1 on the joint angles it was fitted on,
// fading smoothly to 0 outside them, so a profile never extrapolates (AngleCoverage). A profile
// is fitted jointly with the geometry; profile_geometry δ_j is the part of that geometry which
// goes with joint j's profile (the geometry's least-squares answer to the profile's effect on
// the fit rows, with the opposite sign), switched by the same gate. Where a profile fades out,
// so does its share of the geometry, and the model is the one fitted without that profile.
// Joints are 0-based here and 1-based in names, reports and JSON.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/chain.hpp"

namespace stepcal {

/// The catalogue. Values are stable: they are stored in the model file.
enum class MechanismKind : uint32_t {
  kBacklash = 1,            ///< joint j: lost motion b, taken up in the direction of τ_j
  kSelfWeight = 2,          ///< every link: lumped mass and first moment; C acts on their gravity
  kTransmissionError = 3,   ///< joint j: Σ_k a_k sin(k q_j) + b_k cos(k q_j), k = 1 … order
  kNonlinearStiffness = 4,  ///< joint j: extra compliance c at small torque, fading above τ₀
  kThermalExpansion = 5,    ///< link lengths × (1 + α (T − T_ref))
  kSensorBias = 6,          ///< a constant offset of the F/T reading
  kJointCoupling = 7,       ///< joint j's link angle moves with joint i's commanded angle
  kProfileGeometry = 8,     ///< joint j: initial-pose corrections that go with its transmission profile
  kTorsionCurve = 9,        ///< joint j: lost motion and stiffening terms of its torque, one curve
  kJointZeroDrift = 10,     ///< joint j: its zero moves by k (T − T_ref) with temperature
  kRegistrationDrift = 11,  ///< the tracker's frame moves in time order: measurement, not robot
  kSessionFrames = 12,      ///< a campaign's own tracker station and tool: measurement, not robot
  kCampaignJointZero = 13,  ///< joint j: its zero in each later campaign against the first's
  kOffAxisCompliance = 14,  ///< joint j: its frame tilts across its axis by the moment it carries
  kToolMountCompliance = 15,  ///< the tool shifts on its mount by the load's force (m/N per axis)
};

/// Snake-case name, e.g. "transmission_error".
const char* toString(MechanismKind kind) noexcept;
/// Kind of a snake-case name; nullopt when it names none.
std::optional<MechanismKind> mechanismKindFromString(const std::string& name);

/// Highest harmonic of a transmission profile.
inline constexpr int kMaxHarmonics = 64;
/// Most stiffening terms of a torsion curve.
inline constexpr int kMaxTorsionTerms = 4;
/// Width of a torsion curve's knee as a fraction of its torque: its term's compliance falls from
/// c_k to 0 over about ±2 widths around T_k (a logistic), so the curve is C¹ for the runtime's
/// Newton steps yet close to a catalogue's corner.
inline constexpr double kTorsionKneeWidth = 0.1;
/// Highest degree of a registration_drift's polynomial in time order.
inline constexpr int kMaxDriftDegree = 8;
/// Most arcs in one coverage.
inline constexpr int kMaxCoverageArcs = 32;

/// The joint angles a 2π-periodic term was fitted on, as arcs of the circle, and the gate that
/// switches the term off smoothly outside them: g(q) = 1 deeper than fade_rad inside an arc,
/// smoothstep(d / fade_rad) at a distance d < fade_rad from its nearest edge, 0 outside every arc.
/// The gate is C¹ in q, so a corrected trajectory has no step where it leaves the coverage.
struct AngleCoverage {
  /// Pairs (start, length) in rad: start ∈ [0, 2π), 0 < length ≤ 2π, ordered by start, not
  /// overlapping. Empty = no gate (the term applies at every angle). length = 2π: the full turn.
  std::vector<double> arcs_rad;
  double fade_rad = 0.0;  ///< width of the ramp inside each edge, rad (> 0 when arcs are given)
};

/// Gate value g(q) ∈ [0, 1] of a coverage at angle q_rad, and dg/dq (1/rad) when derivative is
/// given. Allocation-free.
double coverageGate(const AngleCoverage& coverage, double q_rad,
                    double* derivative = nullptr) noexcept;

/// Empty when the coverage is well formed (see AngleCoverage); else what is wrong.
std::string coverageProblem(const AngleCoverage& coverage);

/// One identified mechanism with its parameters (SI) and their 1-σ.
struct Mechanism {
  MechanismKind kind = MechanismKind::kBacklash;
  int joint = -1;  ///< joint it moves (0-based): backlash, transmission, nonlinear, coupling;
                   ///< profile_geometry: the joint whose transmission profile it goes with
  int source_joint = -1;  ///< joint_coupling: the joint whose commanded angle drives it
  /// transmission_error: harmonics 1 … order (1 ≤ order ≤ kMaxHarmonics); torsion_curve: its
  /// stiffening terms (0 ≤ order ≤ kMaxTorsionTerms); registration_drift: its polynomial's
  /// degree (1 ≤ order ≤ kMaxDriftDegree); session_frames: the campaign's index among those
  /// fitted together (≥ 1; the first campaign's frames are the chain's own);
  /// campaign_joint_zero: the number of campaigns after the first (≥ 1); other kinds 0.
  int order = 0;
  /// SI, laid out per kind as mechanismParameterNames lists them: see the kind's header,
  /// stepcal/common/mechanisms/<kind>.hpp, and read them through its typed view there, e.g.
  /// view<mechanism::Backlash>(m).lostMotion_rad(); code generic over kinds (fits, reports)
  /// through parameter(i).
  std::vector<double> parameters;
  std::vector<double> sigma;  ///< 1-σ of each parameter, same size (0 = not estimated)
  /// transmission_error: the angles of its joint it was fitted on (empty: everywhere); other
  /// kinds: empty.
  AngleCoverage coverage;

  /// Parameter i (0-based, as mechanismParameterNames lists them), for code generic over kinds.
  double parameter(int i) const noexcept { return parameters[static_cast<size_t>(i)]; }
  double& parameter(int i) noexcept { return parameters[static_cast<size_t>(i)]; }
};

/// What a kind is, in one place: its name, its parameters, its checks and its description. One
/// per kind, in the kind's own file (common/src/mechanisms/<kind>.cpp), listed in the registry
/// (common/src/mechanisms/registry.cpp).
struct MechanismTraits {
  /// How many of the kind one model holds.
  enum class Multiplicity { kAny, kOnePerModel, kOnePerJoint };

  MechanismKind kind;
  const char* name;                ///< snake case, as in model files and reports
  bool measurement_only = false;   ///< isMeasurementOnly
  bool uses_joint = false;         ///< Mechanism::joint is a joint (else −1)
  bool uses_source_joint = false;  ///< Mechanism::source_joint is a joint (else −1)
  bool has_coverage = false;       ///< Mechanism::coverage may hold arcs
  bool torque_deflection = false;  ///< isTorqueDeflection
  Multiplicity multiplicity = Multiplicity::kAny;
  /// Whether Mechanism::order fits the kind (its meaning: Mechanism::order).
  bool (*order_fits)(int order) = nullptr;
  /// mechanismParameterNames.
  std::vector<std::string> (*parameter_names)(int dof, int order) = nullptr;
  /// What is wrong with the kind's own values once the checks common to all kinds (order,
  /// sizes, finite values, joints, coverage) passed; empty when nothing. Null: nothing to check.
  std::string (*problem)(const Mechanism& m, int dof) = nullptr;
  /// describe's text after the name, e.g. " (joint 2)"; null: none.
  std::string (*describe_suffix)(const Mechanism& m) = nullptr;
  /// torque_deflection: the curve's formula at every torque, rad, and ∂/∂τ when derivative is
  /// given; and the torque above which torqueDeflection carries it on with its slope (0 or null:
  /// none).
  double (*deflection)(const Mechanism& m, double tau_nm, double* derivative) noexcept = nullptr;
  double (*linear_above_nm)(const Mechanism& m) noexcept = nullptr;
  /// A kind that moves the commanded link angles θ₀ by a term of its own (joint_coupling,
  /// joint_zero_drift; physicalLinkAngles): adds it at the commanded angles q_rad and temperature
  /// temp_c (NaN: not known) to theta0_rad, in place (its rounding is the sum's). Null: none.
  /// Allocation-free. The transmission profiles, whose gate also switches their geometry, stay
  /// in physicalLinkAngles.
  void (*add_link_angle_offset)(const Mechanism& m, const JointVector& q_rad, double temp_c,
                                JointVector& theta0_rad) noexcept = nullptr;
};

/// Every kind's traits, in the order of MechanismKind.
const std::vector<const MechanismTraits*>& mechanismRegistry();
/// A kind's traits; null when the value names no kind.
const MechanismTraits* findMechanismTraits(MechanismKind kind) noexcept;

/// A kind's typed view of a mechanism's parameters (stepcal/common/mechanisms/<kind>.hpp), e.g.
/// view<mechanism::TorsionCurve>(m).kneeTorque_nm(k). View<Double> is an aggregate {Double* p;
/// int order;} with its kind View<double>::kKind; a const mechanism gives a read-only view. It
/// neither owns nor resizes the parameters: they must have the kind's size.
template <template <class> class View>
View<const double> view(const Mechanism& m) noexcept {
  return {m.parameters.data(), m.order};
}
template <template <class> class View>
View<double> view(Mechanism& m) noexcept {
  return {m.parameters.data(), m.order};
}

/// Names of a kind's parameters, units in the names, for an n-joint chain (order: a
/// transmission_error's harmonics, else unused).
std::vector<std::string> mechanismParameterNames(MechanismKind kind, int dof, int order = 0);

/// Empty when the mechanism is well formed for an n-joint chain; else what is wrong and what
/// was expected (joint ranges, parameter count, finite values, τ₀ > 0, harmonic ≥ 1, …).
std::string mechanismProblem(const Mechanism& mechanism, int dof);

/// Short human name, e.g. "backlash (joint 2)", "transmission_error (joint 3, 24 harmonics)".
std::string describe(const Mechanism& mechanism);

/// Whether a kind describes the measurement, not the robot as it is now (registration_drift,
/// session_frames, campaign_joint_zero: a campaign's tracker or the robot as an earlier campaign
/// found it): the diagnosis fits it, a model file never holds it, no correction applies it.
bool isMeasurementOnly(MechanismKind kind) noexcept;

/// Legendre polynomial P_degree(s), degree ≥ 0 (Bonnet's recurrence): a registration_drift's
/// basis in the time order s ∈ [−1, 1].
double legendrePolynomial(int degree, double s) noexcept;

/// Twist (v m, ω rad; tracker axes) by which a registration_drift moves the tracker's frame at
/// time order seq: Σ_d P_d(s) ξ_d (Mechanism's layout). Allocation-free.
Vec6 registrationDrift(const Mechanism& drift, double seq) noexcept;

/// A session_frames mechanism's station and tool as poses (Mechanism's layout).
struct StationAndTool {
  Pose X_Station;  ///< the first campaign's tracker frame in this campaign's tracker frame
  Pose X_Tool;     ///< this campaign's tool frame in the first campaign's tool frame
};
StationAndTool stationAndTool(const Mechanism& frames) noexcept;
/// The parameters (Mechanism's layout) of a station and a tool.
std::vector<double> stationAndToolParameters(const Pose& X_Station, const Pose& X_Tool);

/// Whether a kind is a joint's torque–deflection beyond its linear compliance: backlash,
/// nonlinear_stiffness or torsion_curve.
bool isTorqueDeflection(MechanismKind kind) noexcept;

/// Deflection of a torque-deflection mechanism (isTorqueDeflection) at its joint's torque
/// tau_nm [N·m], rad, and its derivative ∂/∂τ [rad/(N·m)] when derivative is given; 0 for other
/// kinds. Above its τ_lin (nonlinear_stiffness, torsion_curve) the tangent there: where no row
/// showed the curve, the joint carries on with the stiffness it had at the largest torque that
/// did (C¹, so the runtime's Newton steps see no corner). Allocation-free.
double torqueDeflection(const Mechanism& mechanism, double tau_nm,
                        double* derivative = nullptr) noexcept;

/// Link-angle offset of a transmission_error at commanded angle q_rad, gate included, rad, and
/// its derivative d/dq when derivative is given. Allocation-free (harmonics by recurrence).
double transmissionOffset(const Mechanism& transmission, double q_rad,
                          double* derivative = nullptr) noexcept;

/// The calibrated physical model: geometry, compliance and mechanisms (no GPR).
struct PhysicalModel {
  KinematicChain chain_Tracker;         ///< calibrated, rooted at the tracker
  int sensor_frame = -1;                ///< attached frame of the F/T sensor, −1 = none
  JointVector compliance_rad_per_nm;    ///< n entries (zeros: rigid)
  Vec3 gravity_Tracker = Vec3::Zero();  ///< m/s², tracker axes (zero: unknown)
  std::vector<Mechanism> mechanisms;

  /// The chain's translation scale at temperature temp_c (NaN: unknown → 1).
  double linkLengthScale(double temp_c) const noexcept;
  /// Whether any mechanism is of this kind.
  bool has(MechanismKind kind) const noexcept;
};

/// What physicalLinkAngles can take, once computed, from a model that no longer changes (the
/// runtime's): the initial poses with every profile's gate open (g = 1 for each joint with a
/// transmission_error: inside its coverage, the common case), which otherwise cost an exp per
/// pose and call. Used only while every gate is exactly 1, so the answers are the same bit for
/// bit with and without them.
struct PhysicalConstants {
  bool has_open_geometry = false;  ///< whether profile_geometry moves the poses with gates open
  InitialPoses exp_open_geometry;  ///< exp(Σ_j δ̂_jk) per initial pose k, gates open
  InitialPoses initial_open;       ///< the initial poses, gates open, link length scale 1
};
/// The constants of a model (allocation-free; recompute after any change of the model).
PhysicalConstants physicalConstants(const PhysicalModel& model) noexcept;

/// Passes of the fixed point θ = θ₀ + Δθ(τ(θ)) that define the model: from θ₀, each contracts
/// the error by ~C ∂τ/∂θ ≈ 1e-3, so three leave it far below a nanoradian (docs/method.md eq. 24
/// uses two for compliance alone).
inline constexpr int kFixedPointPasses = 3;

/// How physicalLinkAngles runs that fixed point. The default is the model. An iterative solver
/// that evaluates it at nearby q may start from the deflection of its last evaluation and run
/// fewer passes: an approximation of the model (error ~1e-3 × the change of the deflection per
/// pass), which the solver must check against the model.
/// A fixed point's frames at θ₀ (its first evaluation), kept by one evaluation for the next ones
/// at the same commanded angles: a model that differs only in what its fixed point does with the
/// torques (a compliance, a torque–deflection mechanism, the sensor bias, the self weight's
/// masses: finite differences of them) has the same θ₀ and initial poses, and needs no
/// kinematics of its own there. Reusing it gives the values evaluating them again gives.
struct FirstPass {
  bool kept = false;
  JointVector q_rad, theta0_rad;
  InitialPoses initial;
  JointTrig trig_q, trig0;  ///< sin and cos of q and of θ₀
  ChainWorkspace ws;        ///< the frames at θ₀
  Jacobian J;               ///< their spatial Jacobian, when has_J
  bool has_J = false;
};

/// An off_axis_compliance's frame tilts start from zero whatever the start: with fewer passes than
/// the model's, they lag behind (passes 0: none).
struct FixedPointStart {
  int passes = kFixedPointPasses;  ///< 0: θ = θ₀ + deflection_rad, no pass (τ left zero)
  const JointVector* deflection_rad = nullptr;  ///< θ − θ₀ to start from (null: θ₀ itself)
  JointVector* deflection_out_rad = nullptr;    ///< gets θ − θ₀ (may be deflection_rad)
  /// Not kept yet: keeps this evaluation's frames at θ₀; kept at the same q, θ₀ and initial
  /// poses: they are this evaluation's too.
  FirstPass* first_pass = nullptr;
};

/// A payload as the controller knows it (its load data): a point mass on the last link. Its
/// weight loads the joints at the deflected pose, inside the fixed point, in place of a measured
/// wrench.
struct PointPayload {
  double mass_kg = 0.0;
  Vec3 p_CoGInLast_m = Vec3::Zero();  ///< centre of gravity in frame n (after joint n's motion), m
};

/// Where physicalLinkAngles writes, in the caller's storage: the frames at θ (with the thermal
/// length scale), the link angles θ [rad], the joint torques τ [N·m], and, when profile_slope is
/// given, per joint the derivative of its transmission profile's offset (gate included) by its
/// commanded angle, 0 without one.
struct PhysicalLinkAnglesOut {
  ChainWorkspace& ws;
  JointVector& theta_rad;
  JointVector& tau_nm;
  JointVector* profile_slope = nullptr;
};

/// How physicalLinkAngles evaluates, each optional: constants, when given, must be
/// physicalConstants(model); start changes the fixed point's start and passes (FixedPointStart);
/// payload loads the joints by its weight (model.gravity_Tracker) at each pass instead of the
/// measured wrench (the wrench and the sensor bias are then unused): τ_k = ξ_kᵀ (m g, p × m g),
/// p its centre of gravity in the root at the pass's θ.
struct PhysicalEvaluation {
  const PhysicalConstants* constants = nullptr;
  const FixedPointStart* start = nullptr;
  const PointPayload* payload = nullptr;
};

/// Link angles θ and joint torques τ of the physical model at commanded angles q, a measured
/// wrench (sensor axes; zero when unloaded or no sensor) and a temperature (NaN: unknown), into
/// out: θ₀ from the commanded-angle mechanisms, then the fixed point θ = θ₀ + Δθ(τ(θ)).
/// Allocation-free; false when sizes disagree.
bool physicalLinkAngles(const PhysicalModel& model, const JointVector& q_rad,
                        const Vec6& wrench_Sensor, double temp_c, const PhysicalLinkAnglesOut& out,
                        const PhysicalEvaluation& how = {}) noexcept;

/// Joints whose commanded angle lies (partly, within the fade) outside the coverage of their
/// transmission profile: bit j set for joint j (0-based). There the profile's correction is
/// faded out and the model is the rest of the physical model. Allocation-free.
uint32_t jointsOutsideCoverage(const PhysicalModel& model, const JointVector& q_rad) noexcept;

/// Gravity torques of the lumped link masses of a self_weight mechanism at the pose in ws,
/// N·m (n entries). Allocation-free.
void selfWeightTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                       const Vec3& gravity_Root, const std::vector<double>& parameters,
                       JointVector& tau_nm) noexcept;

}  // namespace stepcal
