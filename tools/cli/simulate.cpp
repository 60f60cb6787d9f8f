#include "simulate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/twin/model_twin.hpp"
#include "stepcal/twin/twin.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

// A number as written, shortest form ("-1e-07", "nan").
std::string shortest(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

// "J:C" of --off-axis-compliance on a chain of `joints` joints: joint J (1-based) and c
// rad/(N·m), as (J − 1, c); a joint outside the chain or a compliance no bearing has is refused
// with the option's own words (the twin's mechanism check would name a 0-based index).
std::pair<int, double> offAxisComplianceSpec(const std::string& spec, int joints) {
  constexpr double kMostCompliance_rad_per_nm = 1e-5;  // the twin's bearing_tilt bound
  const std::string hint = " (hint: 1:1.7e-7, a heavy robot's base bearing)";
  const size_t colon = spec.find(':');
  int joint = 0;
  double c = 0.0;
  bool parsed = false;
  try {
    if (colon != std::string::npos) {
      size_t used = 0;
      joint = std::stoi(spec.substr(0, colon), &used);
      const std::string c_text = spec.substr(colon + 1);
      size_t c_used = 0;
      c = std::stod(c_text, &c_used);
      parsed = used == colon && c_used == c_text.size();
    }
  } catch (const std::logic_error&) {
  }
  if (!parsed) {
    throw InputError("--off-axis-compliance '" + spec +
                     "'; expected JOINT:C, a joint (1-based) and its tilt compliance across the "
                     "axis in rad/(N·m)" + hint);
  }
  if (joint < 1 || joint > joints) {
    throw InputError("--off-axis-compliance '" + spec + "': joint " + std::to_string(joint) +
                     "; expected a joint 1 … " + std::to_string(joints) + " of the model's chain" +
                     hint);
  }
  if (!(std::isfinite(c) && c >= 0.0 && c < kMostCompliance_rad_per_nm)) {
    throw InputError("--off-axis-compliance '" + spec + "': compliance " + shortest(c) +
                     " rad/(N·m); expected a finite value in [0, 1e-05) rad/(N·m)" + hint);
  }
  return {joint - 1, c};
}

// The twin of a calibrated robot (model_twin.hpp): the model's physics on a campaign's rows.
void runSimulateModel(const SimulateArgs& a) {
  twin::ModelTwinOptions options;
  options.model_path = a.model;
  options.campaign_dir = a.campaign;
  options.seed = a.seed;
  if (a.position_sigma_given) options.tracker_position_sigma_m = a.position_sigma_mm * kMPerMm;
  if (a.orientation_sigma_given) {
    options.tracker_orientation_sigma_rad = a.orientation_sigma_deg * kRadPerDeg;
  }
  if (!a.payload_cog_m.empty()) options.p_CoGInSensor_m = payloadCoG(a.payload_cog_m);
  const int joints = readModelFile(a.model).chain_Tracker.dof();
  if (!a.poses.empty()) options.planned_fit_rows = readPoseList(a.poses, joints);
  for (const std::string& spec : a.off_axis_compliance) {
    options.off_axis_compliance.push_back(offAxisComplianceSpec(spec, joints));
  }
  options.tool_mount_compliance_m_per_n = a.tool_mount_compliance_m_per_n;
  twin::writeModelSimulation(options, a.out);
}

}  // namespace

void runSimulate(const SimulateArgs& a) {
  if (!a.model.empty()) {
    runSimulateModel(a);
    return;
  }
  const Robot robot = resolveRobot(a.robot);
  twin::TwinOptions options =
      twin::twinOptionsForRobot(robot.urdf_path, robot.base_link, robot.tip_link, robot.sensor_link);
  if (!a.protocol.empty()) options.protocol = a.protocol;
  options.seed = a.seed;
  options.station = a.station;
  options.tracker_position_sigma_m = a.position_sigma_mm * kMPerMm;
  options.tracker_orientation_sigma_rad = a.orientation_sigma_deg * kRadPerDeg;
  if (!a.stiffness_nm_per_rad.empty()) options.stiffness_nm_per_rad = a.stiffness_nm_per_rad;
  if (!a.payload_cog_m.empty()) options.p_CoGInSensor_m = payloadCoG(a.payload_cog_m);
  options.load_order = a.load_order;
  options.temperature_swing_c = a.temperature_swing_c;
  options.temperature_ramp_c = a.temperature_ramp_c;
  for (const std::string& spec : a.effects) {
    nlohmann::json effect;
    try {
      effect = nlohmann::json::parse(spec);
    } catch (const nlohmann::json::exception& e) {
      throw InputError("--effect '" + spec + "': not a JSON object (" + e.what() +
                       "); expected e.g. '{\"name\": \"backlash\", \"joint\": 2, "
                       "\"lost_motion_rad\": 2e-4}'");
    }
    // A self weight given replaces the one of the URDF's inertials.
    if (effect.is_object() && effect.value("name", "") == "self_weight") {
      auto& hidden = options.hidden_effects;
      hidden.erase(std::remove_if(hidden.begin(), hidden.end(),
                                  [](const nlohmann::json& e) { return e.at("name") == "self_weight"; }),
                   hidden.end());
    }
    options.hidden_effects.push_back(effect);
  }
  if (!a.poses.empty()) {
    const int joint_count =
        chainFromUrdfFile(options.urdf_path, options.base_link, options.tip_link).dof();
    options.planned_fit_rows = readPoseList(a.poses, joint_count);
  }
  twin::writeSimulation(options, a.out);
}

