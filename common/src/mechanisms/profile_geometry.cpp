#include "stepcal/common/mechanisms/profile_geometry.hpp"

#include "kinds.hpp"

namespace stepcal::mechanism {
namespace {

std::vector<std::string> names(int dof, int) {
  std::vector<std::string> names;
  for (int k = 0; k <= dof; ++k) {
    const std::string pose = "pose" + std::to_string(k) + "_";
    for (const char* p : {"vx_m", "vy_m", "vz_m", "wx_rad", "wy_rad", "wz_rad"}) {
      names.push_back(pose + p);
    }
  }
  return names;
}

}  // namespace

const MechanismTraits& profileGeometryTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kProfileGeometry, "profile_geometry"};
    t.uses_joint = true;
    t.multiplicity = MechanismTraits::Multiplicity::kOnePerJoint;
    t.order_fits = [](int order) { return order == 0; };
    t.parameter_names = names;
    t.describe_suffix = jointSuffix;
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism
