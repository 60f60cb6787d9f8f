#include "stepcal/runtime/corrector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>
#include <vector>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/mechanisms/joint_coupling.hpp"
#include "stepcal/common/mechanisms/sensor_bias.hpp"
#include "damped_step.hpp"

namespace stepcal::runtime {
namespace {

/// n × n joint-space matrix, heap-free.
using JointMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxJoints, kMaxJoints>;

/// Largest |RᵀR − I| entry and |det R − 1| accepted for a desired rotation.
constexpr double kRotationTolerance = 1e-6;
/// Factor on the rigid reach bound leaving room for the deflection and the residual twist.
constexpr double kReachMargin = 1.05;
/// Share of the prior variance explained at the least-covered training input that a query must
/// keep to be in the GPR's domain.
constexpr double kDomainVarianceShare = 0.25;
/// An iterate farther than this (any joint) from where the GPR's twist was last evaluated
/// evaluates it again, rad (3°: a seed from the previous cycle, or a few degrees off, is
/// closer; the GPR's length scales over the joint angles are tens of degrees).
constexpr double kFrozenTwistDistance_rad = 0.05;
/// A Newton step whose largest joint change is at most this, rad, leads to an iterate that is
/// evaluated with the full model rather than its approximation: the approximation is off by
/// ~1e-6 of the step, which after the long first steps is far below what the next steps correct,
/// but near the answer would compete with tight tolerances (1e-10) and cost steps.
constexpr double kFullModelStep_rad = 1e-2;

/// FNV-1a 64 of a byte range.
uint64_t fnv1a64(const std::vector<uint8_t>& bytes) noexcept {
  uint64_t h = 1469598103934665603ull;
  for (const uint8_t b : bytes) {
    h ^= b;
    h *= 1099511628211ull;
  }
  return h;
}

/// Whether R is a proper rotation to within kRotationTolerance.
bool isRotation(const Mat3& R) noexcept {
  return R.allFinite() &&
         (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff() <= kRotationTolerance &&
         std::abs(R.determinant() - 1.0) <= kRotationTolerance;
}

bool validOptions(const InverseOptions& o) noexcept {
  const double values[] = {o.position_tolerance_m, o.orientation_tolerance_rad, o.damping,
                           o.singular_value_threshold, o.max_step_rad};
  for (const double v : values) {
    if (!std::isfinite(v) || v < 0.0) return false;
  }
  return o.max_iterations >= 0 && o.max_step_rad > 0.0;
}

/// Centre and radius of a sphere holding every rigid tip position of the chain, tracker frame, m.
/// Each initial pose moves the tip's distance from the centre by at most its translation's
/// length; joint k, a rotation about an axis at ‖ω × v‖ from frame k's origin (|ω| = 1, v ⟂ ω),
/// by at most twice that.
std::pair<Vec3, double> reachSphere(const KinematicChain& chain) {
  double radius_m = 0.0;
  for (int k = 1; k <= chain.dof(); ++k) {
    const Vec6& s = chain.joints()[static_cast<size_t>(k - 1)].twist_Local;
    radius_m += 2.0 * s.tail<3>().cross(s.head<3>()).norm() +
                chain.initialPose(k).translation().norm();
  }
  return {chain.initialPose(0).translation(), kReachMargin * radius_m};
}

/// A call's terms resolved against the model (prepare): what the steps use.
struct Prepared {
  Pose X_TrackerFrame = Pose::Identity();  ///< the call's frame in the tracker frame
  bool in_tracker = true;                  ///< X_TrackerFrame is the identity
  Pose X_TipTcp = Pose::Identity();        ///< the TCP in the calibrated target's frame
  bool at_target = true;                   ///< X_TipTcp is the identity
  bool tool_offset = false;                ///< X_TipTcp moves the point (its translation ≠ 0)
  Pose X_ControllerFrameBase = Pose::Identity();  ///< base → controller frame (user frame⁻¹)
  Pose X_NominalRefTcp = Pose::Identity(); ///< the tool as given, from the nominal ref frame
  bool from_flange = false;                ///< the nominal ref frame is the flange, not the tip
  bool payload = false;                    ///< the load is a payload (point), not a wrench
  PointPayload point;
};
/// The calibration's own terms: tracker frame, the measured target, a wrench.
const Prepared kOwnTerms{};

bool finitePose(const Pose& X) noexcept {
  return X.translation().allFinite() && isRotation(X.linear());
}

/// The terms against the model: kOk, or kBadRequest when they do not hold.
Status prepare(const RuntimeModel& model, const CallTerms& terms, Prepared& out) noexcept {
  const int frame = static_cast<int>(terms.frame), tool = static_cast<int>(terms.tool_from),
            load = static_cast<int>(terms.load_from),
            cog = static_cast<int>(terms.payload.frame);
  if (frame < 0 || frame > 2 || tool < 0 || tool > 1 || load < 0 || load > 1 || cog < 0 ||
      cog > 1 || !finitePose(terms.X_Tool) ||
      (terms.frame == PoseFrame::kUser && !finitePose(terms.X_BaseUser))) {
    return Status::kBadRequest;
  }
  out.from_flange = terms.tool_from == ToolFrom::kFlange;
  if (out.from_flange && !model.has_flange) return Status::kBadRequest;
  out.X_TrackerFrame = trackerFromFrame(model, terms.frame, terms.X_BaseUser);
  out.in_tracker = terms.frame == PoseFrame::kTracker;
  out.X_TipTcp = out.from_flange ? Pose(model.X_TipFlange * terms.X_Tool) : terms.X_Tool;
  out.at_target = out.X_TipTcp.matrix() == Eigen::Matrix4d::Identity();
  out.tool_offset = out.X_TipTcp.translation().squaredNorm() > 0.0;
  out.X_ControllerFrameBase =
      terms.frame == PoseFrame::kUser ? terms.X_BaseUser.inverse() : Pose::Identity();
  out.X_NominalRefTcp = terms.X_Tool;
  out.payload = terms.load_from == LoadFrom::kPayload;
  if (!out.payload) return Status::kOk;
  const Payload& p = terms.payload;
  if (!std::isfinite(p.mass_kg) || p.mass_kg < 0.0 || !p.p_CoG_m.allFinite() ||
      (p.mass_kg > 0.0 && model.physical.gravity_Tracker.isZero(0.0))) {
    return Status::kBadRequest;
  }
  out.point.mass_kg = p.mass_kg;
  if (p.mass_kg == 0.0) return Status::kOk;  // no load: nowhere to put it
  if (p.frame == CogFrame::kFlange && !model.has_flange) return Status::kBadRequest;
  const Pose X_LastCogFrame = p.frame == CogFrame::kFlange
                                  ? Pose(model.X_LastTip * model.X_TipFlange)
                                  : Pose(model.X_LastTip * out.X_TipTcp);
  out.point.p_CoGInLast_m = X_LastCogFrame * p.p_CoG_m;
  return Status::kOk;
}

/// The model's sensor_bias, if any, sensor axes: N, N·m.
Vec6 sensorBias(const PhysicalModel& model) noexcept {
  Vec6 bias = Vec6::Zero();
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kSensorBias) {
      for (int i = 0; i < 6; ++i) bias(i) += view<mechanism::SensorBias>(m).wrench(i);
    }
  }
  return bias;
}

/// What a sensor tared unloaded reads from the payload at the pose in ws.chain: its weight in
/// sensor axes, moment about the sensor's origin, plus the model's sensor bias; the model's
/// unloaded wrench when it has no sensor frame. N, N·m.
Vec6 payloadReading(const RuntimeModel& model, const Workspace& ws,
                    const PointPayload& point) noexcept {
  const PhysicalModel& physical = model.physical;
  if (physical.sensor_frame < 0) return model.unloaded_wrench_Sensor;
  const KinematicChain& chain = physical.chain_Tracker;
  const Pose X_RootSensor = framePose(chain, ws.chain, physical.sensor_frame);
  const Vec3 f_Root = point.mass_kg * physical.gravity_Tracker;
  const Vec3 p_CoGRoot = ws.chain.X_RootFrame[static_cast<size_t>(chain.dof())] * point.p_CoGInLast_m;
  Vec6 reading;
  reading.head<3>() = X_RootSensor.linear().transpose() * f_Root;
  reading.tail<3>() = (X_RootSensor.inverse() * p_CoGRoot).cross(reading.head<3>());
  return reading + sensorBias(physical);
}

/// The wrench a call's answer and its GPR input use at the pose in ws.chain (after physicalTip):
/// the payload's reading, or the call's wrench.
Vec6 loadReading(const RuntimeModel& model, const Workspace& ws, const Prepared& call,
                 const Vec6& wrench_Sensor) noexcept {
  return call.payload ? payloadReading(model, ws, call.point) : wrench_Sensor;
}

/// How physicalTip evaluates the physical model's deflection.
enum class Deflection {
  kModel,      ///< the model itself: the fixed point's passes from θ₀
  kOnePass,    ///< one pass from ws.deflection_rad: within ~1e-3 of the deflection's change since
  kHeld,       ///< ws.deflection_rad itself: off by the deflection's change since (~3e-5 rad
               ///< after a 2° step of the UR10), for a chord step's iterate only
};

/// The physical model's tip at q: FK at its link angles (every mechanism, the thermal length
/// scale at temp_c), the deflection as `deflection` says (FixedPointStart). Leaves ws.chain
/// evaluated there, ws.link_rad, ws.torque_nm (zero with kHeld: no pass), ws.deflection_rad and,
/// with_slopes (for a Jacobian there), ws.profile_slope set. Sizes must have been checked.
Pose physicalTip(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                 const Prepared& call, const Vec6& wrench_Sensor, double temp_c, bool with_slopes,
                 Deflection deflection = Deflection::kModel) noexcept {
  FixedPointStart start;
  start.deflection_out_rad = &ws.deflection_rad;
  // A frame's tilt (off_axis_compliance) is not held between evaluations: the model itself.
  if (deflection != Deflection::kModel && !model.tilts_frames) {
    start.passes = deflection == Deflection::kOnePass ? 1 : 0;
    start.deflection_rad = &ws.deflection_rad;
  }
  const bool sized = physicalLinkAngles(
      model.physical, q_rad, wrench_Sensor, temp_c,
      {ws.chain, ws.link_rad, ws.torque_nm, with_slopes ? &ws.profile_slope : nullptr},
      {&model.physical_constants, &start, call.payload ? &call.point : nullptr});
  STEPCAL_INVARIANT(sized, "the physical model and q were checked to have the chain's size");
  return tipPose(ws.chain);
}

/// The GPR's residual twist ξ in the tip's axes at (q, measured wrench) into ws.gpr_mean (zero
/// without a GPR), at a physical tip turned by R_TrackerTip (a GPR per payload force learns it in
/// the tracker's axes: tipTwistFromGprOutput); with_std also writes its std bound (the subset
/// GP's, GprPredictor::predictMeanAndBoundInto, per output of the GPR) to ws.gpr_std.
const Vec6& residualTwist(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                          const Vec6& wrench_Sensor, const Mat3& R_TrackerTip,
                          bool with_std) noexcept {
  if (!model.file.gpr) {
    ws.gpr_mean.setZero();
    return ws.gpr_mean;
  }
  ws.gpr_input.head(q_rad.size()) = q_rad;
  ws.gpr_input.tail<6>() = wrench_Sensor;
  model.gpr.predictMeanAndBoundInto(ws.gpr_input.data(), ws.gpr_mean.data(),
                                    with_std ? ws.gpr_std.data() : nullptr, ws.gpr);
  tipTwistFromGprOutput(*model.file.gpr, R_TrackerTip, ws.gpr_mean);
  return ws.gpr_mean;
}

/// The corrected tip T_C2 at q (docs/method.md eq. 32): the physical tip, then exp(ξ̂) of the GPR mean
/// at (q, measured wrench), with its std bound in ws.gpr_std; the wrench used in *reading.
Pose correctedTip(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                  const Prepared& call, const Vec6& wrench_Sensor, double temp_c,
                  Vec6* reading) noexcept {
  const Pose X_physical = physicalTip(model, ws, q_rad, call, wrench_Sensor, temp_c, false);
  *reading = loadReading(model, ws, call, wrench_Sensor);
  if (!model.file.gpr) return X_physical;
  return Pose(X_physical *
              lie::expSE3(residualTwist(model, ws, q_rad, *reading, X_physical.linear(), true)));
}

/// Whether the model's accuracy includes its mechanisms' σ (they are in the calls' workspace).
bool statesMechanismAccuracy(const RuntimeModel& model) noexcept {
  return model.file.accuracy && hasMechanismUncertainty(model.physical);
}

/// The fitted parameters' share of the covariance (parameterCovariance) of the tip just
/// evaluated at q: ws.chain at its link angles, ws.torque_nm; the mechanisms' share evaluated
/// again at (q, the call's load, temp_c) in ws.mechanism_accuracy. False when the mechanisms'
/// share cannot be stated (a workspace made for another model, a failed evaluation).
bool parameterShare(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                    const Prepared& call, const Vec6& wrench_Sensor, double temp_c,
                    Mat6& covariance) noexcept {
  const bool with_mechanisms = statesMechanismAccuracy(model);
  // A workspace made for another model holds its mechanisms: no bound rather than one without
  // this model's share.
  if (with_mechanisms && ws.mechanism_accuracy_for != &model.physical) return false;
  Mat6 mechanism_covariance = Mat6::Zero();
  if (with_mechanisms &&
      !addMechanismCovariance(model.physical, &model.physical_constants,
                              &model.file.accuracy->profile_factors, ws.chain, q_rad,
                              wrench_Sensor, temp_c, call.payload ? &call.point : nullptr,
                              ws.mechanism_accuracy, mechanism_covariance)) {
    return false;
  }
  covariance = parameterCovariance(model.file, model.physical.chain_Tracker, ws.chain,
                                   ws.torque_nm, &mechanism_covariance);
  return true;
}

/// The accuracy of the corrected tip just evaluated at q (correctedTip, or the inverse's full
/// model there): the parameters' share as parameterShare says, the GPR's from ws.gpr_input and
/// ws.gpr_std.
PoseAccuracy answerAccuracy(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                            const Prepared& call, const Vec6& wrench_Sensor, double temp_c,
                            const Mat3& R_TrackerTip) noexcept {
  if (!ws.with_accuracy || !model.file.accuracy) return PoseAccuracy{};
  const GprUncertainty gpr =
      model.file.gpr ? gprUncertainty(model.gpr, model.gpr_noise, ws.gpr_input.data(), ws.gpr_std)
                     : GprUncertainty{};
  Mat6 covariance;
  if (!parameterShare(model, ws, q_rad, call, wrench_Sensor, temp_c, covariance)) {
    return PoseAccuracy{};
  }
  return poseAccuracy(*model.file.accuracy, covariance, R_TrackerTip, gpr);
}

/// RuntimeModel::gpr_noise: per output, the GPR's held-out noise (GprPredictor::heldOutNoise,
/// raw units) less the mean over its training inputs of the parameters' share in its output
/// axes (over the output gain² for a GPR per payload force; an input at zero force adds none).
Vec6 gprWhiteNoise(const RuntimeModel& model) {
  const GprParameters& g = *model.file.gpr;
  const int n = model.file.chain_Tracker.dof();
  const bool tracker_axes = g.payload_force_reference_n > 0.0;
  Workspace ws = makeWorkspace(model);
  Vec6 share = Vec6::Zero();
  const Eigen::Index m = g.inputs_normalised.rows();
  Eigen::VectorXd x_raw(n + 6);
  for (Eigen::Index i = 0; i < m; ++i) {
    x_raw = g.input_offset + g.input_scale.cwiseProduct(g.inputs_normalised.row(i).transpose());
    const double gain = model.gpr.outputGain(x_raw.data());
    if (gain == 0.0) continue;
    const JointVector q_rad = x_raw.head(n);
    const Vec6 wrench_Sensor = x_raw.tail<6>();
    // The training rows' temperature is not among the GPR's inputs: not measured.
    const double temp_c = std::numeric_limits<double>::quiet_NaN();
    const Pose X_TrackerTip =
        physicalTip(model, ws, q_rad, kOwnTerms, wrench_Sensor, temp_c, false);
    Mat6 covariance;
    if (!parameterShare(model, ws, q_rad, kOwnTerms, wrench_Sensor, temp_c, covariance)) continue;
    const Mat3 R = tracker_axes ? Mat3(Mat3::Identity()) : Mat3(X_TrackerTip.linear());
    share.head<3>() += (R.transpose() * covariance.topLeftCorner<3, 3>() * R).diagonal() /
                       (gain * gain);
    share.tail<3>() += (R.transpose() * covariance.bottomRightCorner<3, 3>() * R).diagonal() /
                       (gain * gain);
  }
  share /= static_cast<double>(m);
  Vec6 noise;
  for (int o = 0; o < 6; ++o) {
    const double held_out = model.gpr.heldOutNoise()(o) * g.output_scale(o);
    noise(o) = std::sqrt(std::max(0.0, held_out * held_out - share(o)));
  }
  return noise;
}

/// σ/σ_f from the per-output std bound (raw units) that predictMeanAndBoundInto wrote: the
/// kernel is shared, so output 0 serves (its scale and σ_f are > 0, checked by fromParameters).
/// Equals GprPredictor::relativeStdBound without computing the kernel column a second time.
double relativeStd(const RuntimeModel& model, const Vec6& gpr_std) noexcept {
  const GprParameters& g = model.gpr.parameters();
  return gpr_std(0) / (g.output_scale(0) * g.signal_sigma);
}

bool outOfDomain(const RuntimeModel& model, const Vec6& gpr_std) noexcept {
  return model.file.gpr && relativeStd(model, gpr_std) > model.out_of_domain_relative_std;
}

/// Residual e = (p_desired − p, log(R_desired Rᵀ)^∨), tracker axes: m, rad.
Vec6 poseResidual(const Pose& X_TrackerTip_desired, const Pose& X_TrackerTip) noexcept {
  Vec6 e;
  e << X_TrackerTip_desired.translation() - X_TrackerTip.translation(),
      lie::logSO3(X_TrackerTip_desired.linear() * X_TrackerTip.linear().transpose());
  return e;
}

/// Clamps q into the chain's joint limits; true when a joint was moved.
bool clampToLimits(const KinematicChain& chain, JointVector& q_rad) noexcept {
  bool clamped = false;
  for (int i = 0; i < q_rad.size(); ++i) {
    const ChainJoint& joint = chain.joints()[static_cast<size_t>(i)];
    const double inside = std::clamp(q_rad(i), joint.lower_rad, joint.upper_rad);
    clamped = clamped || inside != q_rad(i);
    q_rad(i) = inside;
  }
  return clamped;
}

/// ad_ξᵀ w of a twist ξ = (v, ω) and a wrench w = (f, m): (f × ω, f × v + m × ω), so that
/// wᵀ [ξ, η] = (ad_ξᵀ w)ᵀ η for every twist η.
Vec6 coadjointTimes(const Vec6& xi, const Vec6& w) noexcept {
  const Vec3 f = w.head<3>(), m = w.tail<3>(), v = xi.head<3>(), omega = xi.tail<3>();
  Vec6 out;
  out.head<3>() = f.cross(omega);
  out.tail<3>() = f.cross(v) + m.cross(omega);
  return out;
}

/// The measured wrench less the model's sensor_bias, if any, sensor axes: N, N·m.
Vec6 unbiasedWrench(const PhysicalModel& model, const Vec6& wrench_Sensor) noexcept {
  Vec6 wrench = wrench_Sensor;
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kSensorBias) {
      for (int i = 0; i < 6; ++i) wrench(i) -= view<mechanism::SensorBias>(m).wrench(i);
    }
  }
  return wrench;
}

