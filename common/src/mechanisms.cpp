#include "stepcal/common/mechanisms.hpp"

#include <algorithm>
#include <array>
#include <type_traits>
#include <cmath>
#include <cstdio>

#include "mechanisms/kinds.hpp"
#include "stepcal/common/compliance.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms/off_axis_compliance.hpp"
#include "stepcal/common/mechanisms/sensor_bias.hpp"
#include "stepcal/common/mechanisms/thermal_expansion.hpp"
#include "stepcal/common/mechanisms/tool_mount_compliance.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal {
namespace {

constexpr double kTwoPi = 2.0 * kPi;

}  // namespace

const char* toString(MechanismKind kind) noexcept {
  const MechanismTraits* traits = findMechanismTraits(kind);
  return traits != nullptr ? traits->name : "unknown";
}

std::optional<MechanismKind> mechanismKindFromString(const std::string& name) {
  for (const MechanismTraits* traits : mechanismRegistry()) {
    if (name == traits->name) return traits->kind;
  }
  return std::nullopt;
}

double coverageGate(const AngleCoverage& coverage, double q_rad, double* derivative) noexcept {
  if (derivative) *derivative = 0.0;
  const size_t arcs = coverage.arcs_rad.size() / 2;
  if (arcs == 0) return 1.0;
  // q mod 2π in [0, 2π) by one floor rather than fmod's exact remainder: the two agree to the
  // rounding of 2π's multiple, ~1e-15 rad at the joint ranges robots have.
  double angle = q_rad - kTwoPi * std::floor(q_rad / kTwoPi);
  if (angle >= kTwoPi) angle -= kTwoPi;
  if (angle < 0.0) angle += kTwoPi;
  double best = 0.0, best_slope = 0.0;
  for (size_t a = 0; a < arcs; ++a) {
    const double start = coverage.arcs_rad[2 * a], length = coverage.arcs_rad[2 * a + 1];
    if (length >= kTwoPi) {  // the full turn: no edge
      if (derivative) *derivative = 0.0;
      return 1.0;
    }
    double u = angle - start;  // position inside the arc, [0, 2π)
    if (u < 0.0) u += kTwoPi;
    if (u > length) continue;
    // Distance to the nearer edge, and its slope along q.
    const bool near_start = u < length - u;
    const double d = near_start ? u : length - u;
    const double x = d / coverage.fade_rad;
    if (x >= 1.0) {
      if (derivative) *derivative = 0.0;
      return 1.0;
    }
    const double g = x * x * (3.0 - 2.0 * x);
    if (g > best) {
      best = g;
      best_slope = 6.0 * x * (1.0 - x) / coverage.fade_rad * (near_start ? 1.0 : -1.0);
    }
  }
  if (derivative) *derivative = best_slope;
  return best;
}

std::string coverageProblem(const AngleCoverage& coverage) {
  const std::vector<double>& a = coverage.arcs_rad;
  if (a.empty()) return {};
  if (a.size() % 2 != 0 || a.size() / 2 > static_cast<size_t>(kMaxCoverageArcs)) {
    return "coverage has " + std::to_string(a.size()) +
           " numbers; expected pairs (start, length), at most " +
           std::to_string(kMaxCoverageArcs) + " arcs";
  }
  if (!(std::isfinite(coverage.fade_rad) && coverage.fade_rad > 0.0)) {
    return "coverage fade " + std::to_string(coverage.fade_rad) + " rad; expected > 0";
  }
  for (size_t i = 0; i < a.size(); i += 2) {
    const double start = a[i], length = a[i + 1];
    char line[200];
    if (!(std::isfinite(start) && start >= 0.0 && start < kTwoPi && std::isfinite(length) &&
          length > 0.0 && length <= kTwoPi)) {
      std::snprintf(line, sizeof line,
                    "coverage arc %zu (start %.9g rad, length %.9g rad); expected start in [0, "
                    "2pi), length in (0, 2pi]",
                    i / 2, start, length);
      return line;
    }
    if (i > 0 && !(start >= a[i - 2] + a[i - 1])) {
      std::snprintf(line, sizeof line,
                    "coverage arc %zu starts at %.9g rad, inside the arc before it; expected arcs "
                    "ordered by start, not overlapping",
                    i / 2, start);
      return line;
    }
  }
  const size_t last = a.size() - 2;
  if (a.size() > 2 && a[last] + a[last + 1] > a[0] + kTwoPi) {
    return "the last coverage arc wraps over the first; expected arcs not overlapping";
  }
  return {};
}

