// Hidden physical mechanisms of the twin, each a small stage of the measurement pipeline.
//
// One measurement of the true robot at commanded joint angles q_cmd under a payload, at the true
// temperature T of the row:
//   0. link-length scale s = 1 + α (T − T_ref)                       (thermal_expansion, else 1)
//   1. link angles θ, the fixed point of
//        τ = J_s(θ)ᵀ W_payload(θ) + τ_self(θ)        joint load torques, N·m (self_weight)
//        θ = e_k(q_cmd, τ, … e_1(q_cmd, τ, q_cmd))  the link-angle effects in order
//      with every frame from FK_true(θ; s), the links' translations scaled by s
//   2. tip pose  X_TrackerTip = X_TrackerBase · FK_true(θ; s)
//   3. F/T reading: the payload's wrench at the same θ, plus b_sensor (sensor_bias)
// A joint's zero may drift with T (joint_zero_drift: added to θ after the link-angle effects),
// and the tracker's frame may move while the campaign is measured (registration_drift: step 2
// in the moved frame).
// A mechanism that moves the link side away from the controller's angles is a LinkAngleEffect:
// joint compliance (always, unless switched off) and the hidden mechanisms a campaign may carry
// (backlash, transmission error, nonlinear stiffness, a torsion curve, joint coupling, a
// stiffness that varies with the joint angle), each on given joints with
// given parameters. Three more act on the other stages: SelfWeight (the links' own gravity
// torques join τ, so every effect that uses τ sees them, and unloaded rows deflect too),
// ThermalExpansion (s) and SensorBias (the reading only; the robot's physics is unaffected).
// BearingTilt turns the frames beyond a joint under the moment perpendicular to its axis: it
// joins step 1's fixed point (every frame evaluated with the tilts, the tilts from the wrench
// at those frames). ToolMountCompliance shifts the tool along the sensor's axis under the
// payload's force (after step 1: a shift of micrometres does not change the torques).
// EffectSet holds one twin's mechanisms and builds them from their truth.json objects.
// Joints and links are numbered 1 … n in names, parameters and truth.json.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/types.hpp"

namespace stepcal::twin {

/// A stage that maps the commanded angles and the joint loads to link angles.
class LinkAngleEffect {
 public:
  virtual ~LinkAngleEffect() = default;
  /// Name of the mechanism; the "name" key of its truth.json object.
  virtual std::string name() const = 0;
  /// Updates the link angles theta_rad [rad] in place, given the controller's angles
  /// q_cmd_rad [rad] and the joint load torques tau_nm [N·m].
  virtual void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
                     JointVector& theta_rad) const = 0;
  /// Its true parameters for truth.json: SI, units in the key names, with "name".
  virtual nlohmann::json toJson() const = 0;
};

/// Linear joint compliance (docs/method.md eq. 15): every joint a torsion spring, Δθ = K⁻¹ τ,
/// so a joint deflects in the direction of its load torque.
class JointCompliance final : public LinkAngleEffect {
 public:
  /// stiffness_nm_per_rad: K_θ of each joint, N·m/rad, finite and > 0. Throws InputError.
  explicit JointCompliance(std::vector<double> stiffness_nm_per_rad);