/// dθ₀/dq of the commanded-angle mechanisms (mechanisms.hpp): identity, plus c at (j, i) for a
/// joint_coupling of joint j to joint i, plus the gated profile's derivative at (j, j) for a
/// transmission_error of joint j (profile_slope, from physicalLinkAngles at the same q). Exact.
/// True when it differs from the identity.
bool commandedAngleDerivative(const PhysicalModel& model, const JointVector& profile_slope,
                              JointMatrix& dtheta0_dq) noexcept {
  const int n = model.chain_Tracker.dof();
  dtheta0_dq = JointMatrix::Identity(n, n);
  bool changed = false;
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kJointCoupling) {
      dtheta0_dq(m.joint, m.source_joint) += view<mechanism::JointCoupling>(m).ratio();
      changed = true;
    } else if (m.kind == MechanismKind::kTransmissionError) {
      changed = true;
    }
  }
  if (changed) dtheta0_dq.diagonal() += profile_slope;
  return changed;
}

/// ∂θ/∂τ per joint at the torques τ [N·m]: the compliance C, plus the slope of each joint's
/// torque-deflection mechanism (backlash, nonlinear_stiffness, torsion_curve; mechanisms.hpp),
/// rad/(N·m). True when any entry is nonzero.
bool torqueCompliance(const PhysicalModel& model, const JointVector& tau_nm,
                      JointVector& dtheta_dtau) noexcept {
  dtheta_dtau = model.compliance_rad_per_nm;
  for (const Mechanism& m : model.mechanisms) {
    if (!isTorqueDeflection(m.kind)) continue;
    double slope = 0.0;
    torqueDeflection(m, tau_nm(m.joint), &slope);
    dtheta_dtau(m.joint) += slope;
  }
  return !dtheta_dtau.isZero(0.0);
}

