#include "stepcal/common/mechanisms/session_frames.hpp"

#include "kinds.hpp"
#include "stepcal/common/lie.hpp"

namespace stepcal::mechanism {

const MechanismTraits& sessionFramesTraits() {
  static const MechanismTraits traits = [] {
    MechanismTraits t{MechanismKind::kSessionFrames, "session_frames"};
    t.measurement_only = true;
    t.order_fits = [](int order) { return order >= 1; };
    t.parameter_names = [](int, int) -> std::vector<std::string> {
      return {"station_x_m",    "station_y_m",    "station_z_m", "station_rx_rad",
              "station_ry_rad", "station_rz_rad", "tool_x_m",    "tool_y_m",
              "tool_z_m",       "tool_rx_rad",    "tool_ry_rad", "tool_rz_rad"};
    };
    t.describe_suffix = [](const Mechanism& m) {
      return " (campaign " + std::to_string(m.order + 1) + ")";
    };
    return t;
  }();
  return traits;
}

}  // namespace stepcal::mechanism

namespace stepcal {

StationAndTool stationAndTool(const Mechanism& frames) noexcept {
  const auto pose = [](const double* p) {  // t (3), r (3)
    Pose X = Pose::Identity();
    X.linear() = lie::expSO3(Vec3(p[3], p[4], p[5]));
    X.translation() = Vec3(p[0], p[1], p[2]);
    return X;
  };
  const mechanism::SessionFrames<const double> f = view<mechanism::SessionFrames>(frames);
  return {pose(&f.station(0)), pose(&f.tool(0))};
}

std::vector<double> stationAndToolParameters(const Pose& X_Station, const Pose& X_Tool) {
  std::vector<double> p;
  for (const Pose* X : {&X_Station, &X_Tool}) {
    const Vec3 r = lie::logSO3(X->linear());
    p.insert(p.end(), {X->translation().x(), X->translation().y(), X->translation().z(), r.x(),
                       r.y(), r.z()});
  }
  return p;
}

}  // namespace stepcal
