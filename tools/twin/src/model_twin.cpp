#include "stepcal/twin/model_twin.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "random.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms/sensor_bias.hpp"
#include "stepcal/common/model_robot.hpp"

namespace stepcal::twin {
namespace {

constexpr char kFormat[] = "stepcal-model-twin/1";
// The payload's reading and the deflection it causes agree to this relative change; the sensor
// turns by ~1e-3 rad under a payload, so a few passes get there.
constexpr double kReadingTolerance = 1e-13;
constexpr int kMaxReadingPasses = 20;

Vec6 sensorBias(const PhysicalModel& model) {
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kSensorBias) return view<mechanism::SensorBias>(m).wrench();
  }
  return Vec6::Zero();
}

double sigmaOrStated(const std::optional<double>& given, double stated, bool is_stated,
                     const std::string& what, const std::string& campaign) {
  if (given) {
    if (!(std::isfinite(*given) && *given >= 0.0)) {
      throw InputError("tracker " + what + " noise " + std::to_string(*given) +
                       "; expected a finite 1-sigma >= 0");
    }
    return *given;
  }
  if (!is_stated) {
    throw InputError("the campaign states no tracker noise; expected its tracker block "
                     "(campaign.yaml) or the noise given (hint: stepcal simulate "
                     "--tracker-position-sigma-mm and --tracker-orientation-sigma-deg)",
                     campaign);
  }
  return stated;
}

// Refuses a model of another robot than the campaign's (model_robot.hpp), or one that cannot
// apply the campaign's loads.
void requireSameRobot(const CalibratedModel& model, const Campaign& campaign,
                      const std::string& model_path) {
  requireCampaignOfModelRobot(model, campaign, model_path);
  bool loaded = false;
  for (const Measurement& row : campaign.rows) loaded = loaded || row.load_kg != 0.0;
  if (loaded && model.sensor_frame < 0) {
    throw InputError("the campaign has loaded rows but the model no F/T sensor frame to apply "
                     "their wrench at; expected a model calibrated with the campaign's sensor",
                     model_path);
  }
}

}  // namespace

namespace {

PhysicalModel withAdded(PhysicalModel physical, const std::vector<Mechanism>& added) {
  for (const Mechanism& m : added) {
    const std::string problem = mechanismProblem(m, physical.chain_Tracker.dof());
    if (!problem.empty()) throw InputError("added " + describe(m) + ": " + problem);
    for (const Mechanism& own : physical.mechanisms) {
      if (own.kind == m.kind && own.joint == m.joint) {
        throw InputError("added " + describe(m) + ": the model holds one already; expected a " +
                         "joint without one");
      }
    }
    physical.mechanisms.push_back(m);
  }
  return physical;
}

/// The options' off_axis_compliance entries and tool mount as mechanisms.
std::vector<Mechanism> addedMechanisms(const ModelTwinOptions& options) {
  std::vector<Mechanism> added;
  for (const auto& [joint, compliance] : options.off_axis_compliance) {
    Mechanism m;
    m.kind = MechanismKind::kOffAxisCompliance;
    m.joint = joint;
    m.parameters = {compliance, compliance};
    m.sigma = {0.0, 0.0};
    added.push_back(std::move(m));
  }
  if (options.tool_mount_compliance_m_per_n != 0.0) {  // a negative one is refused (withAdded)
    Mechanism m;
    m.kind = MechanismKind::kToolMountCompliance;
    m.parameters = {0.0, 0.0, options.tool_mount_compliance_m_per_n};
    m.sigma = {0.0, 0.0, 0.0};
    added.push_back(std::move(m));
  }
  return added;
}

}  // namespace

ModelTwin::ModelTwin(const CalibratedModel& model, const std::vector<Mechanism>& added)
    : physical_(withAdded(physicalModelOf(model), added)),
      constants_(physicalConstants(physical_)) {}

Pose ModelTwin::X_TrackerTip(const JointVector& q_cmd_rad, const Vec6& wrench_Sensor,
                             double temp_c) const {
  ChainWorkspace ws;
  JointVector theta, tau;
  const bool sizes = physicalLinkAngles(physical_, q_cmd_rad, wrench_Sensor, temp_c,
                                        {ws, theta, tau}, {&constants_});
  STEPCAL_INVARIANT(sizes, "one commanded angle per joint of the model");
  return tipPose(ws);
}