bool isTorqueDeflection(MechanismKind kind) noexcept {
  const MechanismTraits* traits = findMechanismTraits(kind);
  return traits != nullptr && traits->torque_deflection;
}

double torqueDeflection(const Mechanism& m, double tau_nm, double* derivative) noexcept {
  const MechanismTraits* traits = findMechanismTraits(m.kind);
  if (traits == nullptr || !traits->torque_deflection) {
    if (derivative) *derivative = 0.0;
    return 0.0;
  }
  const double limit = traits->linear_above_nm ? traits->linear_above_nm(m) : 0.0;  // none: 0
  if (!(limit > 0.0 && std::abs(tau_nm) > limit)) return traits->deflection(m, tau_nm, derivative);
  // d(±τ_lin) + d'(±τ_lin) (τ ∓ τ_lin)
  const double edge = std::copysign(limit, tau_nm);
  double slope = 0.0;
  const double at_edge = traits->deflection(m, edge, &slope);
  if (derivative) *derivative = slope;
  return at_edge + slope * (tau_nm - edge);
}

std::vector<std::string> mechanismParameterNames(MechanismKind kind, int dof, int order) {
  const MechanismTraits* traits = findMechanismTraits(kind);
  return traits != nullptr ? traits->parameter_names(dof, order) : std::vector<std::string>{};
}

std::string mechanismProblem(const Mechanism& m, int dof) {
  const MechanismTraits* traits = findMechanismTraits(m.kind);
  if (traits == nullptr) {
    return "mechanism kind " + std::to_string(static_cast<uint32_t>(m.kind)) + "; expected 1 to " +
           std::to_string(mechanismRegistry().size()) + " (mechanisms.hpp)";
  }
  const std::string what = traits->name;
  if (!traits->order_fits(m.order)) {
    return what + " order " + std::to_string(m.order) + "; expected 1 to " +
           std::to_string(kMaxHarmonics) + " harmonics for transmission_error, 0 to " +
           std::to_string(kMaxTorsionTerms) + " terms for torsion_curve, 1 to " +
           std::to_string(kMaxDriftDegree) +
           " (degree) for registration_drift, a campaign index ≥ 1 for session_frames, the "
           "campaigns after the first (≥ 1) for campaign_joint_zero, else 0";
  }
  const size_t count = traits->parameter_names(dof, m.order).size();
  if (m.parameters.size() != count || m.sigma.size() != count) {
    return what + " has " + std::to_string(m.parameters.size()) + " parameters and " +
           std::to_string(m.sigma.size()) + " sigmas; expected " + std::to_string(count);
  }
  for (int i = 0; i < static_cast<int>(count); ++i) {
    const double value = m.parameter(i), sigma = m.sigma[static_cast<size_t>(i)];
    if (!std::isfinite(value) || !std::isfinite(sigma) || sigma < 0.0) {
      return what + " parameter " + std::to_string(i) + " = " + std::to_string(value) + " (σ " +
             std::to_string(sigma) + "); expected finite values, σ ≥ 0";
    }
  }
  if (traits->uses_joint != (m.joint >= 0) || m.joint >= dof) {
    return what + " joint index " + std::to_string(m.joint) + "; expected " +
           (traits->uses_joint ? "0 to " + std::to_string(dof - 1) : std::string("-1 (none)"));
  }
  if (traits->uses_source_joint != (m.source_joint >= 0 && m.source_joint < dof) ||
      (traits->uses_source_joint && m.source_joint == m.joint) ||
      (!traits->uses_source_joint && m.source_joint != -1)) {
    return what + " source joint index " + std::to_string(m.source_joint) +
           "; expected a joint other than the moved one for joint_coupling, else -1";
  }
  if (!traits->has_coverage && !m.coverage.arcs_rad.empty()) {
    return what + " has a joint-angle coverage; expected one only for transmission_error";
  }
  if (const std::string problem = coverageProblem(m.coverage); !problem.empty()) {
    return what + " " + problem;
  }
  return traits->problem != nullptr ? traits->problem(m, dof) : std::string();
}

