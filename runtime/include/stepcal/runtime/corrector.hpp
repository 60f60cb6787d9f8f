// Real-time pose correction with a calibrated model: forward (what pose will the robot really
// reach) and inverse (which joint targets make the real robot reach a desired pose).
//
// The model applied is the file's physical model (mechanisms.hpp: geometry, joint compliance and
// every identified mechanism, at the measured wrench and temperature) followed by the GPR's
// residual twist (docs/method.md eq. 32), whose input stays (q, measured wrench) as in training.
//
// RuntimeModel is immutable after load; Workspace holds every buffer, sized once. The two
// calls allocate nothing, lock nothing, throw nothing and return a status.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/closed_form_ik.hpp"
#include "stepcal/common/gpr_predictor.hpp"
#include "stepcal/common/mechanism_accuracy.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/pose_accuracy.hpp"

namespace stepcal::runtime {

/// Outcome of a real-time call. Values are stable: they travel over LCM.
enum class Status : int8_t {
  kOk = 0,
  kNotConverged = 1,  ///< time or iteration budget ran out; the best answer so far is returned
  kStaleWrench = 2,   ///< the live wrench is older than allowed (set by the caller/daemon)
  kOutOfDomain = 3,   ///< the GPR is extrapolating: predictive std above the model's threshold
  kUnreachable = 4,   ///< the desired pose is outside the workspace or joint limits
  kNearSingular = 5,  ///< the Jacobian is (nearly) singular at the answer
  kBadRequest = 6,    ///< NaN/inf, wrong sizes, a non-rotation, an unknown mode
};
/// Upper-case name of a status ("OK", "NOT_CONVERGED", …); "UNKNOWN" for other values.
const char* toString(Status status) noexcept;

using Clock = std::chrono::steady_clock;

/// Lowest and highest structure temperature the real-time calls accept, °C.
inline constexpr double kMinTemperature_c = -50.0;
inline constexpr double kMaxTemperature_c = 150.0;
/// The temperature of a caller without a thermometer: NaN, no thermal correction.
inline constexpr double kUnknownTemperature_c = std::numeric_limits<double>::quiet_NaN();
/// Whether temp_c [°C] is NaN (not measured: no thermal correction) or within
/// kMinTemperature_c … kMaxTemperature_c; ±inf and values outside are not.
inline bool validTemperature(double temp_c) noexcept {
  return std::isnan(temp_c) || (temp_c >= kMinTemperature_c && temp_c <= kMaxTemperature_c);
}

/// The frame in which a call's poses are given and answered (docs/runtime.md, "Integration").
enum class PoseFrame : int8_t {
  kTracker = 0,  ///< the tracker (work) frame of the calibration campaign
  kBase = 1,     ///< the robot's base frame: the nominal robot where the model registered it
                 ///< (CalibratedModel::X_TrackerBase), the frame of the controller's kinematics
  kUser = 2,     ///< a user frame given in the base frame (CallTerms::X_BaseUser), as a
                 ///< controller's work object (ABB wobjdata, KUKA BASE_DATA)
};
/// What a call's tool transform is given from.
enum class ToolFrom : int8_t {
  kTarget = 0,  ///< from the measured target (the calibrated chain's tip)
  kFlange = 1,  ///< from the robot's flange: the controller's tool data (needs a model whose
                ///< campaign named its flange_link, RuntimeModel::has_flange)
};
/// The frame in which a payload's centre of gravity is given.
enum class CogFrame : int8_t { kFlange = 0, kTool = 1 };
/// Where a call's wrench comes from.
enum class LoadFrom : int8_t {
  kWrench = 0,   ///< a wrench on the F/T sensor, sensor axes (measured or given)
  kPayload = 1,  ///< a payload's mass and centre of gravity (the controller's load data)
};

/// A payload as the controller's load data gives it.
struct Payload {
  double mass_kg = 0.0;            ///< ≥ 0, kg
  Vec3 p_CoG_m = Vec3::Zero();     ///< centre of gravity in `frame`, m
  CogFrame frame = CogFrame::kFlange;
};

/// A call in the controller's terms: the frame of its poses, its tool, its load. The default is
/// the calibration's own terms: tracker frame, the measured target, a wrench on the sensor.
struct CallTerms {
  PoseFrame frame = PoseFrame::kTracker;
  Pose X_BaseUser = Pose::Identity();  ///< kUser: the user frame in the base frame, m
  ToolFrom tool_from = ToolFrom::kTarget;
  /// The tool centre point (TCP) in the frame it is given from: X_TargetTcp or X_FlangeTcp, m.
  /// Identity with kTarget: the measured target itself.
  Pose X_Tool = Pose::Identity();
  LoadFrom load_from = LoadFrom::kWrench;
  Vec6 wrench_Sensor = Vec6::Zero();  ///< kWrench: (f [N], m [N·m]), sensor axes
  Payload payload;                    ///< kPayload
};

/// Everything the runtime needs, built once from a model file (off the real-time path).
struct RuntimeModel {
  CalibratedModel file;         ///< as loaded
  PhysicalModel physical;       ///< physicalModelOf(file), built once at load
  PhysicalConstants physical_constants;  ///< physicalConstants(physical), built once at load
  GprPredictor gpr;             ///< valid when file.gpr is present
  uint64_t model_id = 0;        ///< FNV-1a 64 of the file's bytes: tells answers of two models apart
  /// GPR relative predictive std (σ/σ_f) above which a request is OUT_OF_DOMAIN. Set at load
  /// from the training inputs: √(1 − ¼ (1 − s²)), s the largest relative std at a training
  /// input, i.e. out of domain where the data explain less than a quarter of the prior variance
  /// they explain at the least-covered training input. (A fixed value fails: with a residual at
  /// the noise level, σ/σ_f stays near 1 even at the training inputs.)
  /// σ here and in every status is the conservative std bound of the real-time calls
  /// (GprPredictor::relativeStdBound: the GP on a subset of ≤ 48 training points), never below
  /// the exact predictive std.
  double out_of_domain_relative_std = 1.0;
  /// The GPR's white noise 1-σ per output at unit output gain, raw units (v m, ω rad), set at
  /// load: what its training points, each left out, show beyond its latent variance
  /// (GprPredictor::heldOutNoise), less the mean of the fitted parameters' share of the
  /// covariance at those points, which the bound states on its own (docs/method.md, "The
  /// accuracy bound"). Zero without a GPR or accuracy factors.
  Vec6 gpr_noise = Vec6::Zero();
  /// Centre of a sphere holding every tip position the arm can reach: origin of T_{0,1}(0),
  /// tracker frame, m.
  Vec3 p_ReachCentreInTracker_m = Vec3::Zero();
  /// Its radius, m: Σ_k (‖p of T_{k,k+1}(0)‖ + 2 · axis offset of joint k) over joints 1..n,
  /// plus 5 % for the deflection and the residual twist. A desired tip beyond it is UNREACHABLE.
  double reach_radius_m = 0.0;
  /// Whether a call's answer depends on the wrench: the physical model turns the sensor's wrench
  /// into deflection (a sensor frame with compliance, backlash or nonlinear stiffness), or the
  /// GPR's training wrenches vary. When not, a call asking for the live sensor is answered with
  /// unloaded_wrench_Sensor and never STALE_WRENCH.
  bool needs_wrench = true;
  /// Whether the physical model tilts joint frames (off_axis_compliance): its inverse then
  /// evaluates every iterate with the model's fixed point (a tilt is not held between them).
  bool tilts_frames = false;
  /// The wrench of a model that needs none: the GPR's training wrench (constant), else zero.
  Vec6 unloaded_wrench_Sensor = Vec6::Zero();
  /// Whether the model knows the robot's flange (an attached frame named kFlangeFrame).
  bool has_flange = false;
  /// The flange in the calibrated target's frame (has_flange), m. The calibration identifies the
  /// target, not the flange: the flange is placed on the calibrated joint-n frame by the nominal
  /// chain's X_nFlange, with the joint-n frame's unidentifiable part (a rotation about and a
  /// translation along joint n's axis, traded between T_{n−1,n} and T_{n,tip}) taken as
  /// nominal: that part of the calibration's correction belongs to the target's mounting.
  Pose X_TipFlange = Pose::Identity();
  /// The flange in the nominal chain's frame n, m (the controller's view, for the pre-distorted
  /// pose).
  Pose X_LastFlange_nominal = Pose::Identity();
  /// The calibrated T_{n,tip}(0): the target in the calibrated joint-n frame, m.
  Pose X_LastTip = Pose::Identity();
  /// The closed-form inverse of the nominal chain (file.nominal_Base), recognised at load: the
  /// seeds of closed_form_seed.hpp; ArmLayout::kOther for an arm it does not solve.
  ClosedFormInverse nominal_inverse;

