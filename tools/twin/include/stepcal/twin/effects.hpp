// Hidden physical mechanisms of the twin, each a small stage of the measurement pipeline.
//
// One measurement of the true robot at commanded joint angles q_cmd under a payload:
//   1. link angles θ, the fixed point of
//        τ = J_s(θ)ᵀ W_payload(θ)                  joint load torques, N·m
//        θ = e_k(q_cmd, τ, … e_1(q_cmd, τ, q_cmd))  the link-angle effects in order
//   2. tip pose  X_TrackerTip = X_TrackerBase · FK_true(θ)
//   3. F/T sensor wrench at the same θ
// A mechanism that moves the link side away from the controller's angles is a LinkAngleEffect:
// joint compliance (always, unless switched off) and the hidden mechanisms a campaign may carry
// (backlash, transmission error, nonlinear stiffness, joint coupling), each on given joints with
// given parameters. Joints are numbered 1 … n in names, parameters and truth.json.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

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

/// Linear joint compliance (METHOD.md eq. 15): every joint a torsion spring, Δθ = K⁻¹ τ,
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

/// Rebuilds an effect of a dof-joint chain from its truth.json object ("name" and its
/// parameters, joints numbered from 1). Throws InputError on an unknown name or bad parameters.
std::shared_ptr<const LinkAngleEffect> linkAngleEffectFromJson(const nlohmann::json& j, int dof);

}  // namespace stepcal::twin