std::string describe(const Mechanism& m) {
  const MechanismTraits* traits = findMechanismTraits(m.kind);
  std::string s = toString(m.kind);
  if (traits != nullptr && traits->describe_suffix != nullptr) s += traits->describe_suffix(m);
  return s;
}

double PhysicalModel::linkLengthScale(double temp_c) const noexcept {
  if (!std::isfinite(temp_c)) return 1.0;
  double scale = 1.0;
  for (const Mechanism& m : mechanisms) {
    if (m.kind == MechanismKind::kThermalExpansion) {
      const mechanism::ThermalExpansion<const double> expansion =
          view<mechanism::ThermalExpansion>(m);
      scale *= 1.0 + expansion.expansion_per_k() * (temp_c - expansion.referenceTemp_c());
    }
  }
  return scale;
}

bool isMeasurementOnly(MechanismKind kind) noexcept {
  const MechanismTraits* traits = findMechanismTraits(kind);
  return traits != nullptr && traits->measurement_only;
}

bool PhysicalModel::has(MechanismKind kind) const noexcept {
  for (const Mechanism& m : mechanisms) {
    if (m.kind == kind) return true;
  }
  return false;
}

uint32_t jointsOutsideCoverage(const PhysicalModel& model, const JointVector& q_rad) noexcept {
  uint32_t outside = 0;
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kTransmissionError && m.joint < q_rad.size() &&
        coverageGate(m.coverage, q_rad(m.joint)) < 1.0) {
      outside |= 1u << m.joint;
    }
  }
  return outside;
}

namespace {

/// A payload's weight at the pose in ws as a wrench (root axes, about the root origin): its
/// weight at its centre of gravity.
Vec6 payloadWrenchInRoot(const KinematicChain& chain, const ChainWorkspace& ws,
                         const Vec3& gravity_Root, const PointPayload& payload) noexcept {
  Vec6 W_Root;
  W_Root.head<3>() = payload.mass_kg * gravity_Root;
  W_Root.tail<3>() = (ws.X_RootFrame[static_cast<size_t>(chain.dof())] * payload.p_CoGInLast_m)
                         .cross(W_Root.head<3>());
  return W_Root;
}

/// The joint torques of a payload's weight at the pose in ws, N·m: every joint carries it.
void payloadTorques(const KinematicChain& chain, const ChainWorkspace& ws,
                                      const Vec3& gravity_Root, const PointPayload& payload,
                                      JointVector& tau_nm) noexcept {
  const int n = chain.dof();
  const Vec6 W_Root = payloadWrenchInRoot(chain, ws, gravity_Root, payload);
  for (int k = 1; k <= n; ++k) tau_nm(k - 1) = jointTwistInRoot(chain, ws, k).dot(W_Root);
}

/// δ = Σ_j g_j δ_j of the profiles' geometry (6(n+1) entries; mechanisms.hpp) at the gates g per
/// joint (a joint without a profile has g 0); false when no profile moves the poses.
bool profileGeometryDelta(const PhysicalModel& model, const std::array<double, kMaxJoints>& gate,
                          std::array<double, 6 * (kMaxJoints + 1)>& delta) noexcept {
  delta.fill(0.0);
  bool corrected = false;
  for (const Mechanism& m : model.mechanisms) {
    const double g = m.kind == MechanismKind::kProfileGeometry ? gate[static_cast<size_t>(m.joint)] : 0.0;
    if (g == 0.0) continue;
    for (size_t i = 0; i < m.parameters.size(); ++i) {
      delta[i] += g * m.parameter(static_cast<int>(i));
    }
    corrected = true;
  }
  return corrected;
}

}  // namespace

