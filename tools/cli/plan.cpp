// `stepcal plan`: the poses of a campaign (trainer/plan.hpp), written as a pose list.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "common.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/report/certificate.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/trainer/iso9283_plan.hpp"
#include "stepcal/trainer/plan.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct PlanArgs {
  RobotArgs robot;
  std::vector<double> loads_kg;  ///< empty: 0,20,40 with a sensor link, else 0
  std::vector<double> payload_cog_m;
  std::string candidates_from;  ///< a campaign whose measured poses are the candidates
  std::string recheck_model;    ///< a model to plan the re-check of; empty: a calibration's plan
  std::string selection = "d-optimal";
  std::vector<double> tracker_m = {4.0, 0.0, 1.2};
  std::vector<int> off_axis_joints;  ///< 1-based, as on the command line
  std::string out;
  trainer::PlanOptions options;
  bool iso9283 = false;
  bool poses_given = false;
  trainer::Iso9283PlanOptions iso;
};

/// "a, b, c": the joints' names.
std::string jointNames(const KinematicChain& chain) {
  std::string names;
  for (const ChainJoint& j : chain.joints()) names += (names.empty() ? "" : ", ") + j.name;
  return names;
}

// The unloaded fit rows of a campaign (one per pose_id) as the candidates of a plan for chain,
// and the tracker noise it states (weighing position against rotation), if it does.
std::vector<PlannedMeasurement> measuredPoses(const std::string& dir, const KinematicChain& chain,
                                              trainer::PlanOptions& options) {
  const Campaign campaign = readCampaign(dir);
  if (campaign.tracker.stated) {
    options.position_sigma_m = campaign.tracker.position_sigma_m;
    options.orientation_sigma_rad = campaign.tracker.orientation_sigma_rad;
  }
  const KinematicChain measured = chainFromUrdf(campaign.urdf_xml, campaign.base_link,
                                                campaign.tip_link, {}, campaign.robot_file);
  if (jointNames(measured) != jointNames(chain)) {
    throw InputError("--candidates-from: the campaign's joints (" + jointNames(measured) +
                         ") are not the planned robot's (" + jointNames(chain) +
                         "); expected a campaign of the robot planned for",
                     dir);
  }
  std::vector<PlannedMeasurement> poses;
  std::set<std::string> seen;
  for (const Measurement& row : campaign.rows) {
    if (row.set == RowSet::kValidation || row.load_kg != 0.0) continue;
    if (seen.insert(row.pose_id).second) poses.push_back({row.pose_id, 0.0, row.q_rad, row.source_line});
  }
  if (poses.empty()) {
    throw InputError("--candidates-from: no unloaded fit rows; expected measured poses to "
                     "choose from (rows of set geometry, stiffness or residual at 0 kg)",
                     dir);
  }
  return poses;
}

// Writes the pose list, creating its folder first (a plan is often the first thing written).
void writePlannedRows(const std::vector<PlannedMeasurement>& rows, const std::string& path) {
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  std::error_code ignored;  // writePoseList names the file when its folder cannot be made
  if (!folder.empty()) std::filesystem::create_directories(folder, ignored);
  writePoseList(rows, path);
}

// The test of ISO 9283 for the robot (trainer/iso9283_plan.hpp), written as a pose list.
void runIsoPlan(const PlanArgs& a) {
  const Robot robot = resolveRobot(a.robot);
  if (a.iso.rated_load_kg > 0.0 && robot.sensor_link.empty()) {
    throw InputError("--rated-load-kg " + std::to_string(a.iso.rated_load_kg) + ", but " +
                     robot.urdf_path + " has no F/T sensor link ('" + kDefaultSensorLink +
                     "'); expected --rated-load-kg 0 (unloaded test), or --sensor-link LINK: the "
                     "link the test load hangs from");
  }
  std::vector<std::string> attached;
  if (!robot.sensor_link.empty()) attached.push_back(robot.sensor_link);
  const KinematicChain chain =
      chainFromUrdfFile(robot.urdf_path, robot.base_link, robot.tip_link, attached);
  trainer::Iso9283PlanOptions options = a.iso;
  options.seed = a.options.seed;
  const trainer::Iso9283Plan plan = trainer::planIso9283(chain, options);
  writePlannedRows(plan.rows, a.out);
  std::cerr << "wrote " << a.out << "\n";
  std::cout << report::formatIsoPlan(plan);
}

