// stepcal: the offline command line. Every subcommand reads and writes campaign folders
// (campaign-format.md); errors in the user's input end with exit status 2 and one clear line.
#include <CLI/CLI.hpp>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iostream>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "correct.hpp"
#include "diagnosis_report.hpp"
#include "report.hpp"
#include "report_html.hpp"
#include "stepcal/common/atomic_file.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/robots.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/common/urdf_export.hpp"
#include "stepcal/importers/ipa.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/validate.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/trainer/plan.hpp"
#include "stepcal/twin/model_twin.hpp"
#include "stepcal/twin/twin.hpp"

namespace {

using namespace stepcal;

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
constexpr const char* kNoSensor = "none";

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

/// "irb4400, ur10": the shipped robots found, for --robot's help.
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

/// x,y,z in metres from a --payload-cog value.
Vec3 payloadCoG(const std::vector<double>& xyz) {
  if (xyz.size() != 3) {
    throw InputError("--payload-cog has " + std::to_string(xyz.size()) +
                     " values; expected x,y,z of the payload's centre of gravity in the sensor "
                     "link, m (hint: --payload-cog 0.03,-0.02,0.15)");
  }
  return Vec3(xyz[0], xyz[1], xyz[2]);
}

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
};

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
  if (!a.poses.empty()) {
    options.planned_fit_rows =
        readPoseList(a.poses, readModelFile(a.model).chain_Tracker.dof());
  }
  twin::writeModelSimulation(options, a.out);
}

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

struct PlanArgs {
  RobotArgs robot;
  std::vector<double> loads_kg;  ///< empty: 0,20,40 with a sensor link, else 0
  std::vector<double> payload_cog_m;
  std::string candidates_from;  ///< a campaign whose measured poses are the candidates
  std::string selection = "d-optimal";
  std::vector<double> tracker_m = {4.0, 0.0, 1.2};
  std::string out;
  trainer::PlanOptions options;
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

// Plans a campaign (trainer/plan.hpp), writes its pose list and says what was found.
void runPlan(PlanArgs a) {
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
  std::vector<std::string> attached;
  if (sensor) attached.push_back(robot.sensor_link);
  const KinematicChain chain =
      chainFromUrdfFile(robot.urdf_path, robot.base_link, robot.tip_link, attached);
  if (!a.candidates_from.empty()) {
    a.options.given_candidates = measuredPoses(a.candidates_from, chain, a.options);
  }
  const trainer::CampaignPlan plan = trainer::planCampaign(chain, sensor ? 0 : -1, a.options);
  writePoseList(plan.rows, a.out);
  std::cerr << "wrote " << a.out << "\n";
  std::cout << cli::formatPlan(plan, a.options);
}

// SIGINT and SIGTERM end a calibration or diagnosis at once (the trainer has no point to stop
// at) by the signal, after one line on stderr saying which output files are as they were. Files
// are written with the signals held (SignalsHeldForWriting) until the line is updated, so it is
// always true: an output is either untouched or completely replaced.
class InterruptNotice {
 public:
  explicit InterruptNotice(std::vector<std::string> outputs) : unchanged_(std::move(outputs)) {
    publish();
    struct sigaction action {};
    action.sa_handler = onSignal;
    action.sa_flags = SA_RESETHAND;  // the raise in onSignal then ends the process
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
  }
  ~InterruptNotice() {
    ::signal(SIGINT, SIG_DFL);
    ::signal(SIGTERM, SIG_DFL);
    line_.store("");
  }
  InterruptNotice(const InterruptNotice&) = delete;
  InterruptNotice& operator=(const InterruptNotice&) = delete;

  /// Writes one output with the signals held, and the line then counts it as written.
  template <typename Write>
  void write(const std::string& path, const std::string& what, Write&& write_file) {
    const SignalsHeldForWriting held;
    write_file();
    std::cerr << "wrote " << what << " " << path << "\n";
    unchanged_.erase(std::find(unchanged_.begin(), unchanged_.end(), path));
    written_.push_back(path);
    publish();
  }

 private:
  static std::string listed(const std::vector<std::string>& paths) {
    std::string out;
    for (size_t i = 0; i < paths.size(); ++i) {
      out += (i == 0 ? "" : i + 1 == paths.size() ? " and " : ", ") + paths[i];
    }
    return out;
  }

  void publish() {
    std::string line = "stepcal: interrupted";
    if (!written_.empty()) line += "; wrote " + listed(written_);
    if (!unchanged_.empty()) line += "; " + listed(unchanged_) + " unchanged";
    // Every line stays alive: the handler may be printing the previous one.
    lines_.push_back(line + "\n");
    line_.store(lines_.back().c_str());
  }

  static void onSignal(int signal) {
    const char* line = line_.load();
    const ssize_t ignored = ::write(STDERR_FILENO, line, std::strlen(line));
    (void)ignored;  // nothing left to tell if stderr is gone
    ::raise(signal);
  }

  static inline std::atomic<const char*> line_{""};
  std::vector<std::string> unchanged_;
  std::vector<std::string> written_;
  std::deque<std::string> lines_;
};

/// The output files given (the empty ones are not asked for).
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

/// The calibration's options with the GPR's training set capped at gpr_points (--gpr-points).
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

// One campaign, or several of one robot fitted together (mergeCampaigns): the first one's
// tracker frame and tool are the model's.
void runCalibrate(const std::vector<std::string>& dirs, const std::string& model_out,
                  const std::string& report_out, bool json, int gpr_points) {
  const trainer::CalibrationOptions options = calibrationOptions(gpr_points);
  InterruptNotice notice(outputs({report_out, model_out}));
  std::vector<Campaign> campaigns;
  for (const std::string& dir : dirs) campaigns.push_back(readCampaign(dir));
  const Campaign campaign = mergeCampaigns(std::move(campaigns));
  const trainer::CalibrationOutcome outcome = trainer::calibrateCampaign(campaign, options);
  if (!report_out.empty()) {
    notice.write(report_out, "report",
                 [&] { writeReport(report_out, cli::htmlReport(campaign, outcome)); });
  }
  if (!model_out.empty()) {
    notice.write(model_out, "model", [&] {
      writeModelFile(trainer::modelFromOutcome(campaign, outcome), model_out);
    });
  }
  if (json) {
    std::cout << cli::reportJson(campaign, outcome).dump(2) << "\n";
  } else {
    std::cout << cli::formatReport(campaign, outcome);
  }
}

// Accuracy of every layer of a model file (chain, + compliance and mechanisms, + GPR) on a
// campaign's rows, all of them and those every transmission profile covers. With refit_frames,
// the tracker and tool frames are fitted again on the campaign's rows by each layer's model
// (validate.hpp): for a campaign measured with the tracker or the target moved.
void runValidate(const std::string& model_path, const std::string& dir, bool refit_frames,
                 const std::string& covered_by, bool json) {
  const CalibratedModel model = readModelFile(model_path);
  const Campaign campaign = readCampaign(dir);
  if (campaign.joint_count != model.chain_Tracker.dof()) {
    throw InputError("campaign has " + std::to_string(campaign.joint_count) +
                         " joints, the model " + std::to_string(model.chain_Tracker.dof()),
                     dir);
  }
  std::optional<CalibratedModel> covering;
  if (!covered_by.empty()) covering = readModelFile(covered_by);
  const trainer::ValidationResult v =
      trainer::validateModel(model, campaign, refit_frames, covering ? &*covering : nullptr);
  std::vector<trainer::AccuracySummary> summaries = v.all;
  summaries.insert(summaries.end(), v.covered.begin(), v.covered.end());
  if (json) {
    std::cout << cli::accuracyJson(summaries).dump(2) << "\n";
  } else {
    std::cout << "model " << model_path << " (campaign " << model.provenance.campaign_path
              << ") on " << dir << ": " << v.rows << " rows";
    if (!v.covered.empty() || v.covered_rows > 0 || covering) {
      std::cout << ", " << v.covered_rows << " inside every transmission profile's coverage";
    }
    std::cout << "\n" << cli::formatAccuracyTable(summaries);
  }
}

// Diagnosis of a campaign against its calibrated physical model (calibrated here, or the given
// model file): the named causes, the extended model (written with --out) and its gain.
// Several campaigns: one robot from several tracker stations, diagnosed together (diagnose.hpp).
void runDiagnose(const std::vector<std::string>& dirs, const std::string& model_path,
                 const std::string& model_out, const std::string& report_out, bool json,
                 int gpr_points) {
  trainer::DiagnoseOptions options;
  options.calibration = calibrationOptions(gpr_points);
  InterruptNotice notice(outputs({report_out, model_out}));
  std::vector<Campaign> campaigns;
  for (const std::string& dir : dirs) campaigns.push_back(readCampaign(dir));
  const Campaign campaign = mergeCampaigns(std::move(campaigns));
  const auto start = std::chrono::steady_clock::now();
  CalibratedModel model;
  if (model_path.empty()) {
    model = trainer::modelFromOutcome(campaign,
                                      trainer::calibrateCampaign(campaign, options.calibration));
  } else {
    model = readModelFile(model_path);
  }
  const double seconds_calibrate =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const trainer::Diagnosis diagnosis = trainer::diagnose(campaign, model, options);
  if (!report_out.empty()) {
    notice.write(report_out, "report",
                 [&] { writeReport(report_out, cli::diagnosisHtml(campaign, diagnosis)); });
  }
  if (!model_out.empty()) {
    notice.write(model_out, "model", [&] { writeModelFile(diagnosis.extended_model, model_out); });
  }
  if (json) {
    std::cout << cli::diagnosisJson(diagnosis, seconds_calibrate).dump(2) << "\n";
  } else {
    std::cout << cli::formatDiagnosis(diagnosis, seconds_calibrate);
  }
}

// The model's chain as the robot's URDF (urdf_export.hpp), then what a URDF-only user gets
// against the full runtime: the model's validation figures of its poe layer and its last one.
void runExportUrdf(const std::string& model_path, const std::string& campaign_dir,
                   const std::string& out) {
  const CalibratedModel model = readModelFile(model_path);
  std::string dir = campaign_dir;
  if (dir.empty()) {
    dir = model.provenance.campaign_path;
    if (dir.empty() || !std::filesystem::exists(dir)) {
      throw InputError("the model's campaign '" + dir + "' (from its provenance) is not there; "
                       "expected the campaign it was calibrated on, for its robot.urdf, base_link "
                       "and tip_link; hint: pass --campaign DIR",
                       model_path);
    }
  }
  const Campaign campaign = readCampaign(dir);
  const RobotDescription robot{campaign.urdf_xml, campaign.base_link, campaign.tip_link,
                               campaign.directory + "/" + campaign.robot_file};
  const CalibratedUrdf urdf = calibratedUrdf(model, model_path, robot);
  writeFileAtomically(out, urdf.urdf_xml.data(), urdf.urdf_xml.size(), "URDF");
  std::cerr << "wrote " << out << "\n";

  std::cout << "calibrated URDF of " << robot.source << " (" << robot.base_link << " -> "
            << robot.tip_link << ", " << model.chain_Tracker.dof() << " joints): link '"
            << kUrdfWorldLink << "' is the tracker frame, link '" << kUrdfToolLink
            << "' the calibrated " << robot.tip_link << "\n";
  if (!urdf.dropped_links.empty()) {
    std::cout << "left out, not below " << robot.base_link << ":";
    for (const std::string& link : urdf.dropped_links) std::cout << " " << link;
    std::cout << "\n";
  }
  const std::string full = trainer::modelLayers(model).back().first;
  std::cout << "a URDF carries the geometric layer (" << trainer::kMethodPoe
            << ") only; the runtime applies " << full << "\n";
  std::set<double> loads_kg;
  for (const ValidationFigure& v : model.provenance.validation) {
    if (v.method == trainer::kMethodPoe) loads_kg.insert(v.load_kg);
  }
  if (loads_kg.empty()) {
    std::cout << "the model holds no validation figures of " << trainer::kMethodPoe
              << " (its campaign had no validation rows)\n";
    return;
  }
  std::cout << "validation figures at training time (mean / max position mm, mean orientation "
               "deg):\n";
  for (const double load_kg : loads_kg) {
    for (const std::string& method : {std::string(trainer::kMethodPoe), full}) {
      for (const ValidationFigure& v : model.provenance.validation) {
        if (v.method == method && v.load_kg == load_kg) std::cout << cli::formatValidationFigure(v);
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal: stepwise calibration of heavy-duty robots (geometry, compliance, residual)"};
  app.require_subcommand(1);

  SimulateArgs sim;
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
                       "settling_rows}; joints and links 1 … n; a self_weight replaces the "
                       "URDF inertials' one")
      ->excludes(model_option);
  simulate->add_option("--poses", sim.poses,
                       "pose list (poses.csv, e.g. from stepcal plan) measured as the fit rows; "
                       "the protocol's (with --model: the campaign's) validation rows stay");
  simulate->add_option("--out", sim.out, "campaign folder to write")->required();

  PlanArgs plan_args;
  CLI::App* plan = app.add_subcommand(
      "plan", "choose the poses of a campaign, each measured at the given loads: D-optimal for geometry and "
              "compliance, spread over every joint's range, visible to the tracker");
  addRobotOptions(plan, plan_args.robot);
  plan->add_option("--poses", plan_args.options.poses, "number of poses N")->required();
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
  plan->add_option("--out", plan_args.out, "pose list to write (poses.csv)")->required();

  CLI::App* import = app.add_subcommand("import", "convert foreign measurements into a campaign");
  import->require_subcommand(1);
  std::string ipa_csv, ipa_out, ipa_robot = "ur10";
  int validation_from_row = -1;
  CLI::App* ipa = import->add_subcommand("ipa", "a series of the IPA UR10 data set (ipa-robot-accuracy)");
  ipa->add_option("csv", ipa_csv, "the series' measurements CSV")->required();
  ipa->add_option("--validation-from-row", validation_from_row,
                  "rows from N on (0-based, after the header) become set=validation");
  ipa->add_option("--robot", ipa_robot,
                  "nominal UR10 description: a URDF file or a shipped robot's name (" +
                      shippedRobotList() + ")")
      ->capture_default_str();
  ipa->add_option("--out", ipa_out, "campaign folder to write")->required();

  std::vector<std::string> campaign_dirs;
  std::string model_out;
  bool json = false;
  CLI::App* calibrate = app.add_subcommand("calibrate", "calibrate a campaign and print its accuracy tables");
  calibrate
      ->add_option("campaign", campaign_dirs,
                   "campaign folder (or its campaign.yaml); several: one robot measured in several "
                   "sessions (tracker stations, target remounted), fitted together; the model "
                   "takes the first one's tracker frame, tool and the joint frames each campaign "
                   "keeps its own: give first the campaign of the robot as it is now")
      ->required();
  calibrate->add_option("--out", model_out, "model file to write");
  calibrate->add_flag("--json", json, "print the report as JSON");
  std::string report_out;
  calibrate->add_option("--report", report_out, "HTML report with the figures to write");
  // The GPR's size trades accuracy for the runtime's call time (docs/runtime.md, "Against the
  // number of GPR points").
  int gpr_points = trainer::CalibrationOptions{}.gpr_max_points;
  const std::string gpr_points_help =
      "largest GPR training set: more residual rows are thinned evenly (the runtime's call time "
      "grows with it)";
  calibrate->add_option("--gpr-points", gpr_points, gpr_points_help)->capture_default_str();

  std::string validate_model, validate_dir;
  bool validate_json = false;
  CLI::App* validate = app.add_subcommand(
      "validate", "accuracy of a model file on another campaign's rows (e.g. fit on one series, check on another)");
  validate->add_option("model", validate_model, "model file")->required();
  validate->add_option("campaign", validate_dir, "campaign folder")->required();
  validate->add_flag("--json", validate_json, "print the table as JSON");
  bool refit_frames = false;
  validate->add_flag("--refit-frames", refit_frames,
                     "fit the tracker and tool frames again on this campaign (joint frames kept)");
  std::string covered_by;
  validate->add_option("--rows-covered-by", covered_by,
                       "count as covered the rows this other model's profiles cover (to compare "
                       "two models on the same rows)");

  std::string inspect_model;
  CLI::App* inspect = app.add_subcommand("inspect", "print what a model file holds");
  inspect->add_option("model", inspect_model, "model file")->required();

  std::string export_model, export_campaign, export_out;
  CLI::App* export_cmd =
      app.add_subcommand("export", "write a model file's contents in another format");
  export_cmd->require_subcommand(1);
  CLI::App* export_urdf = export_cmd->add_subcommand(
      "urdf", "the robot's URDF with the calibrated joint origins and axes, the tracker as link "
              "'world' and the calibrated tip as link 'tool'");
  export_urdf->add_option("model", export_model, "model file")->required();
  export_urdf->add_option("--out", export_out, "URDF file to write")->required();
  export_urdf->add_option("--campaign", export_campaign,
                          "campaign the model was calibrated on, for its robot.urdf, base_link and "
                          "tip_link (default: the model's own, from its provenance)");

  std::string demo_out = "out/demo-campaign";
  uint64_t demo_seed = 1;
  CLI::App* diagnose_cmd = app.add_subcommand(
      "diagnose", "name what the physical model gets wrong, extend it and measure the gain");
  std::vector<std::string> diagnose_dirs;
  std::string diagnose_model, diagnose_out, diagnose_report;
  bool diagnose_json = false;
  diagnose_cmd
      ->add_option("campaign", diagnose_dirs,
                   "campaign folder (or its campaign.yaml); several: one robot measured from "
                   "several tracker stations, diagnosed together, each campaign with its own "
                   "tracker and tool frames; the extended model takes the first one's")
      ->required();
  diagnose_cmd->add_option("--model", diagnose_model,
                           "model file to diagnose, in the first campaign's tracker frame "
                           "(default: calibrate the campaigns first)");
  diagnose_cmd->add_flag("--json", diagnose_json, "print the diagnosis as JSON");
  diagnose_cmd->add_option("--out", diagnose_out, "extended model file to write");
  diagnose_cmd->add_option("--report", diagnose_report, "HTML report with the plots to write");
  diagnose_cmd->add_option("--gpr-points", gpr_points,
                           gpr_points_help + ", of the calibration and of the extended model")
      ->capture_default_str();

  CLI::App* demo = app.add_subcommand(
      "demo", "the main job: simulate the paper's IRB4400 campaign, calibrate it, print the tables");
  demo->add_option("--out", demo_out, "where the simulated campaign goes")->capture_default_str();
  demo->add_option("--seed", demo_seed, "random seed of the twin")->capture_default_str();

  cli::CorrectArgs correct_args;
  CLI::App* correct = cli::addCorrectCommand(app, correct_args);

  CLI11_PARSE(app, argc, argv);
  sim.position_sigma_given = simulate->count("--tracker-position-sigma-mm") > 0;
  sim.orientation_sigma_given = simulate->count("--tracker-orientation-sigma-deg") > 0;
  try {
    if (*simulate) {
      runSimulate(sim);
      std::cerr << "wrote " << sim.out << " (campaign + truth.json)\n";
    } else if (*plan) {
      runPlan(plan_args);
    } else if (*ipa) {
      writeCampaign(importers::importIpaSeries(ipa_csv, validation_from_row,
                                               robotDescriptionPath(ipa_robot)),
                    ipa_out);
      std::cerr << "wrote " << ipa_out << "\n";
    } else if (*calibrate) {
      runCalibrate(campaign_dirs, model_out, report_out, json, gpr_points);
    } else if (*inspect) {
      const std::string bytes = readTextFile(inspect_model);
      std::cout << cli::formatModel(
          parseModel(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), inspect_model),
          bytes.size());
    } else if (*diagnose_cmd) {
      runDiagnose(diagnose_dirs, diagnose_model, diagnose_out, diagnose_report, diagnose_json,
                  gpr_points);
    } else if (*export_urdf) {
      runExportUrdf(export_model, export_campaign, export_out);
    } else if (*validate) {
      runValidate(validate_model, validate_dir, refit_frames, covered_by, validate_json);
    } else if (*correct) {
      cli::runCorrect(correct_args);
    } else if (*demo) {
      SimulateArgs paper;
      paper.seed = demo_seed;
      paper.out = demo_out;
      runSimulate(paper);
      std::cout << "simulated the paper's IRB4400 campaign (seed " << demo_seed << ") into "
                << demo_out << "\n\n";
      runCalibrate({demo_out}, demo_out + "/model.stepcal", demo_out + "/report.html", false,
                   trainer::CalibrationOptions{}.gpr_max_points);
    }
  } catch (const InputError& e) {
    std::cerr << "stepcal: error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