PhysicalConstants physicalConstants(const PhysicalModel& model) noexcept {
  PhysicalConstants constants;
  std::array<double, kMaxJoints> open_gate{};
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kTransmissionError) open_gate[static_cast<size_t>(m.joint)] = 1.0;
  }
  std::array<double, 6 * (kMaxJoints + 1)> delta;
  constants.has_open_geometry = profileGeometryDelta(model, open_gate, delta);
  for (int k = 0; k <= model.chain_Tracker.dof(); ++k) {
    constants.exp_open_geometry[static_cast<size_t>(k)] =
        constants.has_open_geometry ? lie::expSE3(Eigen::Map<const Vec6>(delta.data() + 6 * k))
                                    : Pose::Identity();
  }
  evaluateInitialPoses(model.chain_Tracker, 1.0,
                       constants.has_open_geometry ? &constants.exp_open_geometry : nullptr,
                       constants.initial_open);
  return constants;
}

namespace {

/// What the fixed point takes from the mechanisms that act before it (physicalLinkAngles).
struct CommandedSide {
  /// θ₀ = q and the wrench as measured, copy-constructed (cheaper than assigned).
  CommandedSide(const JointVector& q_rad, const Vec6& wrench) noexcept
      : theta0_rad(q_rad), wrench_Sensor(wrench) {}

