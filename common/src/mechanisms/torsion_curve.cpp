#include "stepcal/common/mechanisms/torsion_curve.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

using View = TorsionCurve<const double>;

std::vector<std::string> names(int, int order) {
  std::vector<std::string> names = {"lost_motion_rad", "smoothing_torque_nm"};
  for (int k = 1; k <= order; ++k) {
    names.push_back("extra_compliance" + std::to_string(k) + "_rad_per_nm");
    names.push_back("knee_torque" + std::to_string(k) + "_nm");
  }
  names.push_back("linear_above_nm");
  return names;
}

std::string problem(const Mechanism& m, int) {
  const View c = view<TorsionCurve>(m);
  const std::string what = toString(m.kind);
  if (!(c.linearAbove_nm() >= 0.0)) {
    return what + " linear_above_nm = " + std::to_string(c.linearAbove_nm()) +
           "; expected ≥ 0 (0: the curve's formula at every torque)";
  }
  if (c.smoothingTorque_nm() < 0.0 ||
      (c.smoothingTorque_nm() == 0.0 && c.lostMotion_rad() != 0.0)) {
    return what + " smoothing_torque_nm = " + std::to_string(c.smoothingTorque_nm()) +
           " with lost_motion_rad = " + std::to_string(c.lostMotion_rad()) +
           "; expected > 0, or 0 with no lost motion";
  }
  if (c.smoothingTorque_nm() == 0.0 && m.order == 0) {
    return what + " has neither lost motion nor a stiffening term; expected at least one";
  }
  double previous = 0.0;
  for (int k = 1; k <= m.order; ++k) {
    const double knee = c.kneeTorque_nm(k);
    if (!(knee > previous)) {
      return what + " knee_torque" + std::to_string(k) + "_nm = " + std::to_string(knee) +
             "; expected > 0 and above the term before it";
    }
    previous = knee;
  }
  return {};
}

double deflection(const Mechanism& m, double tau_nm, double* derivative) noexcept {
  const View c = view<TorsionCurve>(m);
  double slope = 0.0, deflection = 0.0;
  addLostMotion(c.lostMotion_rad(), c.smoothingTorque_nm(), tau_nm, deflection, slope);
  for (int k = 1; k <= m.order; ++k) {
    addKnee(c.extraCompliance_rad_per_nm(k), c.kneeTorque_nm(k), tau_nm, deflection, slope);
  }
  if (derivative) *derivative = slope;
  return deflection;
}

double linearAbove(const Mechanism& m) noexcept { return view<TorsionCurve>(m).linearAbove_nm(); }

}  // namespace

const MechanismTraits& torsionCurveTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kTorsionCurve, "torsion_curve"};
    t.uses_joint = true;
    t.torque_deflection = true;
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerJoint;
    t.order_fits = [](int order) { return order >= 0 && order <= kMaxTorsionTerms; };
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
