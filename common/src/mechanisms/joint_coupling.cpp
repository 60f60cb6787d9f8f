#include "stepcal/common/mechanisms/joint_coupling.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {

const MechanismTraits& jointCouplingTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kJointCoupling, "joint_coupling"};
    t.uses_joint = true;
    t.uses_source_joint = true;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = [](int, int) -> std::vector<std::string> { return {"ratio"}; };
    t.describe_suffix = [](const Mechanism& m) {
      return " (joint " + std::to_string(m.source_joint + 1) + " -> joint " +
             std::to_string(m.joint + 1) + ")";
    };
    t.add_link_angle_offset = [](const Mechanism& m, const JointVector& q_rad, double,
                                 JointVector& theta0_rad) noexcept {
      theta0_rad(m.joint) += view<JointCoupling>(m).ratio() * q_rad(m.source_joint);
    };
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