  JointVector theta0_rad;                  ///< θ₀: q and the commanded-angle mechanisms
  std::array<double, kMaxJoints> gate{};   ///< each profile's gate (0: no profile)
  bool gates_open = true;                  ///< every transmission_error's gate is 1
  Vec6 wrench_Sensor;                      ///< the measured wrench less the sensor's bias
  const Mechanism* self_weight = nullptr;  ///< the model's self_weight, if any
};

/// θ₀ = q plus the commanded-angle mechanisms (each kind's MechanismTraits::add_link_angle_offset:
/// joint_coupling, joint_zero_drift where temp_c is known; and the transmission profiles), each
/// profile's gate once (it switches the profile and its share of the geometry), and the wrench
/// less the sensor's bias. profile_slope, when given, gets each profile's derivative by its
/// commanded angle (zeroed before).
void addCommandedSide(const PhysicalModel& model, const JointVector& q_rad,
                      const JointTrig& trig_q, double temp_c, JointVector* profile_slope,
                      CommandedSide& side) noexcept {
  JointVector& theta0 = side.theta0_rad;
  for (const Mechanism& m : model.mechanisms) {
    const MechanismTraits* traits = findMechanismTraits(m.kind);
    if (traits != nullptr && traits->add_link_angle_offset != nullptr) {
      traits->add_link_angle_offset(m, q_rad, temp_c, theta0);
    } else if (m.kind == MechanismKind::kTransmissionError) {
      const size_t j = static_cast<size_t>(m.joint);
      double gate_slope = 0.0, slope = 0.0;
      side.gate[j] =
          coverageGate(m.coverage, q_rad(m.joint), profile_slope ? &gate_slope : nullptr);
      side.gates_open = side.gates_open && side.gate[j] == 1.0;
      theta0(m.joint) +=
          mechanism::gatedOffset(m, trig_q.sin(m.joint), trig_q.cos(m.joint), side.gate[j],
                                 gate_slope, profile_slope ? &slope : nullptr);
      if (profile_slope) (*profile_slope)(m.joint) += slope;
    } else if (m.kind == MechanismKind::kSensorBias) {
      const mechanism::SensorBias<const double> bias = view<mechanism::SensorBias>(m);
      for (int i = 0; i < 6; ++i) side.wrench_Sensor(i) -= bias.wrench(i);
    } else if (m.kind == MechanismKind::kSelfWeight) {
      side.self_weight = &m;
    }
  }
}

/// The initial poses of every pass (the thermal scale and the profiles' geometry hold for the
/// whole fixed point) at this link-length scale: with every gate open, the constants' own at
/// scale 1 (the usual call: returned, nothing evaluated), else null.
const InitialPoses* constantInitialPoses(double link_length_scale,
                                         const PhysicalConstants* constants,
                                         const CommandedSide& side) noexcept {
  const bool usual = constants != nullptr && side.gates_open && link_length_scale == 1.0;
  return usual ? &constants->initial_open : nullptr;
}

/// The initial poses where constantInitialPoses has none, evaluated into initial.
void evaluateInitialPosesOf(const PhysicalModel& model, double link_length_scale,
                            const PhysicalConstants* constants, const CommandedSide& side,
                            InitialPoses& initial) noexcept {
  if (constants != nullptr && side.gates_open) {
    evaluateInitialPoses(model.chain_Tracker, link_length_scale,
                         constants->has_open_geometry ? &constants->exp_open_geometry : nullptr,
                         initial);
    return;
  }
  std::array<double, 6 * (kMaxJoints + 1)> delta;
  const bool corrected = profileGeometryDelta(model, side.gate, delta);
  evaluateInitialPoses(model.chain_Tracker, link_length_scale, corrected ? delta.data() : nullptr,
                       initial);
}

/// The fixed point θ = θ₀ + Δθ(τ(θ)) from θ as out holds it, and its frames, with what it
/// reuses from or keeps for another evaluation at the same commanded angles (FirstPass). The
/// passes move θ by the deflection only (~1e-3 rad): sin and cos of θ₀ once, then by the angle
/// sum.
///
/// Its arrays are FixedPointScratch's, outside the object, and it refers to the outputs directly:
/// its address then never escapes into the calls it makes, so the compiler keeps its members in
/// registers across them (as it did when the steps were lambdas; bench answers identical).
struct FixedPointScratch {
  JointTrig trig0, trig;  ///< sin and cos of θ₀ and of the pass's θ
  Jacobian J;
  JointVector tau_self;
  InitialPoses tilted;  ///< off_axis_compliance: the initial poses with the last pass's tilts
};

class FixedPoint {
 public:
  FixedPoint(const PhysicalModel& model, const JointVector& q_rad, const CommandedSide& side,
             const InitialPoses& initial, const JointTrig& trig_q, FirstPass* first,
             const PhysicalLinkAnglesOut& out, FixedPointScratch& scratch) noexcept
      : model_(model),
        chain_(model.chain_Tracker),
        n_(chain_.dof()),
        q_rad_(q_rad),
        side_(side),
        theta0_(side.theta0_rad),
        initial_(initial),
        trig_q_(trig_q),
        first_(first),
        keep_(first != nullptr && !first->kept),
        tilting_(model.has(MechanismKind::kOffAxisCompliance)),
        ws_(out.ws),
        theta_rad_(out.theta_rad),
        tau_nm_(out.tau_nm),
        trig0_(scratch.trig0),
        trig_(scratch.trig),
        J_(scratch.J),
        tau_self_(scratch.tau_self),
        tilted_(scratch.tilted) {
    // The frames at θ₀ another evaluation kept, where they are this one's.
    reuse_ = first_ != nullptr && first_->kept && first_->q_rad == q_rad_ &&
             first_->theta0_rad == theta0_ &&
             std::equal(initial_.begin(), initial_.begin() + n_ + 1, first_->initial.begin(),
                        [](const Pose& a, const Pose& b) { return a.matrix() == b.matrix(); });
    if (reuse_) {
      trig0_ = first_->trig0;
    } else {
      shiftedJointTrig(trig_q_, q_rad_, theta0_ - q_rad_, trig0_);
    }
  }