/// Derivative of the link angles by the commanded ones, dθ/dq ≈ (I + M) dθ₀/dq with
/// M = diag(∂θ/∂τ) ∂τ/∂θ (the fixed point of physicalLinkAngles, linearised to first order), at
/// the link angles in ws.chain, the torques in ws.torque_nm and the profile slopes in
/// ws.profile_slope, all of the last physicalTip (docs/method.md eq. 13, 15). ∂τ/∂θ is
/// that of the measured wrench less the sensor bias, held in sensor axes: τ_k = ξ_kᵀ w with ξ_k
/// joint k's twist in sensor axes, so ∂τ_k/∂θ_j = ([j ≤ k] − [j ≤ p]) wᵀ [ξ_j, ξ_k], p the
/// sensor's parent joint. The self_weight torques' derivative is left out (solveInverse).
/// twists_Tip: the joints' twists at the link angles with the tip as reference point, root axes
/// (tipPointJacobian's columns). A payload's torques (no wrench held in sensor axes) are left
/// out, as the self weight's.
void linkAngleDerivative(const RuntimeModel& model, const Workspace& ws, const Prepared& call,
                         const Vec6& wrench_Sensor, const Jacobian& twists_Tip,
                         JointMatrix& dtheta_dq) noexcept {
  const PhysicalModel& physical = model.physical;
  const KinematicChain& chain = physical.chain_Tracker;
  const int n = chain.dof();
  JointMatrix dtheta0_dq;
  const bool commanded = commandedAngleDerivative(physical, ws.profile_slope, dtheta0_dq);
  JointVector dtheta_dtau;
  const bool has_sensor = physical.sensor_frame >= 0 && !call.payload;
  if (!has_sensor || !torqueCompliance(physical, ws.torque_nm, dtheta_dtau)) {
    dtheta_dq = dtheta0_dq;
    return;
  }
  // In root axes about the tip: brackets commute with the adjoint, so wᵀ [ξ_j, ξ_k] is the same
  // there, with the wrench's moment taken about the tip too.
  Vec6 wrench_Tip = wrenchInRoot(framePose(chain, ws.chain, physical.sensor_frame),
                                 unbiasedWrench(physical, wrench_Sensor));
  wrench_Tip.tail<3>() -= tipPose(ws.chain).translation().cross(wrench_Tip.head<3>());
  const int p = chain.frames()[static_cast<size_t>(physical.sensor_frame)].parent;
  JointMatrix M = JointMatrix::Zero(n, n);
  for (int j = 0; j < n; ++j) {
    const Vec6 u = coadjointTimes(twists_Tip.col(j), wrench_Tip);  // wᵀ [ξ_j, ·] = uᵀ
    for (int k = 0; k < n; ++k) {
      const int c = (j <= k) - (j < p);  // 0-based j: joint j+1 ≤ p ⇔ j < p
      if (c != 0) M(k, j) = dtheta_dtau(k) * c * u.dot(twists_Tip.col(k));
    }
  }
  // M ~ C ∂τ/∂θ ≈ 1e-3: I + M leaves out M² ~ 1e-6 of dθ/dq, far below what changes a step.
  const JointMatrix series = JointMatrix::Identity(n, n) + M;
  if (commanded) {
    dtheta_dq.noalias() = series * dtheta0_dq;
  } else {
    dtheta_dq = series;
  }
}

