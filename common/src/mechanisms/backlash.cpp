#include "stepcal/common/mechanisms/backlash.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

using View = Backlash<const double>;

std::vector<std::string> names(int, int) { return {"lost_motion_rad", "smoothing_torque_nm"}; }

std::string problem(const Mechanism& m, int) {
  const View b = view<Backlash>(m);
  if (!(b.smoothingTorque_nm() > 0.0)) {
    return std::string(toString(m.kind)) +
           " smoothing_torque_nm = " + std::to_string(b.smoothingTorque_nm()) + "; expected > 0";
  }
  return {};
}

double deflection(const Mechanism& m, double tau_nm, double* derivative) noexcept {
  const View b = view<Backlash>(m);
  double slope = 0.0, deflection = 0.0;
  addLostMotion(b.lostMotion_rad(), b.smoothingTorque_nm(), tau_nm, deflection, slope);
  if (derivative) *derivative = slope;
  return deflection;
}

double linearAbove(const Mechanism&) noexcept { return 0.0; }

}  // namespace

const MechanismTraits& backlashTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kBacklash, "backlash"};
    t.uses_joint = true;
    t.torque_deflection = true;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = names;
    t.problem = problem;
    t.describe_suffix = jointSuffix;
    t.deflection = deflection;
    t.linear_above_nm = linearAbove;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