  /// The passes, with a payload's torques or without (a loop of its own each, so that the usual
  /// one, a measured wrench or none, is compiled as it was).
  template <bool kWithPayload>
  void run(int passes, bool has_sensor, const PointPayload* payload) noexcept {
    for (int pass = 0; pass < passes; ++pass) {
      evaluate();
      tau_nm_.setZero(n_);
      if (has_sensor) {
        jacobian();
        tau_nm_ = jointTorques(
            J_, wrenchInRoot(framePose(chain_, ws_, model_.sensor_frame), side_.wrench_Sensor));
      }
      if constexpr (kWithPayload) {
        payloadTorques(chain_, ws_, model_.gravity_Tracker, *payload, tau_nm_);
      }
      if (side_.self_weight != nullptr) {
        selfWeightTorques(chain_, ws_, model_.gravity_Tracker, side_.self_weight->parameters,
                          tau_self_);
        tau_nm_ += tau_self_;
      }
      deflect(tau_nm_);
      if (tilting_) tiltFrames(loadWrenchInRoot(has_sensor, payload));
    }
  }

  /// The frames at θ into out.ws: reused or kept at θ₀.
  void evaluate() noexcept {
    at_theta0_ = theta_rad_ == theta0_ && !tilted_now_;
    if (!at_theta0_) {
      shiftedJointTrig(trig0_, theta0_, theta_rad_ - theta0_, trig_);
      forwardKinematics(chain_, theta_rad_, ws_, tilted_now_ ? tilted_ : initial_, &trig_);
    } else if (reuse_) {
      ws_ = first_->ws;
    } else {
      forwardKinematics(chain_, theta_rad_, ws_, initial_, &trig0_);
      if (keep_ && !kept_frames_) {
        first_->ws = ws_;
        kept_frames_ = true;
      }
    }
  }

  /// The tool_mount_compliance's shift of the tip under the load's force, at the last frames
  /// (after the passes: the shift moves no joint, and the torques it would change by moving the
  /// load ~0.1 mm are left out, as the link angles' own effect on them is not): the measured
  /// force in the sensor's axes, or the payload's weight in the mount's. The frames another
  /// evaluation keeps (FirstPass) are copied before it, unshifted.
  void shiftTool(bool has_sensor, const PointPayload* payload) noexcept {
    const Mechanism* mount = nullptr;
    for (const Mechanism& m : model_.mechanisms) {
      if (m.kind == MechanismKind::kToolMountCompliance) mount = &m;
    }
    if (mount == nullptr || (!has_sensor && payload == nullptr)) return;
    const bool sensor_known =
        model_.sensor_frame >= 0 &&
        model_.sensor_frame < static_cast<int>(chain_.frames().size());
    const Eigen::Matrix3d R_RootMount =
        sensor_known ? framePose(chain_, ws_, model_.sensor_frame).linear()
                     : ws_.X_RootFrame[static_cast<size_t>(n_)].linear();
    const Vec3 force_Mount =
        has_sensor ? Vec3(side_.wrench_Sensor.head<3>())
                   : Vec3(R_RootMount.transpose() * (payload->mass_kg * model_.gravity_Tracker));
    ws_.X_RootFrame[static_cast<size_t>(n_ + 1)].translation() +=
        R_RootMount * mechanism::toolShift_m(*mount, force_Mount);
  }

  /// Keeps this evaluation's frames at θ₀ for the next ones, when it evaluated them.
  void keepFirstPass() noexcept {
    if (!kept_frames_) return;
    first_->q_rad = q_rad_;
    first_->theta0_rad = theta0_;
    std::copy(initial_.begin(), initial_.begin() + n_ + 1, first_->initial.begin());
    first_->trig_q = trig_q_;
    first_->trig0 = trig0_;
    first_->kept = true;
  }

