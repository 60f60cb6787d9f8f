#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "internal.hpp"
#include "random.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal::twin {
namespace {

constexpr int kMaxPoseDraws = 100000;

/// Poses measured together: every pose at the first load, then every pose at the next, as in a
/// real campaign where changing the payload is the slow step.
struct Block {
  const char* pose_prefix;
  RowSet set;
  int poses;
  std::vector<double> loads_kg;
};

// The reference paper's protocol (campaign-format.md), in measurement order.
std::vector<Block> protocolBlocks(const std::string& protocol) {
  std::vector<Block> blocks = {{"geo", RowSet::kGeometry, 80, {0.0}},
                               {"geov", RowSet::kValidation, 50, {0.0}}};
  if (protocol == "paper") {
    blocks.push_back({"stf", RowSet::kStiffness, 80, {0.0, 20.0, 30.0, 40.0}});
    blocks.push_back({"stfv", RowSet::kValidation, 30, {0.0, 20.0, 30.0, 40.0}});
    blocks.push_back({"res", RowSet::kResidual, 100, {20.0, 30.0, 40.0}});
    blocks.push_back({"resv", RowSet::kValidation, 50, {20.0, 30.0, 40.0}});
    blocks.push_back({"ext", RowSet::kValidation, 50, {55.0}});
  }
  return blocks;
}

// A commanded pose: uniform in the sampling ranges (clipped to the URDF limits), redrawn until
// the nominal tip is in front of the robot and high enough. The planner knows only the nominal.
JointVector drawPose(Rng& rng, const KinematicChain& nominal, const TwinOptions& o) {
  const int n = nominal.dof();
  ChainWorkspace ws;
  JointVector q(n);
  for (int draw = 0; draw < kMaxPoseDraws; ++draw) {
    bool accepted = true;
    for (int i = 0; i < n; ++i) {
      const JointSampleRange& r = o.pose_ranges[static_cast<size_t>(i)];
      const ChainJoint& joint = nominal.joints()[static_cast<size_t>(i)];
      q(i) = rng.uniform(std::max(r.lower_rad, joint.lower_rad),
                         std::min(r.upper_rad, joint.upper_rad));
      accepted = accepted && std::abs(q(i)) >= r.min_abs_rad;
    }
    if (!accepted) continue;
    forwardKinematics(nominal, q, ws);
    const Vec3 p_TipInBase = tipPose(ws).translation();
    if (p_TipInBase.x() < o.min_tip_forward_m || p_TipInBase.z() < o.min_tip_height_m) continue;
    if (o.min_link_height_m) {
      for (int k = 2; accepted && k <= n + 1; ++k) {
        accepted = ws.X_RootFrame[static_cast<size_t>(k)].translation().z() >= *o.min_link_height_m;
      }
    }
    if (accepted) return q;
  }
  throw InputError("no commanded pose within TwinOptions.pose_ranges puts the nominal tip at "
                   "x >= " +
                   std::to_string(o.min_tip_forward_m) + " m and z >= " +
                   std::to_string(o.min_tip_height_m) + " m in " +
                   std::to_string(kMaxPoseDraws) +
                   " draws (with every link above the floor, when min_link_height_m is set); "
                   "expected ranges that reach in front of the robot (hint: widen pose_ranges "
                   "or lower min_tip_forward_m / min_tip_height_m)");
}

// True temperature of row seq of rows: TwinOptions::temperature_c's sinusoid and ramp, °C.
double trueTemperature_c(const TwinOptions& o, int64_t seq, int64_t rows) {
  double t = o.temperature_c + o.temperature_swing_c *
                                   std::sin(2.0 * kPi * static_cast<double>(seq) /
                                            o.temperature_period_rows);
  // Added only when on, so that a campaign without a ramp keeps its temperatures bit for bit.
  if (o.temperature_ramp_c != 0.0 && rows > 1) {
    t += o.temperature_ramp_c * static_cast<double>(seq - 1) / static_cast<double>(rows - 1);
  }
  return t;
}

// TwinOptions::load_order "mixed": the fit rows (every row not in set validation) shuffled
// among their own places, Fisher–Yates on the twin's platform-independent uniforms.
template <typename Row>
void mixFitRows(std::vector<Row>& rows, const TwinOptions& o) {
  std::vector<size_t> places;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].set != RowSet::kValidation) places.push_back(i);
  }
  Rng rng(o.seed, Stream::kLoadOrder, static_cast<uint32_t>(o.station));
  for (size_t k = places.size(); k > 1; --k) {
    const auto pick = std::min(k - 1, static_cast<size_t>(rng.uniform(0.0, static_cast<double>(k))));
    std::swap(rows[places[k - 1]], rows[places[pick]]);
  }
}