Vec6 ModelTwin::payloadReading(const JointVector& q_cmd_rad, double load_kg,
                               const Vec3& p_CoGInSensor_m, double temp_c) const {
  STEPCAL_INVARIANT(physical_.sensor_frame >= 0, "a payload needs the model's sensor frame");
  const Vec6 bias = sensorBias(physical_);
  const Vec3 weight_Tracker = load_kg * physical_.gravity_Tracker;
  Vec6 wrench = Vec6::Zero();  // the payload's, sensor axes, about the sensor origin
  ChainWorkspace ws;
  JointVector theta, tau;
  for (int pass = 0; pass < kMaxReadingPasses; ++pass) {
    physicalLinkAngles(physical_, q_cmd_rad, wrench + bias, temp_c, {ws, theta, tau}, {&constants_});
    const Mat3 R_TrackerSensor =
        framePose(physical_.chain_Tracker, ws, physical_.sensor_frame).linear();
    Vec6 next;
    next.head<3>() = R_TrackerSensor.transpose() * weight_Tracker;
    next.tail<3>() = p_CoGInSensor_m.cross(next.head<3>());
    const double change = (next - wrench).norm();
    wrench = next;
    if (change <= kReadingTolerance * (1.0 + wrench.norm())) return wrench + bias;
  }
  STEPCAL_INVARIANT(false, "the payload's reading converges (the arm turns the sensor ~1e-3 rad)");
  return wrench + bias;
}