Subcommand addSimulateCommand(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  SimulateArgs& sim = *args;
  CLI::App* simulate = app.add_subcommand(
      "simulate", "write a campaign of a simulated robot (twin) and its truth.json: a robot drawn "
                  "from its URDF, or with --model the robot a calibrated model describes");
  addRobotOptions(simulate, sim.robot);
  simulate->add_option("--protocol", sim.protocol,
                       "paper | geometry (default: paper with an F/T sensor, else geometry)");
  simulate->add_option("--stiffness", sim.stiffness_nm_per_rad,
                       "joint stiffness K1,...,Kn, N·m/rad (default: the paper's for the IRB4400, "
                       "else each joint's URDF effort limit / 3 mrad)")
      ->delimiter(',');
  simulate->add_option("--payload-cog", sim.payload_cog_m,
                       "payload's centre of gravity in the sensor link, x,y,z, m (default "
                       "0.03,-0.02,0.15)")
      ->delimiter(',');
  CLI::Option* model_option = simulate->add_option(
      "--model", sim.model,
      "model file (calibrate/diagnose --out): simulate the robot it describes (calibrated "
      "geometry, compliance, every mechanism; not the GPR) on a campaign's rows");
  CLI::Option* campaign_option = simulate->add_option(
      "--campaign", sim.campaign,
      "with --model: the campaign whose rows, robot description and tracker noise are used "
      "(default: the model's own, from its provenance)");
  campaign_option->needs(model_option);
  simulate
      ->add_option("--off-axis-compliance", sim.off_axis_compliance,
                   "with --model: switch on a tilt of joint J across its axis in the twin, "
                   "c M⊥ (off_axis_compliance, isotropic), J:C with J a joint of the model's chain "
                   "(1-based) and C in [0, 1e-5) rad/(N·m), e.g. 1:1.7e-7; repeatable")
      ->needs(model_option);
  simulate
      ->add_option("--tool-mount-compliance", sim.tool_mount_compliance_m_per_n,
                   "with --model: switch on the tool's mount giving along the F/T sensor's z in "
                   "the twin (tool_mount_compliance, 0, 0, C), C ≥ 0 m/N, e.g. 2e-7")
      ->needs(model_option);
  for (const char* robot_only : {"--robot", "--base-link", "--tip-link", "--sensor-link",
                                 "--protocol", "--stiffness"}) {
    model_option->excludes(simulate->get_option(robot_only));
  }
  simulate->add_option("--seed", sim.seed, "random seed")->capture_default_str();
  simulate->add_option("--station", sim.station,
                       "tracker station: 0 = the seed's own placement; k >= 1 = the same robot "
                       "measured from another tracker placement, with its own poses and noise")
      ->capture_default_str()
      ->excludes(model_option);
  simulate->add_option("--tracker-position-sigma-mm", sim.position_sigma_mm,
                       "tracker position noise per axis, 1-sigma, mm (with --model: the "
                       "campaign's stated noise)")->capture_default_str();
  simulate->add_option("--tracker-orientation-sigma-deg", sim.orientation_sigma_deg,
                       "tracker orientation noise per axis, 1-sigma, deg (with --model: the "
                       "campaign's stated noise)")->capture_default_str();
  simulate->add_option("--effect", sim.effects,
                       "a hidden mechanism as JSON, repeatable: backlash {joint, lost_motion_rad}, "
                       "transmission_error {joint, harmonic, sin_rad, cos_rad}, nonlinear_stiffness "
                       "{joint, extra_compliance_rad_per_nm, saturation_torque_nm}, joint_coupling "
                       "{joints: [from, to], ratio}, self_weight {links: [{link, mass_kg, com_m}]}, "
                       "thermal_expansion {expansion_per_k, reference_temp_c}, sensor_bias "
                       "{force_n, moment_nm}, joint_zero_drift {joint, drift_rad_per_k, "
                       "reference_temp_c}, registration_drift {translation_m, rotation_rad, "
                       "settling_rows}; outside the diagnosis's catalogue: bearing_tilt {joint, "
                       "compliance_rad_per_nm}, angle_dependent_stiffness {joint, harmonic, "
                       "amplitude, phase_rad}; joints and links 1 … n; a self_weight replaces the "
                       "URDF inertials' one")
      ->excludes(model_option);
  simulate->add_option("--load-order", sim.load_order,
                       "blocks | mixed: the fit rows measured load block by load block (the "
                       "paper's, the load rising with the time order) or shuffled (seeded), so "
                       "that a drift in time can be told from a load effect")
      ->capture_default_str()
      ->excludes(model_option);
  simulate->add_option("--temperature-swing-c", sim.temperature_swing_c,
                       "amplitude of the true temperature's sinusoid, °C (period 300 rows)")
      ->capture_default_str()
      ->excludes(model_option);
  simulate->add_option("--temperature-ramp-c", sim.temperature_ramp_c,
                       "rise of the true temperature from the first row to the last, °C, on top "
                       "of the sinusoid (with --temperature-swing-c 0: a steady ramp, "
                       "temperature and time order correlated)")
      ->capture_default_str()
      ->excludes(model_option);
  simulate->add_option("--poses", sim.poses,
                       "pose list (poses.csv, e.g. from stepcal plan) measured as the fit rows; "
                       "the protocol's (with --model: the campaign's) validation rows stay");
  simulate->add_option("--out", sim.out, "campaign folder to write")->required();
  return {simulate, [args, simulate] {
            args->position_sigma_given = simulate->count("--tracker-position-sigma-mm") > 0;
            args->orientation_sigma_given =
                simulate->count("--tracker-orientation-sigma-deg") > 0;
            runSimulate(*args);
            std::cerr << "wrote " << args->out << " (campaign + truth.json)\n";
          }};
}

}  // namespace stepcal::cli
