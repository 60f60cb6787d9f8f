#include "stepcal/common/mechanisms/tool_mount_compliance.hpp"

#include "kinds.hpp"
#include "stepcal/common/text_number.hpp"

namespace stepcal::mechanism {
namespace {

using View = ToolMountCompliance<const double>;

std::vector<std::string> names(int, int) {
  return {"x_compliance_m_per_n", "y_compliance_m_per_n", "z_compliance_m_per_n"};
}

// A negative compliance is a mount that moves against the force on it: no spring does.
std::string problem(const Mechanism& m, int) {
  const View c = view<ToolMountCompliance>(m);
  if (!(c.alongX_m_per_n() >= 0.0 && c.alongY_m_per_n() >= 0.0 && c.alongZ_m_per_n() >= 0.0)) {
    return std::string(toString(m.kind)) + " compliances " +
           formatShortest(c.alongX_m_per_n()) + ", " + formatShortest(c.alongY_m_per_n()) + ", " +
           formatShortest(c.alongZ_m_per_n()) + " m/N (x, y, z); expected ≥ 0";
  }
  return {};
}

}  // namespace

Vec3 toolShift_m(const Mechanism& m, const Vec3& force_Mount_N) noexcept {
  const View c = view<ToolMountCompliance>(m);
  return {c.alongX_m_per_n() * force_Mount_N.x(), c.alongY_m_per_n() * force_Mount_N.y(),
          c.alongZ_m_per_n() * force_Mount_N.z()};
}

const MechanismTraits& toolMountComplianceTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kToolMountCompliance, "tool_mount_compliance"};
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerModel;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = names;
    t.problem = problem;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
