// What several subcommands share: the robot a command works on (--robot and its links),
// --payload-cog, --gpr-points, and the files a calibration or diagnosis writes.
#pragma once

#include <initializer_list>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "stepcal/common/types.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::cli {

/// --robot and the chain's links, as plan and simulate take them.
struct RobotArgs {
  std::string robot = "irb4400";  ///< a URDF file or a shipped robot's name (robots.hpp)
  std::string base_link, tip_link;  ///< empty: the URDF's root and the end of its arm
  std::string sensor_link;  ///< empty: 'ft_sensor' when the URDF has it; "none": no sensor
};

/// The robot a command works on: its URDF file and links, resolved.
struct Robot {
  std::string urdf_path, base_link, tip_link, sensor_link;  ///< sensor_link empty: none
};

constexpr const char* kDefaultSensorLink = "ft_sensor";

/// Resolves a robot's URDF and links (the defaults from the URDF) and says which on stderr.
Robot resolveRobot(const RobotArgs& a);

/// "irb4400, ur10": the shipped robots found, for --robot's help.
std::string shippedRobotList();

/// --robot, --base-link, --tip-link and --sensor-link on command, filling a.
void addRobotOptions(CLI::App* command, RobotArgs& a);

/// x,y,z in metres from a --payload-cog value.
Vec3 payloadCoG(const std::vector<double>& xyz);

/// The output files given (the empty ones are not asked for).
std::vector<std::string> outputs(std::initializer_list<std::string> paths);

/// Writes an HTML report atomically.
void writeReport(const std::string& path, const std::string& html);

// The GPR's size trades accuracy for the runtime's call time (docs/runtime.md, "Against the
// number of GPR points").
inline const std::string kGprPointsHelp =
    "largest GPR training set: more residual rows are thinned evenly (the runtime's call time "
    "grows with it)";

/// The calibration's options with the GPR's training set capped at gpr_points (--gpr-points).
trainer::CalibrationOptions calibrationOptions(int gpr_points);

}  // namespace stepcal::cli