 private:
  void jacobian() noexcept {
    if (at_theta0_ && reuse_ && first_->has_J) {
      J_ = first_->J;
      return;
    }
    spatialJacobian(chain_, ws_, J_);
    if (at_theta0_ && keep_) {
      first_->J = J_;
      first_->has_J = true;
    }
  }

  /// The load's wrench at the pass's frames (root axes, about the root origin): the measured
  /// wrench at the sensor, or the payload's weight.
  Vec6 loadWrenchInRoot(bool has_sensor, const PointPayload* payload) const noexcept {
    if (has_sensor) {
      return wrenchInRoot(framePose(chain_, ws_, model_.sensor_frame), side_.wrench_Sensor);
    }
    if (payload != nullptr) {
      return payloadWrenchInRoot(chain_, ws_, model_.gravity_Tracker, *payload);
    }
    return Vec6::Zero();
  }

  /// Each off_axis_compliance's tilt of its joint's frame under the load's moment about the
  /// frame's origin at this pass's frames, for the next evaluation: a turn of the joint's
  /// initial pose by the tilt as the frame before the joint's motion (at the new θ) sees it, so
  /// that the joint's frame, what hangs from it and everything beyond turn with it.
  void tiltFrames(const Vec6& W_Root) noexcept {
    std::copy(initial_.begin(), initial_.begin() + n_ + 1, tilted_.begin());
    for (const Mechanism& m : model_.mechanisms) {
      if (m.kind != MechanismKind::kOffAxisCompliance) continue;
      const Pose& X_RootJoint = ws_.X_RootFrame[static_cast<size_t>(m.joint + 1)];
      const Vec3 axis = chain_.joints()[static_cast<size_t>(m.joint)].twist_Local.tail<3>();
      const Vec3 moment_Joint =
          X_RootJoint.linear().transpose() *
          (W_Root.tail<3>() - X_RootJoint.translation().cross(W_Root.head<3>()));
      const Vec3 tilt_BeforeMotion = lie::expSO3(axis * theta_rad_(m.joint)) *
                                     mechanism::frameTilt_rad(m, axis, moment_Joint);
      Pose& T = tilted_[static_cast<size_t>(m.joint)];
      T.linear() = T.linear() * lie::expSO3(tilt_BeforeMotion);
    }
    tilted_now_ = true;
  }

  /// θ = θ₀ + Δθ(τ): the compliance, plus each joint's torque-deflection mechanism.
  void deflect(const JointVector& tau) noexcept {
    theta_rad_ = theta0_ + model_.compliance_rad_per_nm.cwiseProduct(tau);
    for (const Mechanism& m : model_.mechanisms) {
      if (isTorqueDeflection(m.kind)) theta_rad_(m.joint) += torqueDeflection(m, tau(m.joint));
    }
  }