  std::string name() const override { return "joint_compliance"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  nlohmann::json toJson() const override;

  /// K_θ per joint, N·m/rad.
  const std::vector<double>& stiffness() const noexcept { return stiffness_nm_per_rad_; }

 private:
  std::vector<double> stiffness_nm_per_rad_;
};

/// Backlash of joint j: lost motion taken up in the direction of the joint's load torque,
/// Δθ_j = b · tanh(τ_j / τ_s) with τ_s = 1 N·m (a sign function smoothed over ±1 N·m, so the
/// fixed point of the link angles converges where τ_j crosses zero). b rad.
class Backlash final : public LinkAngleEffect {
 public:
  static constexpr double kSmoothingTorque_nm = 1.0;
  /// joint 1 … dof; lost_motion_rad finite, > 0 and < 0.01 rad. Throws InputError.
  Backlash(int joint, double lost_motion_rad, int dof);
  std::string name() const override { return "backlash"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  nlohmann::json toJson() const override;

 private:
  int joint_;
  double lost_motion_rad_;
};

/// Cyclic transmission error of joint j from gear eccentricity, harmonic k of the joint angle:
/// Δθ_j = a sin(k q_j) + b cos(k q_j). a, b rad.
class TransmissionError final : public LinkAngleEffect {
 public:
  /// joint 1 … dof; harmonic 1 … 64; |a|, |b| finite and < 0.01 rad. Throws InputError.
  TransmissionError(int joint, int harmonic, double sin_rad, double cos_rad, int dof);
  std::string name() const override { return "transmission_error"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  nlohmann::json toJson() const override;

 private:
  int joint_, harmonic_;
  double sin_rad_, cos_rad_;
};

/// A joint softer at small torque than at large: on top of the linear compliance,
/// Δθ_j = c τ_j τ_0 / (τ_0 + |τ_j|): slope c at zero torque, levelling off at c τ_0.
/// c rad/(N·m), τ_0 N·m.
class NonlinearStiffness final : public LinkAngleEffect {
 public:
  /// joint 1 … dof; c finite, > 0 and < 1e-3 rad/(N·m); τ_0 finite and > 0. Throws InputError.
  NonlinearStiffness(int joint, double extra_compliance_rad_per_nm, double saturation_torque_nm,
                     int dof);
  std::string name() const override { return "nonlinear_stiffness"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  nlohmann::json toJson() const override;

 private:
  int joint_;
  double extra_compliance_rad_per_nm_, saturation_torque_nm_;
};

/// A gear's torsion curve as its maker's catalogue gives it: lost motion at small torque, then
/// stiffness in segments, K1 up to T1, K2 up to T2, and the joint's own (linear) stiffness K3
/// above. On top of the linear compliance C = 1/K3 of joint_compliance, each segment's extra
/// compliance e_s = 1/K_s − C:
///   Δθ_j = b tanh(τ_j / τ_s) + sign(τ_j) [e_1 min(|τ_j|, T1) + e_2 clamp(|τ_j| − T1, 0, T2 − T1)]
/// with τ_s = 1 N·m as a backlash's. Piecewise linear: a shape the model's torsion_curve (a sum
/// of smooth stiffening terms) does not hold exactly. b rad, e_s rad/(N·m), T_s N·m.
class TorsionCurve final : public LinkAngleEffect {
 public:
  static constexpr double kSmoothingTorque_nm = 1.0;
  /// joint 1 … dof; lost_motion_rad finite in [0, 0.01); extra compliances finite in
  /// [0, 1e-3) rad/(N·m), one per segment (1 or 2); segment end torques finite, > 0 and
  /// increasing, as many. Throws InputError naming the key and the value.
  TorsionCurve(int joint, double lost_motion_rad, std::vector<double> extra_compliance_rad_per_nm,
               std::vector<double> segment_end_torque_nm, int dof);
  std::string name() const override { return "torsion_curve"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  nlohmann::json toJson() const override;

 private:
  int joint_;
  double lost_motion_rad_;
  std::vector<double> extra_compliance_rad_per_nm_, segment_end_torque_nm_;
};

/// A joint whose stiffness varies with its angle (gear mesh stiffness over the revolution): on
/// top of the linear compliance, Δθ_j = ε cos(k q_j + φ) τ_j / K_j, with K_j the joint's
/// stiffness in joint_compliance and q_j its commanded angle. ε 1, φ rad.
class AngleDependentStiffness final : public LinkAngleEffect {
 public:
  /// joint 1 … dof; harmonic 1 … 64; amplitude ε finite in (0, 1); phase_rad finite;
  /// stiffness_nm_per_rad K_j finite and > 0 (joint_compliance's). Throws InputError naming the
  /// key and the value.
  AngleDependentStiffness(int joint, int harmonic, double amplitude, double phase_rad,
                          double stiffness_nm_per_rad, int dof);
  std::string name() const override { return "angle_dependent_stiffness"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  /// {"name", "joint", "harmonic", "amplitude", "phase_rad"} (K_j is joint_compliance's).
  nlohmann::json toJson() const override;

 private:
  int joint_, harmonic_;
  double amplitude_, phase_rad_, stiffness_nm_per_rad_;
};

/// Joint j's compliance in its other directions (a virtual-joint / 6-D spring model of a heavy
/// robot: its bearing tilts, its link bends): the frame after joint j's motion turns about its
/// origin by δ = c M⊥, with M the moment about that origin of everything joint j carries (the
/// payload's wrench and the weight of links j … n, the wrench whose component along the axis is
/// τ_j), in that frame's axes, and M⊥ its part perpendicular to the joint's axis (the part along
/// it is the joint's torsion, joint_compliance's). Every frame beyond turns with it. c rad/(N·m).
class BearingTilt final {
 public:
  /// joint 1 … dof; compliance_rad_per_nm finite in [0, 1e-5) (0: no tilt). Throws InputError
  /// naming the key and the value.
  BearingTilt(int joint, double compliance_rad_per_nm, int dof);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "bearing_tilt"; }
  /// Joint 1 … n.
  int joint() const noexcept { return joint_; }
  /// δ = c (M − a (a·M)) [rad, rotation vector], from the moment moment_Joint [N·m] and the
  /// joint's unit axis axis_Joint, both in the frame after the joint's motion.
  Vec3 tilt(const Vec3& moment_Joint, const Vec3& axis_Joint) const noexcept;
  /// {"name", "joint", "compliance_rad_per_nm"}.
  nlohmann::json toJson() const;