/// Jacobian of the corrected tip by the commanded joints into ws.J, at the q of the last
/// physicalTip: the tip point Jacobian at the link angles in ws.chain times dθ/dq
/// (linkAngleDerivative), its reference point moved to the call's TCP. The GPR's own derivative
/// is left out (it is small: a quasi-Newton Jacobian; convergence is always judged on the full
/// model).
void correctedJacobian(const RuntimeModel& model, Workspace& ws, const Prepared& call,
                       const Vec6& wrench_Sensor) noexcept {
  Jacobian J_link;
  tipPointJacobian(model.physical.chain_Tracker, ws.chain, J_link);
  if ((model.physical.sensor_frame < 0 || call.payload) &&
      !model.physical.has(MechanismKind::kJointCoupling)) {
    // No wrench torques and no coupling: dθ/dq = I + diag(profile slopes), a column scaling.
    ws.J.noalias() = J_link * (ws.profile_slope.array() + 1.0).matrix().asDiagonal();
  } else {
    JointMatrix dtheta_dq;
    linkAngleDerivative(model, ws, call, wrench_Sensor, J_link, dtheta_dq);
    ws.J.noalias() = J_link * dtheta_dq;
  }
  if (call.tool_offset) {
    // ṗ_Tcp = ṗ_Tip + ω × r, r from the tip to the TCP (root axes).
    const Vec3 r = tipPose(ws.chain).linear() * call.X_TipTcp.translation();
    for (int j = 0; j < ws.J.cols(); ++j) {
      ws.J.block<3, 1>(0, j) += ws.J.block<3, 1>(3, j).cross(r);
    }
  }
}

/// The OUT_OF_DOMAIN threshold on σ/σ_f: √(1 − kDomainVarianceShare · (1 − s²)), s the largest
/// σ/σ_f at a training input, σ the std bound the real-time calls use (relativeStdBound).
double outOfDomainThreshold(const GprPredictor& gpr) {
  const GprParameters& g = gpr.parameters();
  GprPredictor::Workspace ws = gpr.makeWorkspace();
  double s = 0.0;
  for (Eigen::Index i = 0; i < g.inputs_normalised.rows(); ++i) {
    const Eigen::VectorXd x_raw =
        g.input_offset + g.input_scale.cwiseProduct(g.inputs_normalised.row(i).transpose());
    s = std::max(s, gpr.relativeStdBound(x_raw.data(), ws));
  }
  return std::sqrt(1.0 - kDomainVarianceShare * (1.0 - s * s));
}

/// Whether the physical model turns a measured wrench into deflection: a linear compliance,
/// any kind whose deflection follows the joint's torque, or a tilt or a tool's shift that
/// follows the load.
bool physicalNeedsWrench(const CalibratedModel& file) noexcept {
  if (file.sensor_frame < 0) return false;
  for (const Mechanism& m : file.mechanisms) {
    if (isTorqueDeflection(m.kind) || m.kind == MechanismKind::kOffAxisCompliance ||
        m.kind == MechanismKind::kToolMountCompliance) {
      return true;
    }
  }
  return file.compliance_rad_per_nm.size() > 0 && !file.compliance_rad_per_nm.isZero(0.0);
}

