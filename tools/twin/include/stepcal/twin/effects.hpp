// Hidden physical mechanisms of the twin, each a small stage of the measurement pipeline.
//
// One measurement of the true robot at commanded joint angles q_cmd under a payload:
//   1. link angles θ, the fixed point of
//        τ = J_s(θ)ᵀ W_payload(θ)                  joint load torques, N·m
//        θ = e_k(q_cmd, τ, … e_1(q_cmd, τ, q_cmd))  the link-angle effects in order
//   2. tip pose  X_TrackerTip = X_TrackerBase · FK_true(θ)
//   3. F/T sensor wrench at the same θ
// A mechanism that moves the link side away from the controller's angles is a LinkAngleEffect.
// Only joint compliance exists now; backlash, transmission error, nonlinear stiffness and joint
// coupling are meant to be further LinkAngleEffects.
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

/// Rebuilds an effect of a dof-joint chain from its truth.json object. Throws InputError on an
/// unknown name or bad parameters.
std::shared_ptr<const LinkAngleEffect> linkAngleEffectFromJson(const nlohmann::json& j, int dof);

}  // namespace stepcal::twin