  const PhysicalModel& model_;
  const KinematicChain& chain_;
  const int n_;
  const JointVector& q_rad_;
  const CommandedSide& side_;
  const JointVector& theta0_;
  const InitialPoses& initial_;
  const JointTrig& trig_q_;
  FirstPass* const first_;
  const bool keep_;  ///< first_ keeps this evaluation's frames at θ₀
  const bool tilting_;  ///< the model has an off_axis_compliance (tiltFrames)
  ChainWorkspace& ws_;  ///< the outputs (PhysicalLinkAnglesOut)
  JointVector& theta_rad_;
  JointVector& tau_nm_;
  JointTrig& trig0_;  ///< the scratch (FixedPointScratch)
  JointTrig& trig_;
  Jacobian& J_;
  JointVector& tau_self_;
  InitialPoses& tilted_;  ///< initial_ with each off_axis_compliance's last tilt
  bool reuse_ = false;        ///< the frames at θ₀ are first_'s
  bool at_theta0_ = false;    ///< ws_ holds the frames at θ₀
  bool kept_frames_ = false;  ///< and first_ keeps them
  bool tilted_now_ = false;   ///< the frames are evaluated with tilted_, not initial_
};

/// physicalLinkAngles from θ₀ on: θ's start, the passes (with a payload's torques or the
/// measured wrench's), the frames at the last θ, and what is kept for the next evaluation.
void solveFixedPoint(const PhysicalModel& model, const JointVector& q_rad,
                     const CommandedSide& side, const InitialPoses& initial,
                     const JointTrig& trig_q, const PhysicalLinkAnglesOut& out,
                     const PhysicalEvaluation& how) noexcept {
  const int n = model.chain_Tracker.dof();
  // The wrench's torques: a measured wrench needs the sensor's frame, a payload none.
  const bool has_sensor =
      how.payload == nullptr && model.sensor_frame >= 0 &&
      model.sensor_frame < static_cast<int>(model.chain_Tracker.frames().size());
  const bool has_payload = how.payload != nullptr && how.payload->mass_kg != 0.0;
  // Without a wrench or self weight every torque is zero and θ = θ₀: no passes.
  const bool loaded = has_sensor || has_payload || side.self_weight != nullptr;
  const int passes = !loaded ? 0 : how.start != nullptr ? how.start->passes : kFixedPointPasses;
  out.theta_rad = side.theta0_rad;
  if (loaded && how.start != nullptr && how.start->deflection_rad != nullptr) {
    out.theta_rad += *how.start->deflection_rad;
  }
  out.tau_nm.setZero(n);
  FirstPass* const first = how.start != nullptr ? how.start->first_pass : nullptr;
  FixedPointScratch scratch;
  FixedPoint fixed_point(model, q_rad, side, initial, trig_q, first, out, scratch);
  if (has_payload) {
    fixed_point.run<true>(passes, has_sensor, how.payload);
  } else {
    fixed_point.run<false>(passes, has_sensor, how.payload);
  }
  fixed_point.evaluate();
  fixed_point.shiftTool(has_sensor, has_payload ? how.payload : nullptr);
  if (how.start != nullptr && how.start->deflection_out_rad != nullptr) {
    *how.start->deflection_out_rad = out.theta_rad - side.theta0_rad;
  }
  fixed_point.keepFirstPass();
}

}  // namespace

bool physicalLinkAngles(const PhysicalModel& model, const JointVector& q_rad,
                        const Vec6& wrench_Sensor, double temp_c, const PhysicalLinkAnglesOut& out,
                        const PhysicalEvaluation& how) noexcept {
  const int n = model.chain_Tracker.dof();
  if (q_rad.size() != n || model.compliance_rad_per_nm.size() != n) return false;

  if (out.profile_slope) out.profile_slope->setZero(n);
  FirstPass* const first = how.start != nullptr ? how.start->first_pass : nullptr;
  // sin and cos of q serve the profiles and, shifted by θ₀ − q (~1e-4 rad), θ₀'s own.
  JointTrig trig_q;
  if (first != nullptr && first->kept && first->q_rad == q_rad) {
    trig_q = first->trig_q;
  } else {
    jointTrig(q_rad, trig_q);
  }
  CommandedSide side(q_rad, wrench_Sensor);
  addCommandedSide(model, q_rad, trig_q, temp_c, out.profile_slope, side);
  const double link_length_scale = model.linkLengthScale(temp_c);
  // Constructing 9 poses costs on the hot path: only where they are evaluated here.
  if (const InitialPoses* initial = constantInitialPoses(link_length_scale, how.constants, side)) {
    solveFixedPoint(model, q_rad, side, *initial, trig_q, out, how);
    return true;
  }
  InitialPoses initial_here;
  evaluateInitialPosesOf(model, link_length_scale, how.constants, side, initial_here);
  solveFixedPoint(model, q_rad, side, initial_here, trig_q, out, how);
  return true;
}

}  // namespace stepcal