/// Whether the GPR's training wrenches vary (its wrench inputs are the last six) or it is a GPR
/// per payload force (its correction scales with the force read); when not, the constant they
/// take, sensor axes.
bool gprNeedsWrench(const GprParameters& gpr, int dof, Vec6& constant_wrench) noexcept {
  if (gpr.payload_force_reference_n > 0.0) return true;
  const Eigen::MatrixXd& x = gpr.inputs_normalised;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Index d = dof + i;
    if (x.rows() > 0 && x.col(d).maxCoeff() != x.col(d).minCoeff()) return true;
    constant_wrench(i) = x.rows() > 0 ? gpr.input_offset(d) + gpr.input_scale(d) * x(0, d) : 0.0;
  }
  return false;
}

/// The screw part of a small correction δ (v, ω) of an initial pose along a joint's twist s:
/// a s + b (ω_s, 0), the rotation about and the translation along its axis (the least-squares
/// projection onto the two), as a twist.
Vec6 screwPartAlong(const Vec6& delta, const Vec6& twist) {
  Vec6 along_axis = Vec6::Zero();
  along_axis.head<3>() = twist.tail<3>();
  Eigen::Matrix<double, 6, 2> basis;
  basis << twist, along_axis;
  const Eigen::Vector2d coefficients = (basis.transpose() * basis).ldlt().solve(basis.transpose() * delta);
  return basis * coefficients;
}

/// The model's flange in its calibrated target's frame (RuntimeModel::X_TipFlange), from the
/// nominal chain's flange frame, which hangs from frame n. Throws InputError when it hangs from
/// another frame.
Pose calibratedTipFlange(const CalibratedModel& file, const AttachedFrame& flange,
                         const std::string& source) {
  const int n = file.chain_Tracker.dof();
  if (flange.parent != n) {
    throw InputError(std::string("the model's frame '") + kFlangeFrame + "' hangs from chain frame " +
                         std::to_string(flange.parent) + "; a flange moves with the last joint (" +
                         std::to_string(n) + ")",
                     source);
  }
  // T_{n−1,n}: calibrated = nominal · exp(δ). Its screw along joint n's axis trades with
  // T_{n,tip} and is not identified; taken as nominal, it moves to the target's side.
  Pose X_LastFlange = flange.X_ParentFrame;
  if (n >= 2) {
    const Pose deviation = file.nominal_Base.initialPose(n - 1).inverse() *
                           file.chain_Tracker.initialPose(n - 1);
    const Vec6 screw = screwPartAlong(
        lie::logSE3(deviation), file.chain_Tracker.joints()[static_cast<size_t>(n - 1)].twist_Local);
    X_LastFlange = lie::expSE3(screw).inverse() * X_LastFlange;
  }
  return file.chain_Tracker.initialPose(n).inverse() * X_LastFlange;
}

std::unique_ptr<const RuntimeModel> build(CalibratedModel file, uint64_t model_id,
                                          const std::string& source) {
  auto model = std::make_unique<RuntimeModel>();
  const int n = file.chain_Tracker.dof();
  if (n < 1) throw InputError("the model's chain has no joints", source);
  if (file.nominal_Base.dof() != n) {
    throw InputError("the model's nominal chain has " + std::to_string(file.nominal_Base.dof()) +
                         " joints, its calibrated chain " + std::to_string(n),
                     source);
  }
  const int frames = static_cast<int>(file.chain_Tracker.frames().size());
  // Compliance acts on the measured wrench's torques (a sensor frame) or on the arm's own weight.
  bool self_weight = false;
  for (const Mechanism& m : file.mechanisms) self_weight = self_weight || m.kind == MechanismKind::kSelfWeight;
  if (file.compliance_rad_per_nm.size() > 0 && !self_weight &&
      (file.sensor_frame < 0 || file.sensor_frame >= frames)) {
    throw InputError("the model has joint compliance but its sensor frame " +
                         std::to_string(file.sensor_frame) + " is not one of its " +
                         std::to_string(frames) +
                         " attached frames, and no self_weight loads the joints",
                     source);
  }
  if (file.compliance_rad_per_nm.size() != 0 && file.compliance_rad_per_nm.size() != n) {
    throw InputError("the model has " + std::to_string(file.compliance_rad_per_nm.size()) +
                         " joint compliances for " + std::to_string(n) + " joints",
                     source);
  }
  if (file.sensor_frame >= frames) {
    throw InputError("the model's sensor frame " + std::to_string(file.sensor_frame) +
                         " is not one of its " + std::to_string(frames) + " attached frames",
                     source);
  }
  for (size_t i = 0; i < file.mechanisms.size(); ++i) {
    const std::string problem = mechanismInModelProblem(file, i);
    if (!problem.empty()) {
      throw InputError("mechanisms[" + std::to_string(i) + "]: " + problem, source);
    }
  }
  model->physical = physicalModelOf(file);
  model->physical_constants = physicalConstants(model->physical);
  if (file.gpr) {
    model->gpr = GprPredictor::fromParameters(*file.gpr);
    if (model->gpr.inputDim() != n + 6 || model->gpr.outputDim() != 6) {
      throw InputError("the model's GPR maps " + std::to_string(model->gpr.inputDim()) +
                           " inputs to " + std::to_string(model->gpr.outputDim()) +
                           " outputs; the runtime needs (q, wrench) = " + std::to_string(n + 6) +
                           " inputs and a 6-D twist",
                       source);
    }
    model->out_of_domain_relative_std = outOfDomainThreshold(model->gpr);
  }
  std::tie(model->p_ReachCentreInTracker_m, model->reach_radius_m) =
      reachSphere(file.chain_Tracker);
  model->needs_wrench = physicalNeedsWrench(file);
  model->tilts_frames = model->physical.has(MechanismKind::kOffAxisCompliance);
  if (file.gpr && gprNeedsWrench(*file.gpr, n, model->unloaded_wrench_Sensor)) {
    model->needs_wrench = true;
  }
  if (model->needs_wrench) model->unloaded_wrench_Sensor.setZero();
  model->X_LastTip = file.chain_Tracker.initialPose(n);
  model->nominal_inverse = ClosedFormInverse::recognise(file.nominal_Base);
  const int flange = file.nominal_Base.findFrame(kFlangeFrame);
  if (flange >= 0) {
    const AttachedFrame& frame = file.nominal_Base.frames()[static_cast<size_t>(flange)];
    model->X_TipFlange = calibratedTipFlange(file, frame, source);
    model->X_LastFlange_nominal = frame.X_ParentFrame;
    model->has_flange = true;
  }
  model->file = std::move(file);
  model->model_id = model_id;
  if (model->file.gpr && model->file.accuracy) model->gpr_noise = gprWhiteNoise(*model);
  return model;
}

}  // namespace