namespace {

/// The campaign the twin takes its robot, noise and rows from: the given one, else the model's
/// own (its provenance), which must be there.
std::string campaignDirOf(const ModelTwinOptions& options, const CalibratedModel& model) {
  std::string dir = options.campaign_dir;
  if (dir.empty()) {
    dir = model.provenance.campaign_path;
    if (dir.empty() || !std::filesystem::exists(dir)) {
      throw InputError("the model's campaign '" + dir + "' (from its provenance) is not there; "
                       "expected the campaign whose robot description, tracker noise and rows "
                       "the twin takes (hint: stepcal simulate --model MODEL --campaign DIR)",
                       options.model_path);
    }
  }
  return dir;
}

void requireValidFtNoise(const ModelTwinOptions& options) {
  if (!(std::isfinite(options.ft_force_sigma_n) && options.ft_force_sigma_n >= 0.0 &&
        std::isfinite(options.ft_moment_sigma_nm) && options.ft_moment_sigma_nm >= 0.0 &&
        options.p_CoGInSensor_m.allFinite())) {
    throw InputError("F/T noise " + std::to_string(options.ft_force_sigma_n) + " N, " +
                     std::to_string(options.ft_moment_sigma_nm) +
                     " N·m or the payload's centre of gravity; expected finite values, noise >= 0");
  }
}

/// A campaign of the source's robot, sensor, flange and gravity, with the twin's tracker noise;
/// no rows yet.
Campaign campaignLike(const Campaign& source, double sigma_p_m, double sigma_r_rad) {
  Campaign campaign;
  campaign.urdf_xml = source.urdf_xml;
  campaign.base_link = source.base_link;
  campaign.tip_link = source.tip_link;
  campaign.sensor_link = source.sensor_link;
  campaign.flange_link = source.flange_link;
  campaign.tracker.position_sigma_m = sigma_p_m;
  campaign.tracker.orientation_sigma_rad = sigma_r_rad;
  campaign.tracker.stated = sigma_p_m > 0.0 && sigma_r_rad > 0.0;
  campaign.gravity_in_base = source.gravity_in_base;
  campaign.joint_count = source.joint_count;
  return campaign;
}

/// The plan's rows, to be measured as the campaign measured its own: at its mean temperature,
/// with orientation if it has any, with the wrench wherever the model has a sensor.
std::vector<Measurement> plannedRows(const ModelTwinOptions& options,
                                     const CalibratedModel& model, const Campaign& source) {
  double temp_sum = 0.0;
  int temps = 0;
  bool orientation = false;
  for (const Measurement& row : source.rows) {
    if (row.temp_c) {
      temp_sum += *row.temp_c;
      ++temps;
    }
    orientation = orientation || row.has_orientation;
  }
  const bool sensor = model.sensor_frame >= 0 && !source.sensor_link.empty();
  std::vector<Measurement> rows;
  for (const PlannedMeasurement& planned : options.planned_fit_rows) {
    if (planned.q_rad.size() != source.joint_count) {
      throw InputError("a planned row has " + std::to_string(planned.q_rad.size()) +
                           " joint angles; expected " + std::to_string(source.joint_count) +
                           " (hint: plan with the robot of the model)",
                       "poses", planned.source_line);
    }
    if (planned.load_kg != 0.0 && !sensor) {
      throw InputError("pose '" + planned.pose_id + "' at " + std::to_string(planned.load_kg) +
                           " kg, but the model has no F/T sensor frame; expected unloaded rows "
                           "only (a payload's wrench is read at the sensor)",
                       "poses", planned.source_line);
    }
    Measurement m;
    m.pose_id = planned.pose_id;
    m.set = planned.load_kg == 0.0 ? RowSet::kGeometry : RowSet::kStiffness;
    m.load_kg = planned.load_kg;
    m.q_rad = planned.q_rad;
    m.has_wrench = sensor;  // a mounted sensor reads every row, unloaded ones too
    m.has_orientation = orientation;
    // Measured at the campaign's mean temperature, unknown if it recorded none.
    if (temps > 0) m.temp_c = temp_sum / temps;
    rows.push_back(std::move(m));
  }
  return rows;
}

/// The rows to measure: the campaign's, or the plan's and then the campaign's validation rows.
std::vector<Measurement> rowsToMeasure(const ModelTwinOptions& options,
                                       const CalibratedModel& model, const Campaign& source) {
  if (options.planned_fit_rows.empty()) return source.rows;
  std::vector<Measurement> rows = plannedRows(options, model, source);
  for (const Measurement& row : source.rows) {
    if (row.set == RowSet::kValidation) rows.push_back(row);
  }
  return rows;
}

/// Each row measured on the twin: the planned rows' wrench read (the payload's, with noise),
/// the tip with the tracker's noise; sequence numbers for a plan's rows.
void measureRows(const ModelTwin& robot, const ModelTwinOptions& options, double sigma_p_m,
                 double sigma_r_rad, std::vector<Measurement>& rows) {
  const bool has_plan = !options.planned_fit_rows.empty();
  Rng noise_rng(options.seed, Stream::kModelTwinNoise);
  const size_t planned_rows = has_plan ? options.planned_fit_rows.size() : 0;
  int64_t seq = 1;
  for (size_t i = 0; i < rows.size(); ++i) {
    Measurement& m = rows[i];
    const bool planned = i < planned_rows;
    if (has_plan) m.seq = seq++;
    const double temp_c = m.temp_c ? *m.temp_c : std::numeric_limits<double>::quiet_NaN();
    // Every draw happens whatever the row, so a row's noise does not depend on the others'.
    const Vec3 dp = noise_rng.normal3(sigma_p_m);
    const Vec3 dr = noise_rng.normal3(sigma_r_rad);
    const Vec3 df = noise_rng.normal3(options.ft_force_sigma_n);
    const Vec3 dm = noise_rng.normal3(options.ft_moment_sigma_nm);
    if (planned && m.has_wrench) {
      m.wrench_Sensor =
          robot.payloadReading(m.q_rad, m.load_kg, options.p_CoGInSensor_m, temp_c);
      m.wrench_Sensor.head<3>() += df;
      m.wrench_Sensor.tail<3>() += dm;
    }
    // The physical model's input is the reading, bias and noise included, as the runtime's is.
    const Pose X_TrackerTip = robot.X_TrackerTip(m.q_rad, m.wrenchOrZero(), temp_c);
    m.p_TipInTracker_m = X_TrackerTip.translation() + dp;
    if (m.has_orientation) {
      Eigen::Quaterniond quat(lie::expSO3(dr) * X_TrackerTip.linear());
      quat.normalize();
      if (quat.w() < 0.0) quat.coeffs() = -quat.coeffs();
      m.q_TrackerTip = quat;
    }
    m.extra.clear();  // the real campaign's own columns say nothing of the twin's rows
    m.source_line = 0;
  }
}

/// truth.json: what the twin was and how it measured.
nlohmann::json truthOf(const ModelTwinOptions& options, const CalibratedModel& model,
                       const ModelTwin& robot, const std::string& dir, double sigma_p_m,
                       double sigma_r_rad) {
  nlohmann::json mechanisms = nlohmann::json::array();
  for (const Mechanism& m : model.mechanisms) mechanisms.push_back(describe(m));
  nlohmann::json added = nlohmann::json::array();
  for (const auto& [joint, compliance] : options.off_axis_compliance) {
    added.push_back({{"name", "off_axis_compliance"},
                     {"joint", joint + 1},
                     {"compliance_rad_per_nm", compliance}});
  }
  if (options.tool_mount_compliance_m_per_n != 0.0) {
    added.push_back({{"name", "tool_mount_compliance"},
                     {"compliance_m_per_n", options.tool_mount_compliance_m_per_n}});
  }
  return {
      {"format", kFormat},
      {"model_path", options.model_path},
      {"model_campaign_hash", model.provenance.campaign_hash},
      {"campaign_dir", dir},
      {"seed", options.seed},
      {"planned_fit_rows", options.planned_fit_rows.size()},
      {"noise",
       {{"tracker_position_sigma_m", sigma_p_m},
        {"tracker_orientation_sigma_rad", sigma_r_rad},
        {"ft_force_sigma_n", options.ft_force_sigma_n},
        {"ft_moment_sigma_nm", options.ft_moment_sigma_nm}}},
      {"p_CoGInSensor_m",
       {options.p_CoGInSensor_m.x(), options.p_CoGInSensor_m.y(), options.p_CoGInSensor_m.z()}},
      {"compliance_rad_per_nm",
       std::vector<double>(robot.physical().compliance_rad_per_nm.data(),
                           robot.physical().compliance_rad_per_nm.data() +
                               robot.physical().compliance_rad_per_nm.size())},
      {"mechanisms", mechanisms},
      {"added_mechanisms", added},
  };
}

}  // namespace

