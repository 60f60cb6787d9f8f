#include "common.hpp"

#include <iostream>

#include "stepcal/common/atomic_file.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal::cli {
namespace {

constexpr const char* kNoSensor = "none";

}  // namespace

Robot resolveRobot(const RobotArgs& a) {
  Robot r;
  r.urdf_path = robotDescriptionPath(a.robot);
  const std::string urdf_xml = readTextFile(r.urdf_path);
  if (a.base_link.empty() || a.tip_link.empty()) {
    const UrdfChainEnds ends = urdfChainEnds(urdf_xml, r.urdf_path);
    r.base_link = a.base_link.empty() ? ends.base_link : a.base_link;
    r.tip_link = a.tip_link.empty() ? ends.tip_link : a.tip_link;
  } else {
    r.base_link = a.base_link;
    r.tip_link = a.tip_link;
  }
  if (a.sensor_link.empty()) {
    if (urdfHasLink(urdf_xml, kDefaultSensorLink, r.urdf_path)) r.sensor_link = kDefaultSensorLink;
  } else if (a.sensor_link != kNoSensor) {
    r.sensor_link = a.sensor_link;
  }
  std::cerr << "robot " << r.urdf_path << ": " << r.base_link << " -> " << r.tip_link << ", "
            << (r.sensor_link.empty() ? "no F/T sensor (unloaded rows only)"
                                      : "payloads and their wrench at " + r.sensor_link)
            << "\n";
  return r;
}

std::string shippedRobotList() {
  std::string names;
  for (const std::string& name : shippedRobots()) names += (names.empty() ? "" : ", ") + name;
  return names.empty() ? std::string("none found") : names;
}

void addRobotOptions(CLI::App* command, RobotArgs& a) {
  command->add_option("--robot", a.robot,
                      "robot description: a URDF file (a path with '/' or ending in .urdf) or a "
                      "shipped robot's name (" + shippedRobotList() + ")")
      ->capture_default_str();
  command->add_option("--base-link", a.base_link,
                      "root of the chain (default: the URDF's root link)");
  command->add_option("--tip-link", a.tip_link,
                      "frame the tracker measures (default: the link that ends the arm)");
  command->add_option("--sensor-link", a.sensor_link,
                      "link the payload hangs from, whose axes its wrench is in: the F/T "
                      "sensor's, or for a payload of known mass and --payload-cog any link of "
                      "the arm (default: 'ft_sensor' if the URDF has it; 'none': unloaded only)");
}

Vec3 payloadCoG(const std::vector<double>& xyz) {
  if (xyz.size() != 3) {
    throw InputError("--payload-cog has " + std::to_string(xyz.size()) +
                     " values; expected x,y,z of the payload's centre of gravity in the sensor "
                     "link, m (hint: --payload-cog 0.03,-0.02,0.15)");
  }
  return Vec3(xyz[0], xyz[1], xyz[2]);
}

std::vector<std::string> outputs(std::initializer_list<std::string> paths) {
  std::vector<std::string> out;
  for (const std::string& path : paths) {
    if (!path.empty()) out.push_back(path);
  }
  return out;
}

void writeReport(const std::string& path, const std::string& html) {
  writeFileAtomically(path, html.data(), html.size(), "report");
}

trainer::CalibrationOptions calibrationOptions(int gpr_points) {
  if (gpr_points < 2) {
    throw InputError("--gpr-points " + std::to_string(gpr_points) +
                     ": expected at least 2 training points (default " +
                     std::to_string(trainer::CalibrationOptions{}.gpr_max_points) + ")");
  }
  trainer::CalibrationOptions options;
  options.gpr_max_points = gpr_points;
  return options;
}

}  // namespace stepcal::cli