const char* toString(Status status) noexcept {
  switch (status) {
    case Status::kOk: return "OK";
    case Status::kNotConverged: return "NOT_CONVERGED";
    case Status::kStaleWrench: return "STALE_WRENCH";
    case Status::kOutOfDomain: return "OUT_OF_DOMAIN";
    case Status::kUnreachable: return "UNREACHABLE";
    case Status::kNearSingular: return "NEAR_SINGULAR";
    case Status::kBadRequest: return "BAD_REQUEST";
  }
  return "UNKNOWN";
}

std::unique_ptr<const RuntimeModel> RuntimeModel::load(const std::string& path) {
  CalibratedModel file = readModelFile(path);
  // Round trips are bit-exact, so these are the file's bytes.
  const uint64_t model_id = fnv1a64(serializeModel(file));
  return build(std::move(file), model_id, path);
}

std::unique_ptr<const RuntimeModel> RuntimeModel::fromModel(CalibratedModel model,
                                                            uint64_t model_id) {
  return build(std::move(model), model_id, "in-memory model");
}

Workspace makeWorkspace(const RuntimeModel& model) {
  Workspace ws;
  const int n = model.file.chain_Tracker.dof();
  ws.link_rad.setZero(n);
  ws.torque_nm.setZero(n);
  ws.profile_slope.setZero(n);
  ws.deflection_rad.setZero(n);
  ws.J.setZero(6, n);
  if (model.file.gpr) {
    ws.gpr = model.gpr.makeWorkspace();
    ws.gpr_input.setZero(n + 6);
  }
  if (statesMechanismAccuracy(model)) {
    ws.mechanism_accuracy = makeMechanismAccuracyWorkspace(model.physical);
    ws.mechanism_accuracy_for = &model.physical;
  }
  return ws;
}

bool workspaceFits(const RuntimeModel& model, const Workspace& ws) noexcept {
  if (!model.file.gpr) return true;
  return ws.gpr_input.size() == model.gpr.inputDim() &&
         ws.gpr.normalised_input.size() == model.gpr.inputDim() &&
         ws.gpr.varying_input.size() == model.gpr.varyingInputs() &&
         ws.gpr.kernel_column.size() == model.gpr.trainingSize() &&
         ws.gpr.subset_column.size() == model.gpr.boundSubsetSize();
}

Pose trackerFromFrame(const RuntimeModel& model, PoseFrame frame, const Pose& X_BaseUser) noexcept {
  switch (frame) {
    case PoseFrame::kTracker: return Pose::Identity();
    case PoseFrame::kBase: return model.file.X_TrackerBase;
    case PoseFrame::kUser: return Pose(model.file.X_TrackerBase * X_BaseUser);
  }
  return Pose::Identity();
}

bool withinDomain(const RuntimeModel& model, const Vec6& gpr_std) noexcept {
  return !outOfDomain(model, gpr_std);
}

Pose nominalTcp(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                const CallTerms& terms) noexcept {
  Prepared call;
  if (q_rad.size() != model.file.nominal_Base.dof() || !q_rad.allFinite() ||
      prepare(model, terms, call) != Status::kOk) {
    return Pose::Identity();
  }
  forwardKinematics(model.file.nominal_Base, q_rad, ws.chain);
  const Pose X_BaseRef =
      call.from_flange ? Pose(ws.chain.X_RootFrame[static_cast<size_t>(q_rad.size())] *
                              model.X_LastFlange_nominal)
                       : tipPose(ws.chain);
  return call.X_TrackerFrame.inverse() * model.file.X_TrackerBase * X_BaseRef *
         call.X_NominalRefTcp;
}

namespace {

/// correctForward with the terms resolved.
ForwardResult forwardWith(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                          const Prepared& call, const Vec6& wrench_Sensor, double temp_c) noexcept {
  ForwardResult result;
  if (q_rad.size() != model.file.chain_Tracker.dof() || !q_rad.allFinite() ||
      !wrench_Sensor.allFinite() || !validTemperature(temp_c) || !workspaceFits(model, ws)) {
    return result;
  }
  result.X_TrackerTip =
      correctedTip(model, ws, q_rad, call, wrench_Sensor, temp_c, &result.wrench_Sensor);
  result.X_FrameTcp = result.X_TrackerTip;
  if (!call.at_target) result.X_FrameTcp = result.X_FrameTcp * call.X_TipTcp;
  if (!call.in_tracker) result.X_FrameTcp = call.X_TrackerFrame.inverse() * result.X_FrameTcp;
  if (model.file.gpr) result.gpr_std = ws.gpr_std;
  result.accuracy =
      answerAccuracy(model, ws, q_rad, call, wrench_Sensor, temp_c, result.X_TrackerTip.linear());
  result.status = outOfDomain(model, result.gpr_std) ? Status::kOutOfDomain : Status::kOk;
  result.uncovered_joints = jointsOutsideCoverage(model.physical, q_rad);
  return result;
}

/// solveInverse's iteration: the request it solves and the state carried from one step to the
/// next. Damped Newton steps from the seed, one chord step after the first, the GPR's twist
/// frozen between its evaluations; each step is a member, inverseWith's loop runs them in order.
/// Allocation-free: every vector has a fixed capacity (JointVector, Vec6) or is the workspace's.
struct InverseIteration {
  // The request, checked by inverseWith.
  const RuntimeModel& model;
  const KinematicChain& chain;
  Workspace& ws;
  const Prepared& call;
  const Vec6& wrench_Sensor;
  const double temp_c;
  const InverseOptions& options;
  /// Residuals, tolerances and the Jacobian are the TCP's, in the tracker frame.
  const Pose X_TrackerTcp_desired;

  // The iterate, and the best one so far.
  JointVector q_rad;
  JointVector q_best_rad;
  double best_cost = std::numeric_limits<double>::infinity();
  int iterations = 0;            ///< steps taken (Newton steps and the chord)
  bool converged = false;        ///< the full model at q_best_rad is within the tolerances
  bool held_at_limit = false;    ///< the last step was clamped into the joint limits
  /// The iterate's physical tip, as evaluateIterate last left it.
  Pose X_TrackerTip_physical = Pose::Identity();

  // The GPR's residual twist varies slowly with q: the Newton steps hold it frozen where it was
  // last evaluated (after the first step, again when the iterate has moved farther than
  // kFrozenTwistDistance_rad), and evaluate it with its std bound where the frozen model has
  // converged. There the full model decides: converged, or the steps go on with that twist. Two
  // GPR evaluations per call instead of one per step.
  Vec6 xi_frozen = Vec6::Zero();
  Pose exp_frozen_tcp;                        ///< exp(ξ̂) of xi_frozen, then the tool
  bool have_twist = false;
  JointVector q_twist_rad;                    ///< where xi_frozen was evaluated
  Pose X_TrackerTip_last = Pose::Identity();  ///< the full model's at q_best_rad when converged
  Vec6 reading_last = Vec6::Zero();           ///< the wrench used there

