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

std::shared_ptr<const LinkAngleEffect> linkAngleEffectFromJson(const nlohmann::json& j, int dof) {
  const std::string name = j.at("name").get<std::string>();
  if (name == "joint_compliance") {
    auto stiffness = j.at("stiffness_nm_per_rad").get<std::vector<double>>();
    if (stiffness.size() != static_cast<size_t>(dof)) {
      throw InputError("joint_compliance has " + std::to_string(stiffness.size()) +
                       " stiffness values; expected one per joint, " + std::to_string(dof));
    }
    return std::make_shared<JointCompliance>(std::move(stiffness));
  }
  throw InputError("unknown link-angle effect '" + name +
                   "'; expected 'joint_compliance' (hint: was the truth written by a newer "
                   "stepcal?)");
}

}  // namespace stepcal::twin