void writePlan(const trainer::CampaignPlan& plan, const PlanArgs& a) {
  writePlannedRows(plan.rows, a.out);
  std::cerr << "wrote " << a.out << "\n";
  std::cout << report::formatPlan(plan, a.options);
}

// The re-check's plan of a stored model (`--recheck MODEL`): its robot as the controller knows it
// (nominal_Base, its sensor frame), unloaded unless --loads says otherwise.
void runRecheckPlan(PlanArgs a) {
  const CalibratedModel model = readModelFile(a.recheck_model);
  a.options.recheck = true;
  a.options.loads_kg = a.loads_kg.empty() ? std::vector<double>{0.0} : a.loads_kg;
  const bool loaded = std::any_of(a.options.loads_kg.begin(), a.options.loads_kg.end(),
                                  [](double load_kg) { return load_kg != 0.0; });
  if (loaded && model.sensor_frame < 0) {
    throw InputError("--loads with payloads, but the model has no sensor frame; expected --loads 0",
                     a.recheck_model);
  }
  if (!a.payload_cog_m.empty()) a.options.p_CoGInSensor_m = payloadCoG(a.payload_cog_m);
  if (model.gravity_Base.norm() > 0.0) a.options.gravity_in_base_m_per_s2 = model.gravity_Base;
  if (!a.candidates_from.empty()) {
    a.options.given_candidates = measuredPoses(a.candidates_from, model.nominal_Base, a.options);
  }
  writePlan(trainer::planCampaign(model.nominal_Base, model.sensor_frame, a.options), a);
}

// Plans a campaign (trainer/plan.hpp), writes its pose list and says what was found.
void runPlan(PlanArgs a) {
  if (a.iso9283) {
    runIsoPlan(a);
    return;
  }
  if (!a.poses_given) {
    throw InputError("--poses is missing; expected the number of poses to plan (hint: --poses "
                     "60), or --iso9283 for the standard's test");
  }
  if (a.selection == "random") {
    a.options.selection = trainer::PoseSelection::kRandom;
  } else if (a.selection != "d-optimal") {
    throw InputError("--selection '" + a.selection +
                     "'; expected 'd-optimal' or 'random' (hint: random is the baseline a plan is "
                     "compared with)");
  }
  if (a.tracker_m.size() != 3) {
    throw InputError("--tracker has " + std::to_string(a.tracker_m.size()) +
                     " values; expected x,y,z of the tracker head in base_link, m (hint: "
                     "--tracker 4,0,1.2)");
  }
  a.options.p_TrackerInBase_m = Vec3(a.tracker_m[0], a.tracker_m[1], a.tracker_m[2]);
  if (!a.recheck_model.empty()) return runRecheckPlan(std::move(a));
  const Robot robot = resolveRobot(a.robot);
  const bool sensor = !robot.sensor_link.empty();
  if (a.loads_kg.empty()) {
    a.options.loads_kg = sensor ? std::vector<double>{0.0, 20.0, 40.0} : std::vector<double>{0.0};
  } else {
    a.options.loads_kg = a.loads_kg;
  }
  const bool loaded = std::any_of(a.options.loads_kg.begin(), a.options.loads_kg.end(),
                                  [](double load_kg) { return load_kg != 0.0; });
  if (loaded && !sensor) {
    throw InputError("--loads with payloads, but " + robot.urdf_path +
                     " has no F/T sensor link ('" + kDefaultSensorLink +
                     "'); expected --loads 0, or --sensor-link LINK: the F/T sensor's, or the "
                     "link a payload of known mass hangs from, with its --payload-cog");
  }
  if (!a.payload_cog_m.empty()) a.options.p_CoGInSensor_m = payloadCoG(a.payload_cog_m);
  for (const int joint : a.off_axis_joints) a.options.off_axis_joints.push_back(joint - 1);
  std::vector<std::string> attached;
  if (sensor) attached.push_back(robot.sensor_link);
  const KinematicChain chain =
      chainFromUrdfFile(robot.urdf_path, robot.base_link, robot.tip_link, attached);
  if (!a.candidates_from.empty()) {
    a.options.given_candidates = measuredPoses(a.candidates_from, chain, a.options);
  }
  writePlan(trainer::planCampaign(chain, sensor ? 0 : -1, a.options), a);
}

}  // namespace