Campaign simulateFromModel(const ModelTwinOptions& options, nlohmann::json* truth_out) {
  const CalibratedModel model = readModelFile(options.model_path);
  const std::string dir = campaignDirOf(options, model);
  const Campaign source = readCampaign(dir);
  requireSameRobot(model, source, options.model_path);
  const double sigma_p_m =
      sigmaOrStated(options.tracker_position_sigma_m, source.tracker.position_sigma_m,
                    source.tracker.stated, "position", dir);
  const double sigma_r_rad =
      sigmaOrStated(options.tracker_orientation_sigma_rad, source.tracker.orientation_sigma_rad,
                    source.tracker.stated, "orientation", dir);
  requireValidFtNoise(options);
  const ModelTwin robot(model, addedMechanisms(options));

  Campaign campaign = campaignLike(source, sigma_p_m, sigma_r_rad);
  std::vector<Measurement> rows = rowsToMeasure(options, model, source);
  measureRows(robot, options, sigma_p_m, sigma_r_rad, rows);
  campaign.rows = std::move(rows);
  if (truth_out != nullptr) {
    *truth_out = truthOf(options, model, robot, dir, sigma_p_m, sigma_r_rad);
  }
  return campaign;
}

void writeModelSimulation(const ModelTwinOptions& options, const std::string& out_dir) {
  nlohmann::json truth;
  const Campaign campaign = simulateFromModel(options, &truth);
  writeCampaign(campaign, out_dir);
  const std::string path = out_dir + "/truth.json";
  std::ofstream out(path);
  out << truth.dump(2) << '\n';
  if (!out) throw InputError("cannot write the truth file", path);
}

}  // namespace stepcal::twin
