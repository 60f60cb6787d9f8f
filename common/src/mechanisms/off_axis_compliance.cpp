#include "stepcal/common/mechanisms/off_axis_compliance.hpp"

#include <cmath>

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

using View = OffAxisCompliance<const double>;

std::vector<std::string> names(int, int) {
  return {"tilt_u_compliance_rad_per_nm", "tilt_v_compliance_rad_per_nm"};
}

// A negative compliance is a frame that turns against the moment: no bearing does.
std::string problem(const Mechanism& m, int) {
  const View c = view<OffAxisCompliance>(m);
  if (!(c.tiltU_rad_per_nm() >= 0.0 && c.tiltV_rad_per_nm() >= 0.0)) {
    return std::string(toString(m.kind)) + " compliances " + std::to_string(c.tiltU_rad_per_nm()) +
           ", " + std::to_string(c.tiltV_rad_per_nm()) + " rad/(N·m); expected ≥ 0";
  }
  return {};
}

}  // namespace

void tiltDirections(const Vec3& axis, Vec3& u, Vec3& v) noexcept {
  int least = 0;
  for (int i = 1; i < 3; ++i) {
    if (std::abs(axis(i)) < std::abs(axis(least))) least = i;
  }
  u = Vec3::Unit(least) - axis(least) * axis;
  u.normalize();
  v = axis.cross(u);
}

Vec3 frameTilt_rad(const Mechanism& m, const Vec3& axis, const Vec3& moment_Nm) noexcept {
  const View c = view<OffAxisCompliance>(m);
  Vec3 u, v;
  tiltDirections(axis, u, v);
  return c.tiltU_rad_per_nm() * u.dot(moment_Nm) * u + c.tiltV_rad_per_nm() * v.dot(moment_Nm) * v;
}

const MechanismTraits& offAxisComplianceTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kOffAxisCompliance, "off_axis_compliance"};
    t.uses_joint = true;
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerJoint;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = names;
    t.problem = problem;
    t.describe_suffix = jointSuffix;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