 private:
  int joint_;
  double compliance_rad_per_nm_;
};

/// The tool's mount (the F/T sensor, a tool changer) gives along the sensor's z axis under the
/// payload: the tool moves by δ = c (z·F) z, F the payload's force and z the sensor's z axis.
/// A spring in series with the arm beyond its last joint that shifts, not tilts: no joint's
/// frame and no mechanism of the catalogue has it.
class ToolMountCompliance final {
 public:
  /// compliance_m_per_n finite in [0, 1e-5) m/N (0: none). Throws InputError naming the key and
  /// the value.
  explicit ToolMountCompliance(double compliance_m_per_n);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "tool_mount_compliance"; }
  /// δ [m] from the payload's force force_Base [N] and the sensor's unit z axis z_Base, both in
  /// the same axes; δ in them.
  Vec3 shift(const Vec3& force_Base, const Vec3& z_Base) const noexcept;
  /// {"name", "compliance_m_per_n"}.
  nlohmann::json toJson() const;

 private:
  double compliance_m_per_n_;
};

/// Joint j's link angle moves with joint i's commanded angle (wrist coupling):
/// Δθ_j = c q_i. c rad/rad.
class JointCoupling final : public LinkAngleEffect {
 public:
  /// from_joint i and to_joint j distinct, 1 … dof; |c| finite and < 0.01. Throws InputError.
  JointCoupling(int from_joint, int to_joint, double ratio, int dof);
  std::string name() const override { return "joint_coupling"; }
  void apply(const JointVector& q_cmd_rad, const JointVector& tau_nm,
             JointVector& theta_rad) const override;
  nlohmann::json toJson() const override;