std::string poseId(const char* prefix, int index) {
  char id[32];
  std::snprintf(id, sizeof id, "%s-%03d", prefix, index);
  return id;
}

}  // namespace

Campaign simulateCampaign(const TwinOptions& options, nlohmann::json* truth_out) {
  const TwinRobot robot(options);  // validates the options
  const std::string path = resolvedUrdfPath(options);
  const std::string urdf_xml = readTextFile(path);
  const KinematicChain nominal = nominalChain(urdf_xml, options, path);

  Campaign campaign;
  campaign.urdf_xml = urdf_xml;
  campaign.base_link = options.base_link;
  campaign.tip_link = options.tip_link;
  campaign.sensor_link = options.sensor_link;
  campaign.flange_link = options.flange_link;
  campaign.tracker.position_sigma_m = options.tracker_position_sigma_m;
  campaign.tracker.orientation_sigma_rad = options.tracker_orientation_sigma_rad;
  // A zero sigma is no statement a weighting could use.
  campaign.tracker.stated =
      options.tracker_position_sigma_m > 0.0 && options.tracker_orientation_sigma_rad > 0.0;
  campaign.gravity_in_base = options.gravity_in_base_m_per_s2;
  campaign.joint_count = nominal.dof();

  // The rows to measure, in order: the planned fit rows (if any), then the protocol's blocks,
  // whose poses are drawn whether or not they are measured, so that validation poses stay.
  struct RowToMeasure {
    std::string pose_id;
    RowSet set;
    double load_kg;
    JointVector q;
  };
  std::vector<RowToMeasure> rows_to_measure;
  const bool has_plan = !options.planned_fit_rows.empty();
  for (const PlannedMeasurement& row : options.planned_fit_rows) {
    if (row.q_rad.size() != nominal.dof()) {
      throw InputError("a planned row has " + std::to_string(row.q_rad.size()) +
                           " joint angles; expected " + std::to_string(nominal.dof()) +
                           " (hint: plan with the robot the twin simulates)",
                       "poses", row.source_line);
    }
    rows_to_measure.push_back({row.pose_id, row.load_kg == 0.0 ? RowSet::kGeometry : RowSet::kStiffness,
                       row.load_kg, row.q_rad});
  }
  const auto station = static_cast<uint32_t>(options.station);
  Rng pose_rng(options.seed, Stream::kPoses, station);
  for (const Block& block : protocolBlocks(options.protocol)) {
    std::vector<JointVector> poses;
    for (int i = 0; i < block.poses; ++i) poses.push_back(drawPose(pose_rng, nominal, options));
    if (has_plan && block.set != RowSet::kValidation) continue;
    for (double load_kg : block.loads_kg) {
      for (int i = 0; i < block.poses; ++i) {
        rows_to_measure.push_back({poseId(block.pose_prefix, i), block.set, load_kg,
                           poses[static_cast<size_t>(i)]});
      }
    }
  }

  if (options.load_order == "mixed") mixFitRows(rows_to_measure, options);

  Rng noise_rng(options.seed, Stream::kNoise, station);
  const auto row_count = static_cast<int64_t>(rows_to_measure.size());
  int64_t seq = 1;
  for (const RowToMeasure& row : rows_to_measure) {
    const JointVector& q = row.q;
    const double load_kg = row.load_kg;
    const double temp_c = trueTemperature_c(options, seq, row_count);
    Pose X_TrackerTip = robot.X_TrackerTip(q, load_kg, temp_c);
    if (const auto& drift = robot.effects().registration_drift) {
      X_TrackerTip = lie::expSE3(drift->twist(seq, row_count)) *
                     X_TrackerTip;
    }
    // Every noise draw happens whatever its sigma, so sigmas do not shift the stream.
    const double noise =
        options.noiseless_validation && row.set == RowSet::kValidation ? 0.0 : 1.0;
    const Vec3 dp = noise * noise_rng.normal3(options.tracker_position_sigma_m);
    const Vec3 dr = noise * noise_rng.normal3(options.tracker_orientation_sigma_rad);
    const Vec3 df = noise * noise_rng.normal3(options.ft_force_sigma_n);
    const Vec3 dm = noise * noise_rng.normal3(options.ft_moment_sigma_nm);
    const double dtemp = noise * options.temperature_sigma_c * noise_rng.normal();

    Measurement m;
    m.seq = seq++;
    m.pose_id = row.pose_id;
    m.set = row.set;
    m.load_kg = load_kg;
    m.q_rad = q;
    m.p_TipInTracker_m = X_TrackerTip.translation() + dp;
    Eigen::Quaterniond quat(lie::expSO3(dr) * X_TrackerTip.linear());
    quat.normalize();
    if (quat.w() < 0.0) quat.coeffs() = -quat.coeffs();
    m.has_orientation = true;
    m.q_TrackerTip = quat;
    // The sensor is always mounted and tared unloaded: unloaded rows read noise (around
    // the bias, if the tare went wrong). Without one, no reading (every row is unloaded).
    m.has_wrench = robot.sensorFrame() >= 0;
    if (m.has_wrench) {
      m.wrench_Sensor = robot.sensorReading(q, load_kg, temp_c);
      m.wrench_Sensor.head<3>() += df;
      m.wrench_Sensor.tail<3>() += dm;
    }
    m.temp_c = temp_c + dtemp;
    campaign.rows.push_back(std::move(m));
  }
  if (truth_out != nullptr) *truth_out = robot.truthJson();
  return campaign;
}

