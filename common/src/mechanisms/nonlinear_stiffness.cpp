#include "stepcal/common/mechanisms/nonlinear_stiffness.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

using View = NonlinearStiffness<const double>;

std::vector<std::string> names(int, int) {
  return {"extra_compliance_rad_per_nm", "saturation_torque_nm", "linear_above_nm"};
}

std::string problem(const Mechanism& m, int) {
  const View s = view<NonlinearStiffness>(m);
  const std::string what = toString(m.kind);
  if (!(s.saturationTorque_nm() > 0.0)) {
    return what + " saturation_torque_nm = " + std::to_string(s.saturationTorque_nm()) +
           "; expected > 0";
  }
  if (!(s.linearAbove_nm() >= 0.0)) {
    return what + " linear_above_nm = " + std::to_string(s.linearAbove_nm()) +
           "; expected ≥ 0 (0: the curve's formula at every torque)";
  }
  return {};
}

double deflection(const Mechanism& m, double tau_nm, double* derivative) noexcept {
  const View s = view<NonlinearStiffness>(m);
  double slope = 0.0, deflection = 0.0;
  addFade(s.extraCompliance_rad_per_nm(), s.saturationTorque_nm(), tau_nm, deflection, slope);
  if (derivative) *derivative = slope;
  return deflection;
}

double linearAbove(const Mechanism& m) noexcept {
  return view<NonlinearStiffness>(m).linearAbove_nm();
}

}  // namespace

const MechanismTraits& nonlinearStiffnessTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kNonlinearStiffness, "nonlinear_stiffness"};
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