  // The iterates are evaluated with the physical model's one-pass approximation (physicalTip),
  // started from the deflection of the iterate before (the seed's from θ₀); where that is within
  // the tolerances, or after a short step, with the full model, which alone decides convergence.
  bool full_model_next = false;
  // After the long first step from the seed, one chord step: the seed's Jacobian and factor
  // again, at an iterate evaluated with the seed's deflection held. The first step leaves
  // ~1e-3 of the seed's error (its quadratic term); the chord cuts that by the Jacobian's change
  // over the step (~2°: a few %) for the price of a forward evaluation, so the next Newton step,
  // with the full model, lands within the tolerance where it would otherwise need two.
  bool chord_next = false;
  bool last_step_chord = false;
  detail::StepFactor factor;
  JointVector dq_rad;
  double sigma_min_last_step = 0.0;  ///< σ_min of the last step's Jacobian (dampedStep)

  InverseIteration(const RuntimeModel& the_model, Workspace& the_ws, const Prepared& the_call,
                   const Vec6& the_wrench_Sensor, double the_temp_c,
                   const InverseOptions& the_options, const Pose& X_FrameTcp_desired,
                   const JointVector& q_seed_rad) noexcept
      : model(the_model),
        chain(the_model.file.chain_Tracker),
        ws(the_ws),
        call(the_call),
        wrench_Sensor(the_wrench_Sensor),
        temp_c(the_temp_c),
        options(the_options),
        X_TrackerTcp_desired(the_call.in_tracker
                                 ? X_FrameTcp_desired
                                 : Pose(the_call.X_TrackerFrame * X_FrameTcp_desired)),
        q_rad(seedInLimits(the_model.file.chain_Tracker, q_seed_rad)),
        q_best_rad(q_rad),
        exp_frozen_tcp(the_call.X_TipTcp),
        q_twist_rad(q_rad) {
    ws.deflection_rad.setZero(chain.dof());
  }

  /// The seed clamped into the joint limits. The iterates are copy-constructed from it
  /// (cheaper than assigned on the hot path).
  static JointVector seedInLimits(const KinematicChain& chain,
                                  const JointVector& q_seed_rad) noexcept {
    JointVector q_rad = q_seed_rad;
    clampToLimits(chain, q_rad);
    return q_rad;
  }

  /// The desired tip farther from the reach sphere's centre than its radius: no step is taken.
  bool beyondReach() const noexcept {
    const Vec3 p_TipDesired = call.at_target
                                  ? X_TrackerTcp_desired.translation()
                                  : (X_TrackerTcp_desired * call.X_TipTcp.inverse()).translation();
    return (p_TipDesired - model.p_ReachCentreInTracker_m).norm() > model.reach_radius_m;
  }

  bool within(const Vec6& e) const noexcept {
    return e.head<3>().norm() <= options.position_tolerance_m &&
           e.tail<3>().norm() <= options.orientation_tolerance_rad;
  }

  /// The residual of the physical tip with the frozen twist.
  Vec6 frozenResidual() const noexcept {
    return poseResidual(X_TrackerTcp_desired, Pose(X_TrackerTip_physical * exp_frozen_tcp));
  }

  /// Step "evaluate": the iterate's physical tip (the seed's deflection held for a chord step,
  /// the full model after a short step, else its one-pass approximation, then the full model
  /// where that is within the tolerances) and its residual with the frozen twist.
  Vec6 evaluateIterate(bool chord) noexcept {
    const bool full_model = full_model_next;
    X_TrackerTip_physical = physicalTip(model, ws, q_rad, call, wrench_Sensor, temp_c, !chord,
                                        chord        ? Deflection::kHeld
                                        : full_model ? Deflection::kModel
                                                     : Deflection::kOnePass);
    refreezeTwist();
    Vec6 e = frozenResidual();
    if (!full_model && within(e)) {
      X_TrackerTip_physical = physicalTip(model, ws, q_rad, call, wrench_Sensor, temp_c, true);
      e = frozenResidual();
    }
    return e;
  }

  /// The frozen twist evaluated again (without its std) after the first step and after long
  /// moves. The seed's own twist would serve one step only (the first step is the long one): the
  /// first step goes without, unless options.twist_at_seed (a seed close to the answer).
  void refreezeTwist() noexcept {
    if ((!have_twist && (iterations > 0 || options.twist_at_seed)) ||
        (have_twist && (q_rad - q_twist_rad).cwiseAbs().maxCoeff() > kFrozenTwistDistance_rad)) {
      xi_frozen = residualTwist(model, ws, q_rad, loadReading(model, ws, call, wrench_Sensor),
                                X_TrackerTip_physical.linear(), false);
      exp_frozen_tcp = lie::expSE3(xi_frozen);
      if (!call.at_target) exp_frozen_tcp = exp_frozen_tcp * call.X_TipTcp;
      q_twist_rad = q_rad;
      have_twist = true;
    }
  }

  /// Step "check convergence", where the full model's physical tip is within the tolerances
  /// with the frozen twist: the twist at q_rad with its std (kept in ws.gpr_std), frozen from
  /// here on. Returns the full model's residual; within the tolerances, the iterate is the answer.
  Vec6 fullModelResidual() noexcept {
    reading_last = loadReading(model, ws, call, wrench_Sensor);
    xi_frozen =
        residualTwist(model, ws, q_rad, reading_last, X_TrackerTip_physical.linear(), true);
    const Pose exp_twist = lie::expSE3(xi_frozen);
    exp_frozen_tcp = call.at_target ? exp_twist : Pose(exp_twist * call.X_TipTcp);
    q_twist_rad = q_rad;
    have_twist = true;
    X_TrackerTip_last = Pose(X_TrackerTip_physical * exp_twist);
    return poseResidual(X_TrackerTcp_desired, call.at_target
                                                  ? X_TrackerTip_last
                                                  : Pose(X_TrackerTip_last * call.X_TipTcp));
  }

  void acceptAsConverged() noexcept {
    converged = true;
    q_best_rad = q_rad;
  }

  void keepIfBest(const Vec6& e) noexcept {
    const double cost = e.squaredNorm();
    if (cost < best_cost) {
      best_cost = cost;
      q_best_rad = q_rad;
    }
  }

  /// Step "take the step": the chord step with the last factor, or a damped step on the
  /// corrected Jacobian here; shortened to max_step_rad, clamped into the limits. Decides how
  /// the next iterate is evaluated.
  void takeStep(bool chord, const Vec6& e) noexcept {
    if (chord) {
      detail::stepFromFactor(ws.J, factor.cholesky, e, dq_rad);
    } else {
      correctedJacobian(model, ws, call, wrench_Sensor);
      sigma_min_last_step = detail::dampedStep(ws.J, e, options, dq_rad, factor);
    }
    last_step_chord = chord;
    const double largest_rad = dq_rad.cwiseAbs().maxCoeff();
    const bool shortened = largest_rad > options.max_step_rad;
    if (shortened) dq_rad *= options.max_step_rad / largest_rad;
    q_rad += dq_rad;
    held_at_limit = clampToLimits(chain, q_rad);
    full_model_next = largest_rad <= kFullModelStep_rad;
    // A shortened or clamped first step is not the Newton step the chord refines.
    chord_next =
        iterations == 0 && !full_model_next && !shortened && !held_at_limit && factor.valid;
    ++iterations;
  }

