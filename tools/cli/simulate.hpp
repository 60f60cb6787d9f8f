// `stepcal simulate`: a campaign of the simulated robot (twin) and its truth.json; demo.cpp
// simulates with it too.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common.hpp"

namespace stepcal::cli {

struct SimulateArgs {
  RobotArgs robot;
  std::string protocol;  ///< empty: paper with a sensor, geometry without
  std::vector<double> stiffness_nm_per_rad;  ///< --stiffness; empty: the robot's default
  std::vector<double> payload_cog_m;         ///< --payload-cog; empty: the twin's default
  std::string model;     ///< --model: the twin of a calibrated robot
  std::string campaign;  ///< --campaign: the rows the model's twin measures
  uint64_t seed = 1;
  int station = 0;  ///< --station: the tracker's placement (TwinOptions::station)
  std::string out;
  double position_sigma_mm = 0.010;
  double orientation_sigma_deg = 0.005;
  bool position_sigma_given = false, orientation_sigma_given = false;
  std::vector<std::string> effects;  ///< --effect: hidden mechanisms as JSON objects
  std::string poses;  ///< --poses: a pose list (poses.csv) to measure as the fit rows
  std::string load_order = "blocks";  ///< --load-order (TwinOptions::load_order)
  double temperature_swing_c = 3.0;   ///< --temperature-swing-c (TwinOptions)
  double temperature_ramp_c = 0.0;    ///< --temperature-ramp-c (TwinOptions)
  /// --off-axis-compliance JOINT:C (with --model): ModelTwinOptions::off_axis_compliance
  std::vector<std::string> off_axis_compliance;
  /// --tool-mount-compliance C (with --model): ModelTwinOptions::tool_mount_compliance_m_per_n
  double tool_mount_compliance_m_per_n = 0.0;
};

/// Writes the campaign a.out (and its truth.json): of a robot drawn from its URDF, or with
/// a.model of the robot a calibrated model describes.
void runSimulate(const SimulateArgs& a);

}  // namespace stepcal::cli
