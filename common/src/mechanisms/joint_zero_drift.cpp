#include "stepcal/common/mechanisms/joint_zero_drift.hpp"

#include <cmath>

#include "kinds.hpp"

namespace stepcal::mechanism {

const MechanismTraits& jointZeroDriftTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kJointZeroDrift, "joint_zero_drift"};
    t.uses_joint = true;
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerJoint;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = [](int, int) -> std::vector<std::string> {
      return {"drift_rad_per_k", "reference_temp_c"};
    };
    t.describe_suffix = jointSuffix;
    t.add_link_angle_offset = [](const Mechanism& m, const JointVector&, double temp_c,
                                 JointVector& theta0_rad) noexcept {
      const JointZeroDrift<const double> drift = view<JointZeroDrift>(m);
      if (std::isfinite(temp_c)) {
        theta0_rad(m.joint) += drift.driftRate_rad_per_k() * (temp_c - drift.referenceTemp_c());
      }
    };
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