  /// The answer q_best_rad and the full model's prediction there (kept from the convergence
  /// check, else evaluated now), in the tracker and the call's frame, and its residual.
  void predictAnswer(InverseResult& result) noexcept {
    result.q_target_rad = q_best_rad;
    if (converged) {
      result.X_TrackerTip_predicted = X_TrackerTip_last;
      result.wrench_Sensor = reading_last;
    } else {
      result.X_TrackerTip_predicted =
          correctedTip(model, ws, q_best_rad, call, wrench_Sensor, temp_c, &result.wrench_Sensor);
    }
    if (model.file.gpr) result.gpr_std = ws.gpr_std;
    result.accuracy = answerAccuracy(model, ws, q_best_rad, call, wrench_Sensor, temp_c,
                                     result.X_TrackerTip_predicted.linear());
    result.uncovered_joints = jointsOutsideCoverage(model.physical, q_best_rad);
    const Pose X_TrackerTcp_predicted = call.at_target
                                            ? result.X_TrackerTip_predicted
                                            : Pose(result.X_TrackerTip_predicted * call.X_TipTcp);
    result.X_FrameTcp_predicted =
        call.in_tracker ? X_TrackerTcp_predicted
                        : Pose(call.X_TrackerFrame.inverse() * X_TrackerTcp_predicted);
    const Vec6 e = poseResidual(X_TrackerTcp_desired, X_TrackerTcp_predicted);
    result.residual_position_m = e.head<3>().norm();
    result.residual_orientation_rad = e.tail<3>().norm();
  }

  /// The answer's status, after predictAnswer (its gpr_std).
  Status answerStatus(const InverseResult& result, bool beyond_reach) noexcept {
    if (!converged) {
      return beyond_reach || held_at_limit ? Status::kUnreachable : Status::kNotConverged;
    }
    // On the last step's Jacobian, taken within the tolerance of the answer (a fresh one when
    // the seed itself was the answer, or the last step a chord with the seed's Jacobian).
    if (iterations == 0 || last_step_chord) {
      correctedJacobian(model, ws, call, wrench_Sensor);
      sigma_min_last_step =
          detail::smallestSingularValueOfJacobianOrFloor(ws.J, options.singular_value_threshold);
    }
    if (sigma_min_last_step < options.singular_value_threshold) return Status::kNearSingular;
    return outOfDomain(model, result.gpr_std) ? Status::kOutOfDomain : Status::kOk;
  }

  /// What the controller is to be commanded for the answer: the nominal chain's tip at
  /// q_best_rad, and its TCP (the tool as given, in the call's frame).
  void commandAnswer(InverseResult& result) noexcept {
    forwardKinematics(model.file.nominal_Base, q_best_rad, ws.chain);
    result.X_BaseTip_commanded = tipPose(ws.chain);
    const Pose X_BaseRef =
        call.from_flange ? Pose(ws.chain.X_RootFrame[static_cast<size_t>(chain.dof())] *
                                model.X_LastFlange_nominal)
                         : result.X_BaseTip_commanded;
    result.X_ControllerTcp_commanded = X_BaseRef;
    if (call.X_NominalRefTcp.matrix() != Eigen::Matrix4d::Identity()) {
      result.X_ControllerTcp_commanded = result.X_ControllerTcp_commanded * call.X_NominalRefTcp;
    }
    if (!call.in_tracker) {
      result.X_ControllerTcp_commanded =
          call.X_ControllerFrameBase * result.X_ControllerTcp_commanded;
    }
  }
};

/// solveInverse with the terms resolved.
InverseResult inverseWith(const RuntimeModel& model, Workspace& ws, const Pose& X_FrameTcp_desired,
                          const Prepared& call, const Vec6& wrench_Sensor, double temp_c,
                          const JointVector& q_seed_rad, Clock::time_point deadline,
                          const InverseOptions& options) noexcept {
  InverseResult result;
  const KinematicChain& chain = model.file.chain_Tracker;
  if (q_seed_rad.size() != chain.dof() || !q_seed_rad.allFinite() ||
      !wrench_Sensor.allFinite() || !validTemperature(temp_c) ||
      !X_FrameTcp_desired.translation().allFinite() || !isRotation(X_FrameTcp_desired.linear()) ||
      !validOptions(options) || !workspaceFits(model, ws)) {
    return result;
  }
  InverseIteration it(model, ws, call, wrench_Sensor, temp_c, options, X_FrameTcp_desired,
                      q_seed_rad);
  const bool beyond_reach = it.beyondReach();
  while (!beyond_reach) {
    const bool chord = it.chord_next;
    Vec6 e = it.evaluateIterate(chord);
    if (it.within(e)) {
      e = it.fullModelResidual();
      if (it.within(e)) {
        it.acceptAsConverged();
        break;
      }
    }
    it.keepIfBest(e);
    if (it.iterations >= options.max_iterations || Clock::now() >= deadline) break;
    it.takeStep(chord, e);
  }
  result.iterations = it.iterations;
  it.predictAnswer(result);
  result.status = it.answerStatus(result, beyond_reach);
  it.commandAnswer(result);
  return result;
}

}  // namespace

ForwardResult correctForward(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                             const Vec6& wrench_Sensor, double temp_c) noexcept {
  return forwardWith(model, ws, q_rad, kOwnTerms, wrench_Sensor, temp_c);
}

ForwardResult correctForward(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                             const CallTerms& terms, double temp_c) noexcept {
  Prepared call;
  if (prepare(model, terms, call) != Status::kOk) return ForwardResult{};
  return forwardWith(model, ws, q_rad, call, terms.wrench_Sensor, temp_c);
}

InverseResult solveInverse(const RuntimeModel& model, Workspace& ws,
                           const Pose& X_TrackerTip_desired, const Vec6& wrench_Sensor,
                           double temp_c, const JointVector& q_seed_rad,
                           Clock::time_point deadline, const InverseOptions& options) noexcept {
  return inverseWith(model, ws, X_TrackerTip_desired, kOwnTerms, wrench_Sensor, temp_c, q_seed_rad,
                     deadline, options);
}

InverseResult solveInverse(const RuntimeModel& model, Workspace& ws,
                           const Pose& X_FrameTcp_desired, const CallTerms& terms, double temp_c,
                           const JointVector& q_seed_rad, Clock::time_point deadline,
                           const InverseOptions& options) noexcept {
  Prepared call;
  if (prepare(model, terms, call) != Status::kOk) return InverseResult{};
  return inverseWith(model, ws, X_FrameTcp_desired, call, terms.wrench_Sensor, temp_c, q_seed_rad,
                     deadline, options);
}

}  // namespace stepcal::runtime