 private:
  int from_joint_, to_joint_;
  double ratio_;
};

/// Gravity of the links themselves (an imperfectly balanced arm), as point masses: link k
/// (1 … n) is the body joint k moves, its frame the chain frame after joint k's motion. The
/// torque on joint j is τ_j = Σ_{k ≥ j} J_s,jᵀ (m_k g, p_k × m_k g), with p_k the mass's position
/// and g gravity, both in base axes (the wrench about the base origin, like the payload's).
class SelfWeight final {
 public:
  /// One point mass.
  struct LinkMass {
    int link = 0;                       ///< 1 … n
    double mass_kg = 0.0;               ///< kg
    Vec3 p_ComInLink_m = Vec3::Zero();  ///< centre of mass in the link's frame, m
  };
  /// links: at least one, each link 1 … dof at most once, mass finite in (0, 2000) kg, centre
  /// of mass finite with |p| < 5 m. Throws InputError naming the key and the value.
  SelfWeight(std::vector<LinkMass> links, int dof);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "self_weight"; }
  /// Adds the links' gravity torques [N·m] to tau_nm, at the frames in ws (filled by
  /// forwardKinematics) with J_s the spatial Jacobian there; gravity_in_base m/s².
  void addTorques(const ChainWorkspace& ws, const Jacobian& J_s, const Vec3& gravity_in_base,
                  JointVector& tau_nm) const;
  /// The gravity wrench (f [N], m [N·m] about the base origin, base axes) of links
  /// first_link … n, those joint first_link carries, at the frames in ws.
  Vec6 wrenchOfLinksFrom(int first_link, const ChainWorkspace& ws,
                         const Vec3& gravity_in_base) const;
  /// {"name", "links": [{"link", "mass_kg", "com_m"}, …]}.
  nlohmann::json toJson() const;

 private:
  // One link's gravity wrench about the base origin, base axes.
  static Vec6 linkWrench(const LinkMass& l, const ChainWorkspace& ws, const Vec3& gravity_in_base);
  std::vector<LinkMass> links_;
};

/// Thermal expansion of the arm: the translations of the links' initial poses T_{1,2}(0) …
/// T_{n,n+1}(0) scale by s = 1 + α (T − T_ref) at the true temperature T (forwardKinematics'
/// link_length_scale). α 1/K, T_ref °C.
class ThermalExpansion final {
 public:
  /// expansion_per_k α finite with |α| < 1e-4 1/K; reference_temp_c finite, °C. Throws
  /// InputError naming the key and the value.
  ThermalExpansion(double expansion_per_k, double reference_temp_c);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "thermal_expansion"; }
  /// s = 1 + α (temp_c − T_ref) at the true temperature temp_c [°C]; 1 when temp_c is NaN.
  double linkLengthScale(double temp_c) const noexcept;
  /// {"name", "expansion_per_k", "reference_temp_c"}.
  nlohmann::json toJson() const;

 private:
  double expansion_per_k_, reference_temp_c_;
};

/// A constant offset of the F/T reading (a tare gone wrong), added to every row's reading,
/// unloaded rows included; the robot's physics is unaffected. sensor_link axes.
class SensorBias final {
 public:
  /// force_n finite with |f| < 500 N; moment_nm finite with |m| < 100 N·m. Throws InputError
  /// naming the key and the value.
  SensorBias(const Vec3& force_n, const Vec3& moment_nm);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "sensor_bias"; }
  /// The offset (f [N], m [N·m]) in sensor_link axes.
  const Vec6& wrench_Sensor() const noexcept { return wrench_Sensor_; }
  /// {"name", "force_n", "moment_nm"}.
  nlohmann::json toJson() const;

 private:
  Vec6 wrench_Sensor_;
};

/// Joint j's zero moves with the true temperature (a motor's or gearbox's heat):
/// Δθ_j = k (T − T_ref), added to the link angle whatever the load; none where T is unknown.
/// k rad/K, T_ref °C.
class JointZeroDrift final {
 public:
  /// joint 1 … dof; |k| finite and < 1e-3 rad/K; reference_temp_c finite. Throws InputError
  /// naming the key and the value.
  JointZeroDrift(int joint, double drift_rad_per_k, double reference_temp_c, int dof);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "joint_zero_drift"; }
  /// Joint 1 … n.
  int joint() const noexcept { return joint_; }
  /// Adds the drift at the true temperature temp_c [°C] to theta_rad (nothing when it is NaN).
  void apply(double temp_c, JointVector& theta_rad) const noexcept;
  /// {"name", "joint", "drift_rad_per_k", "reference_temp_c"}.
  nlohmann::json toJson() const;

