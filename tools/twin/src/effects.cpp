#include "stepcal/twin/effects.hpp"

#include <cmath>
#include <utility>

#include "stepcal/common/error.hpp"

namespace stepcal::twin {

JointCompliance::JointCompliance(std::vector<double> stiffness_nm_per_rad)
    : stiffness_nm_per_rad_(std::move(stiffness_nm_per_rad)) {
  for (size_t i = 0; i < stiffness_nm_per_rad_.size(); ++i) {
    const double k = stiffness_nm_per_rad_[i];
    if (!(std::isfinite(k) && k > 0.0)) {
      throw InputError("stiffness of joint " + std::to_string(i + 1) + " is " +
                       std::to_string(k) +
                       " N·m/rad; expected a finite value > 0 (hint: the paper's IRB4400 values "
                       "are 74226 … 633590 N·m/rad)");
    }
  }
}

void JointCompliance::apply(const JointVector& /*q_cmd_rad*/, const JointVector& tau_nm,
                            JointVector& theta_rad) const {
  STEPCAL_INVARIANT(tau_nm.size() == static_cast<Eigen::Index>(stiffness_nm_per_rad_.size()) &&
                        theta_rad.size() == tau_nm.size(),
                    "compliance: one stiffness per joint");
  for (Eigen::Index i = 0; i < tau_nm.size(); ++i) {
    theta_rad(i) += tau_nm(i) / stiffness_nm_per_rad_[static_cast<size_t>(i)];
  }
}

nlohmann::json JointCompliance::toJson() const {
  return {{"name", name()}, {"stiffness_nm_per_rad", stiffness_nm_per_rad_}};
}

namespace {

/// Throws unless joint is 1 … dof.
void requireJoint(const std::string& effect, const char* key, int joint, int dof) {
  if (joint < 1 || joint > dof) {
    throw InputError(effect + "." + key + " = " + std::to_string(joint) + "; expected a joint 1 … " +
                     std::to_string(dof));
  }
}

/// Throws unless lower < |value| < upper (lower 0 allows 0 only when allow_zero).
void requireMagnitude(const std::string& effect, const char* key, double value, double upper,
                      bool allow_zero, const char* unit) {
  const bool ok = std::isfinite(value) && std::abs(value) < upper && (allow_zero || value > 0.0);
  if (!ok) {
    throw InputError(effect + "." + key + " = " + std::to_string(value) + " " + unit +
                     "; expected a finite value " + (allow_zero ? "with |value| < " : "in (0, ") +
                     std::to_string(upper) + (allow_zero ? "" : ")") + " " + unit);
  }
}

}  // namespace

Backlash::Backlash(int joint, double lost_motion_rad, int dof)
    : joint_(joint), lost_motion_rad_(lost_motion_rad) {
  requireJoint(name(), "joint", joint, dof);
  requireMagnitude(name(), "lost_motion_rad", lost_motion_rad, 0.01, false, "rad");
}

void Backlash::apply(const JointVector&, const JointVector& tau_nm, JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  theta_rad(j) += lost_motion_rad_ * std::tanh(tau_nm(j) / kSmoothingTorque_nm);
}

nlohmann::json Backlash::toJson() const {
  return {{"name", name()}, {"joint", joint_}, {"lost_motion_rad", lost_motion_rad_}};
}

TransmissionError::TransmissionError(int joint, int harmonic, double sin_rad, double cos_rad,
                                     int dof)
    : joint_(joint), harmonic_(harmonic), sin_rad_(sin_rad), cos_rad_(cos_rad) {
  requireJoint(name(), "joint", joint, dof);
  if (harmonic < 1 || harmonic > 64) {
    throw InputError(name() + ".harmonic = " + std::to_string(harmonic) + "; expected 1 … 64");
  }
  requireMagnitude(name(), "sin_rad", sin_rad, 0.01, true, "rad");
  requireMagnitude(name(), "cos_rad", cos_rad, 0.01, true, "rad");
}

void TransmissionError::apply(const JointVector& q_cmd_rad, const JointVector&,
                              JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  const double angle = harmonic_ * q_cmd_rad(j);
  theta_rad(j) += sin_rad_ * std::sin(angle) + cos_rad_ * std::cos(angle);
}

nlohmann::json TransmissionError::toJson() const {
  return {{"name", name()}, {"joint", joint_}, {"harmonic", harmonic_},
          {"sin_rad", sin_rad_}, {"cos_rad", cos_rad_}};
}

NonlinearStiffness::NonlinearStiffness(int joint, double extra_compliance_rad_per_nm,
                                       double saturation_torque_nm, int dof)
    : joint_(joint),
      extra_compliance_rad_per_nm_(extra_compliance_rad_per_nm),
      saturation_torque_nm_(saturation_torque_nm) {
  requireJoint(name(), "joint", joint, dof);
  requireMagnitude(name(), "extra_compliance_rad_per_nm", extra_compliance_rad_per_nm, 1e-3,
                   false, "rad/(N·m)");
  requireMagnitude(name(), "saturation_torque_nm", saturation_torque_nm, 1e9, false, "N·m");
}

void NonlinearStiffness::apply(const JointVector&, const JointVector& tau_nm,
                               JointVector& theta_rad) const {
  const Eigen::Index j = joint_ - 1;
  const double tau = tau_nm(j);
  theta_rad(j) += extra_compliance_rad_per_nm_ * tau * saturation_torque_nm_ /
                  (saturation_torque_nm_ + std::abs(tau));
}

nlohmann::json NonlinearStiffness::toJson() const {
  return {{"name", name()},
          {"joint", joint_},
          {"extra_compliance_rad_per_nm", extra_compliance_rad_per_nm_},
          {"saturation_torque_nm", saturation_torque_nm_}};
}

JointCoupling::JointCoupling(int from_joint, int to_joint, double ratio, int dof)
    : from_joint_(from_joint), to_joint_(to_joint), ratio_(ratio) {
  requireJoint(name(), "joints[0]", from_joint, dof);
  requireJoint(name(), "joints[1]", to_joint, dof);
  if (from_joint == to_joint) {
    throw InputError(name() + ".joints = [" + std::to_string(from_joint) + ", " +
                     std::to_string(to_joint) + "]; expected two different joints");
  }
  requireMagnitude(name(), "ratio", ratio, 0.01, false, "rad/rad");
}

void JointCoupling::apply(const JointVector& q_cmd_rad, const JointVector&,
                          JointVector& theta_rad) const {
  theta_rad(to_joint_ - 1) += ratio_ * q_cmd_rad(from_joint_ - 1);
}

nlohmann::json JointCoupling::toJson() const {
  return {{"name", name()}, {"joints", {from_joint_, to_joint_}}, {"ratio", ratio_}};
}

std::shared_ptr<const LinkAngleEffect> linkAngleEffectFromJson(const nlohmann::json& j, int dof) {
  const std::string name = j.at("name").get<std::string>();
  if (name == "backlash") {
    return std::make_shared<Backlash>(j.at("joint").get<int>(), j.at("lost_motion_rad").get<double>(), dof);
  }
  if (name == "transmission_error") {
    return std::make_shared<TransmissionError>(j.at("joint").get<int>(), j.at("harmonic").get<int>(),
                                               j.value("sin_rad", 0.0), j.value("cos_rad", 0.0), dof);
  }
  if (name == "nonlinear_stiffness") {
    return std::make_shared<NonlinearStiffness>(j.at("joint").get<int>(),
                                                j.at("extra_compliance_rad_per_nm").get<double>(),
                                                j.at("saturation_torque_nm").get<double>(), dof);
  }
  if (name == "joint_coupling") {
    const auto joints = j.at("joints").get<std::vector<int>>();
    if (joints.size() != 2) {
      throw InputError("joint_coupling.joints has " + std::to_string(joints.size()) +
                       " entries; expected [from_joint, to_joint]");
    }
    return std::make_shared<JointCoupling>(joints[0], joints[1], j.at("ratio").get<double>(), dof);
  }
  if (name == "joint_compliance") {
    auto stiffness = j.at("stiffness_nm_per_rad").get<std::vector<double>>();
    if (stiffness.size() != static_cast<size_t>(dof)) {
      throw InputError("joint_compliance has " + std::to_string(stiffness.size()) +
                       " stiffness values; expected one per joint, " + std::to_string(dof));
    }
    return std::make_shared<JointCompliance>(std::move(stiffness));
  }
  throw InputError("unknown link-angle effect '" + name +
                   "'; expected joint_compliance, backlash, transmission_error, "
                   "nonlinear_stiffness or joint_coupling");
}

}  // namespace stepcal::twin