  /// Loads and validates a model file. Throws InputError.
  static std::unique_ptr<const RuntimeModel> load(const std::string& path);
  /// Builds from an in-memory model (tests). Throws InputError when the model lacks what the
  /// real-time calls rely on: a nominal chain of the calibrated chain's size, a valid sensor
  /// frame when it has compliance, mechanisms that pass mechanismInModelProblem, a GPR with
  /// n + 6 inputs and 6 outputs.
  static std::unique_ptr<const RuntimeModel> fromModel(CalibratedModel model, uint64_t model_id);
};

/// All scratch space of the real-time calls; sized for one model by makeWorkspace.
struct Workspace {
  ChainWorkspace chain;
  JointVector link_rad;   ///< link angles θ of the last evaluation, rad
  JointVector torque_nm;  ///< joint torques τ of its last fixed-point pass, N·m
  JointVector profile_slope;  ///< d(profile offset)/dq per joint at its commanded angles
  JointVector deflection_rad;  ///< θ − θ₀ of the last evaluation: where solveInverse's next starts
  Jacobian J;
  GprPredictor::Workspace gpr;
  Eigen::VectorXd gpr_input;  ///< n + 6
  Vec6 gpr_mean = Vec6::Zero(), gpr_std = Vec6::Zero();
  /// Whether the calls state their answer's accuracy (PoseAccuracy; a model without
  /// AccuracyFactors states none either way). Off only to time the calls without it.
  bool with_accuracy = true;
  /// The mechanisms' share of the accuracy (mechanism_accuracy.hpp): a copy of the physical
  /// model it was made for (mechanism_accuracy_for), only when its model has the calibration's
  /// factors and a mechanism with a σ > 0; else empty and null. Used with another model whose
  /// mechanisms have σ > 0, the calls state no accuracy (NaN): make a workspace for each model.
  MechanismAccuracyWorkspace mechanism_accuracy;
  const PhysicalModel* mechanism_accuracy_for = nullptr;
};
/// A workspace sized for the model (allocates; call off the real-time path).
Workspace makeWorkspace(const RuntimeModel& model);
/// Whether ws was sized for a model of this shape (joints, GPR inputs and training size). The
/// real-time calls answer BAD_REQUEST rather than resize a workspace that does not fit, so a
/// caller that swaps models must make a new workspace when this turns false.
bool workspaceFits(const RuntimeModel& model, const Workspace& ws) noexcept;

/// Name of the attached frame of a model's chains that is the robot's flange: the frame of the
/// controller's tool data (campaign.yaml flange_link).
inline constexpr const char* kFlangeFrame = kFlangeFrameName;

struct ForwardResult {
  Status status = Status::kBadRequest;
  Pose X_TrackerTip = Pose::Identity();  ///< corrected pose, T_C2 (docs/method.md eq. 32), m
  /// The TCP (the target with CallTerms' defaults) in the call's frame, m.
  Pose X_FrameTcp = Pose::Identity();
  /// The wrench the answer used, as a sensor tared unloaded reads it (sensor axes, N and N·m):
  /// the given or live one, or a payload's weight at the deflected pose plus the sensor bias.
  Vec6 wrench_Sensor = Vec6::Zero();
  Vec6 gpr_std = Vec6::Zero();           ///< predictive 1-σ of the residual twist (v [m], ω [rad]; of a GPR per payload force in the tracker's axes)
  ///< (gpr_std is an upper bound on the exact predictive std: GprPredictor::predictMeanAndBoundInto)
  /// Bit j: joint j's angle lies outside the angles its transmission profile was fitted on, so
  /// the profile is faded out there (jointsOutsideCoverage); the status is unaffected.
  uint32_t uncovered_joints = 0;
  /// How far a measurement of the corrected target will be from X_TrackerTip: the parameters'
  /// covariance, the GPR's variance and the measurement's noise (pose_accuracy.hpp; the
  /// target's, not a tool's offset from it). NaN for a model without AccuracyFactors.
  PoseAccuracy accuracy;
};

/// Pose the robot reaches at commanded joints q [rad] under the measured wrench_Sensor [N, N·m]
/// at structure temperature temp_c [°C; NaN: not measured, the model's reference temperature]:
/// T_C2 = FK_T(θ) · exp(ξ̂_GPR(q, F)), θ the link angles of the physical model with every
/// mechanism (physicalLinkAngles; with compliance alone θ = q + C τ(θ), docs/method.md eq. 24, 32).
/// Status OK, OUT_OF_DOMAIN (pose still returned) or BAD_REQUEST (wrong size, NaN/inf, a
/// temperature validTemperature refuses, workspace of another shape). Allocation-free; never
/// throws.
ForwardResult correctForward(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                             const Vec6& wrench_Sensor, double temp_c) noexcept;
/// The same in the controller's terms: the TCP's pose X_FrameTcp in terms.frame, with the tool
/// hung rigidly from the corrected target (T_C2 · X_TipTcp); with a payload its weight deflects
/// the joints at the deflected pose (physicalLinkAngles' fixed point), and the GPR gets the
/// wrench a sensor would read there. BAD_REQUEST also for terms that do not hold (non-finite,
/// not a rotation, a negative mass, a flange the model lacks, a payload without gravity).
ForwardResult correctForward(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                             const CallTerms& terms, double temp_c) noexcept;

struct InverseOptions {
  int max_iterations = 8;
  double position_tolerance_m = 1e-6;
  double orientation_tolerance_rad = 1e-6;
  /// Levenberg–Marquardt λ² at an exact singularity; it fades to 0 as σ_min(J) rises to
  /// singular_value_threshold. Units of σ²: m² (position rows) or 1 (rotation rows).
  double damping = 1e-6;
  /// σ_min of the tip point Jacobian below which steps are damped and an answer is NEAR_SINGULAR.
  double singular_value_threshold = 1e-2;
  /// Largest change of any joint in one step, rad (longer steps are scaled down).
  double max_step_rad = 0.2;
  /// Evaluate the GPR's twist at the seed and hold it from the first step on (else the first
  /// step goes without it): for a seed within about a millimetre of the answer, as the nominal
  /// closed form gives (closed_form_seed.hpp), where the seed's twist is the answer's to well
  /// within the tolerance and the first step then aims at the full model.
  bool twist_at_seed = false;
};

struct InverseResult {
  Status status = Status::kBadRequest;
  JointVector q_target_rad;                      ///< joint targets (empty on BAD_REQUEST), rad
  Pose X_BaseTip_commanded = Pose::Identity();   ///< pre-distorted pose: nominal FK at q_target, base frame, m
  Pose X_TrackerTip_predicted = Pose::Identity();  ///< where the real robot ends up (forward model)
  /// The pre-distorted TCP for a controller that takes poses: the nominal chain's target or
  /// flange (as the tool is given) at q_target times the tool, in the controller's frame (the
  /// user frame for kUser, else the base frame), m.
  Pose X_ControllerTcp_commanded = Pose::Identity();
  /// Where the real robot's TCP ends up, in the call's frame, m.
  Pose X_FrameTcp_predicted = Pose::Identity();
  Vec6 wrench_Sensor = Vec6::Zero();             ///< as ForwardResult::wrench_Sensor, at q_target
  Vec6 gpr_std = Vec6::Zero();                   ///< at q_target, as ForwardResult::gpr_std
  int iterations = 0;                            ///< steps taken (Newton steps and the chord)
  double residual_position_m = 0.0;              ///< ‖p_desired − p_predicted‖ at q_target (TCP), m
  double residual_orientation_rad = 0.0;         ///< angle between the two rotations, rad
  uint32_t uncovered_joints = 0;                 ///< at q_target, as ForwardResult::uncovered_joints
  PoseAccuracy accuracy;                         ///< at q_target, as ForwardResult::accuracy
};

/// Joint targets that make the real robot (the full corrected model, as correctForward) reach
/// X_TrackerTip_desired under wrench_Sensor at temp_c [°C; NaN: not measured], by damped Newton
/// steps from q_seed_rad (clamped into the joint limits), staying within the limits. Residual
/// (p_desired − p, log(R_desired Rᵀ)), tracker axes, of the physical model times the GPR's
/// twist held frozen where it was last evaluated (none for the first step; after it, and again
/// after a move of more than 3°). The iterates' physical model is its approximation with one
/// pass of the deflection's fixed point from the iterate before (FixedPointStart; within ~1e-8
/// rad of the model at a 2° step), the model itself where that is within the tolerances or
/// after a step below 0.01 rad; where the model with the frozen twist converges the GPR is
/// evaluated there, and the full model decides: converged, or the steps go on with the new
/// twist. After a long first step (> 0.01 rad, neither shortened nor clamped) one chord step:
/// the first step's Jacobian and factorisation again, at an iterate evaluated with the seed's
/// deflection held (FixedPointStart with no pass): from seeds 2° off it takes the 1.3 mm the
/// first step leaves to 0.05–0.08 mm (median, UR10 and paper models) for a forward evaluation
/// and no Jacobian, so that one Newton step with the full model lands within the default
/// tolerance where two were needed. Jacobian (quasi-Newton): the tip point Jacobian at the
/// link angles θ (thermal length scale and the profiles' geometry included) times
/// dθ/dq ≈ (I + M) dθ₀/dq, the fixed point of physicalLinkAngles linearised to first order with
/// M = diag(∂θ/∂τ) ∂τ_W/∂θ (~1e-3): dθ₀/dq exact (joint_coupling, transmission_error with its
/// gate), ∂θ/∂τ exact per joint (compliance, backlash, nonlinear_stiffness), ∂τ_W/∂θ the measured
/// wrench's (bias removed) torques. Left out: M² and beyond (~1e-6), the self_weight torques'
/// change with the pose (C ∂τ_self/∂θ, ~1e-3: steps converge at that linear rate near the
/// answer), the profiles' geometry's change with the gates, and the GPR's own derivative. Stops
/// at the tolerances (the full model's), the iteration cap or the deadline (checked before
/// every step: never more than one step past it), returning its best answer. NEAR_SINGULAR is
/// judged on the last step's Jacobian. Status: BAD_REQUEST (sizes, NaN/inf, a
/// temperature validTemperature refuses, not a rotation, bad options); UNREACHABLE (tip beyond
/// the reach sphere, or not converged with a joint held at its limit); NOT_CONVERGED; else,
/// converged: NEAR_SINGULAR, OUT_OF_DOMAIN or OK, in that order. Allocation-free; never throws.
InverseResult solveInverse(const RuntimeModel& model, Workspace& ws,
                           const Pose& X_TrackerTip_desired, const Vec6& wrench_Sensor,
                           double temp_c, const JointVector& q_seed_rad,
                           Clock::time_point deadline, const InverseOptions& options = {}) noexcept;
/// The same in the controller's terms: joint targets that bring the real robot's TCP to
/// X_FrameTcp_desired (terms.frame); the residual, the tolerances and the Jacobian are the TCP's.
/// A payload's weight deflects the joints inside the model the steps invert, so the answer is
/// exact for it; its torques' change with the pose is left out of the Jacobian (as the self
/// weight's). BAD_REQUEST also for terms that do not hold (as correctForward).
InverseResult solveInverse(const RuntimeModel& model, Workspace& ws,
                           const Pose& X_FrameTcp_desired, const CallTerms& terms, double temp_c,
                           const JointVector& q_seed_rad, Clock::time_point deadline,
                           const InverseOptions& options = {}) noexcept;

/// The pose of a call's frame in the tracker frame: identity, X_TrackerBase, or X_TrackerBase ·
/// X_BaseUser, m.
Pose trackerFromFrame(const RuntimeModel& model, PoseFrame frame, const Pose& X_BaseUser) noexcept;

/// Where the controller's nominal kinematics put the TCP at joints q [rad], in the call's frame:
/// the nominal chain's target or flange (as terms' tool is given) at q times the tool, placed in
/// the tracker frame by X_TrackerBase for kTracker, m. What an offline program's joint targets
/// mean to reach. Identity for terms or joints that do not hold. Allocation-free.
Pose nominalTcp(const RuntimeModel& model, Workspace& ws, const JointVector& q_rad,
                const CallTerms& terms) noexcept;

/// Whether a GPR std bound (a result's gpr_std) lies within the model's domain: the
/// OUT_OF_DOMAIN test, whatever the call's status. Always true without a GPR.
bool withinDomain(const RuntimeModel& model, const Vec6& gpr_std) noexcept;

}  // namespace stepcal::runtime