 private:
  int joint_;
  double drift_rad_per_k_, reference_temp_c_;
};

/// The tracker's frame moving while the campaign is measured (a tripod settling, the floor
/// warming): the measurement's, not the robot's. Row seq (1 … rows) is measured in the frame
/// exp(ξ̂(seq)) · X_TrackerBase, ξ(seq) = g(seq) ξ_end with ξ_end = (translation_m, rotation_rad)
/// in tracker axes and g a settling 1 − exp(−(seq − 1)/settling_rows), or the ramp
/// (seq − 1)/(rows − 1) when settling_rows is 0.
class RegistrationDrift final {
 public:
  /// translation_m finite with norm < 0.01 m; rotation_rad finite with norm < 0.01 rad;
  /// settling_rows finite and ≥ 0. Throws InputError naming the key and the value.
  RegistrationDrift(const Vec3& translation_m, const Vec3& rotation_rad, double settling_rows);
  /// Name of the mechanism; the "name" key of its truth.json object.
  static std::string name() { return "registration_drift"; }
  /// The twist (v m, ω rad; tracker axes) that moves the tracker's frame at row seq of rows.
  Vec6 twist(int64_t seq, int64_t rows) const noexcept;
  /// {"name", "translation_m", "rotation_rad", "settling_rows"}.
  nlohmann::json toJson() const;

 private:
  Vec6 end_;
  double settling_rows_;
};

/// The mechanisms of one twin, by the stage they act on (the pipeline at the top of this file).
struct EffectSet {
  /// Link-angle effects in pipeline order (joint compliance first when on).
  std::vector<std::shared_ptr<const LinkAngleEffect>> link_angle;
  std::optional<SelfWeight> self_weight;
  std::optional<ThermalExpansion> thermal_expansion;
  std::optional<SensorBias> sensor_bias;
  std::vector<JointZeroDrift> zero_drift;  ///< at most one per joint
  std::vector<BearingTilt> bearing_tilt;   ///< at most one per joint, by joint
  std::optional<ToolMountCompliance> tool_mount;
  std::optional<RegistrationDrift> registration_drift;

  /// Adds the mechanism of a dof-joint chain described by its truth.json object ("name" and
  /// its parameters, joints and links numbered from 1). Throws InputError on an unknown name
  /// (listing the known ones), bad parameters, a second self_weight, thermal_expansion,
  /// sensor_bias or registration_drift, or a second joint_zero_drift of a joint;
  /// nlohmann::json::exception on a missing key or a wrong type. An angle_dependent_stiffness
  /// needs joint_compliance added first (its K_j).
  void add(const nlohmann::json& j, int dof);
  /// Every mechanism as its truth.json object: the link-angle effects in pipeline order, then
  /// the bearing tilts, self_weight, thermal_expansion, sensor_bias, the joint zero drifts,
  /// registration_drift.
  nlohmann::json toJson() const;
  /// Link-length scale at the true temperature temp_c [°C]: 1 without thermal_expansion or
  /// when temp_c is NaN.
  double linkLengthScale(double temp_c) const noexcept;
  /// The sensor_bias offset (f [N], m [N·m]) in sensor_link axes; zero without.
  Vec6 sensorBias_Sensor() const noexcept;

 private:
  // K_j of joint_compliance, for an effect that scales the joint's compliance; throws
  // InputError naming effect when the twin has none.
  double jointStiffness(const std::string& effect, int joint, int dof) const;
};

}  // namespace stepcal::twin