Subcommand addPlanCommand(CLI::App& app) {
  auto args = std::make_shared<PlanArgs>();
  PlanArgs& plan_args = *args;
  CLI::App* plan = app.add_subcommand(
      "plan", "choose the poses of a campaign, each measured at the given loads: D-optimal for geometry and "
              "compliance, spread over every joint's range, visible to the tracker");
  addRobotOptions(plan, plan_args.robot);
  CLI::Option* poses =
      plan->add_option("--poses", plan_args.options.poses, "number of poses N (not with --iso9283)");
  CLI::Option* iso = plan->add_flag(
      "--iso9283", plan_args.iso9283,
      "lay out the test of ISO 9283 instead: the largest cube the robot reaches with one tool "
      "orientation, its poses P1-P5 in its diagonal plane, cycles, approach directions along "
      "+x/+y/+z for P1, P2, P4, loads unloaded, 10 % of rated and rated (docs/certify.md)");
  poses->excludes(iso);
  plan->add_option("--rated-load-kg", plan_args.iso.rated_load_kg,
                   "with --iso9283: the robot's rated payload, kg (0: unloaded test only)")
      ->needs(iso)->capture_default_str();
  plan->add_option("--cycles", plan_args.iso.cycles,
                   "with --iso9283: cycles per pose and approach direction (the standard's 30)")
      ->needs(iso)->capture_default_str();
  plan->add_option("--iso-candidates", plan_args.iso.centre_candidates,
                   "with --iso9283: joint configurations drawn as candidate cube centres")
      ->needs(iso)->capture_default_str();
  plan->add_option("--loads", plan_args.loads_kg,
                   "payloads every pose is measured at, kg, with 0 (default: 0,20,40 with a "
                   "sensor link, else 0)")
      ->delimiter(',');
  plan->add_option("--payload-cog", plan_args.payload_cog_m,
                   "payload's centre of gravity in the sensor link, x,y,z, m (default 0,0,0)")
      ->delimiter(',');
  plan->add_option("--candidates-from", plan_args.candidates_from,
                   "choose among the measured poses of this campaign (its unloaded fit rows, "
                   "pose_ids kept; weighed by its stated tracker noise) instead of drawing "
                   "candidates");
  plan->add_option("--recheck", plan_args.recheck_model,
                   "plan the re-check of this model (stepcal recheck; about twenty poses: "
                   "--poses 20): poses that see the registration, the tool and each inner "
                   "joint's zero; its robot replaces --robot, unloaded unless --loads");
  plan->add_option("--tracker", plan_args.tracker_m, "tracker head in base_link: x,y,z, m")
      ->delimiter(',')->capture_default_str();
  plan->add_option("--min-range-m", plan_args.options.min_range_m, "nearest tip distance, m")
      ->capture_default_str();
  plan->add_option("--max-range-m", plan_args.options.max_range_m, "farthest tip distance, m")
      ->capture_default_str();
  plan->add_option("--clearance-m", plan_args.options.line_of_sight_clearance_m,
                   "line of sight to the arm's link polyline, at least, m")->capture_default_str();
  plan->add_option("--candidates", plan_args.options.candidates, "candidate poses drawn")
      ->capture_default_str();
  plan->add_option("--seed", plan_args.options.seed, "random seed of the candidates")
      ->capture_default_str();
  plan->add_option("--selection", plan_args.selection, "d-optimal | random")->capture_default_str();
  plan->add_option("--off-axis-joints", plan_args.off_axis_joints,
                   "joints (1-based) whose compliance across the axis (off_axis_compliance: "
                   "bearing tilt, link bending) the poses should also identify, e.g. 1,2")
      ->delimiter(',');
  plan->add_flag("--tool-mount", plan_args.options.tool_mount,
                 "the poses should also identify the tool mount's compliance along the sensor's "
                 "axes (tool_mount_compliance)");
  plan->add_option("--out", plan_args.out, "pose list to write (poses.csv)")->required();
  return {plan, [args, poses] {
            args->poses_given = poses->count() > 0;
            runPlan(*args);
          }};
}

}  // namespace stepcal::cli