std::vector<PlannedMeasurement> randomPoseList(const TwinOptions& options, int poses,
                                               const std::vector<double>& loads_kg) {
  if (poses < 1 || std::count(loads_kg.begin(), loads_kg.end(), 0.0) != 1) {
    throw InputError("a random pose list of " + std::to_string(poses) + " poses at " +
                     std::to_string(loads_kg.size()) +
                     " loads; expected at least one pose and the loads with 0 once (hint: every "
                     "pose is measured unloaded, e.g. loads 0, 20, 40)");
  }
  const std::string path = resolvedUrdfPath(options);
  const KinematicChain nominal = nominalChain(readTextFile(path), options, path);
  validateOptions(options, nominal);
  Rng rng(options.seed, Stream::kRandomPoseList, static_cast<uint32_t>(options.station));
  std::vector<JointVector> drawn;
  for (int i = 0; i < poses; ++i) drawn.push_back(drawPose(rng, nominal, options));
  std::vector<double> loads = loads_kg;
  std::sort(loads.begin(), loads.end());
  std::vector<PlannedMeasurement> rows;
  for (const double load_kg : loads) {
    for (int i = 0; i < poses; ++i) {
      rows.push_back({poseId("rand", i), load_kg, drawn[static_cast<size_t>(i)], 0});
    }
  }
  return rows;
}

void writeSimulation(const TwinOptions& options, const std::string& out_dir) {
  nlohmann::json truth;
  const Campaign campaign = simulateCampaign(options, &truth);
  writeCampaign(campaign, out_dir);
  const std::string path = out_dir + "/truth.json";
  std::ofstream out(path);
  out << truth.dump(2) << '\n';
  if (!out) throw InputError("cannot write the truth file", path);
}

}  // namespace stepcal::twin
