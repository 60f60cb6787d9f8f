// The simulated robot: reproducibility, the paper's protocol, the noiseless nominal case, the
// compliance fixed point against its linearisation, the F/T reading, truth.json round trips,
// noise statistics, the size of the errors an uncalibrated model would make, the temperature
// profile, every hidden mechanism against its closed form, and tracker stations (the same robot
// measured from another tracker placement).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/campaign_rows.hpp"
#include "support/files.hpp"

namespace stepcal::twin {
namespace {

const std::string kIrb = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";

TwinOptions paperOptions(uint64_t seed = 1) {
  TwinOptions o;
  o.urdf_path = kIrb;
  o.seed = seed;
  return o;
}

TwinOptions noiseless(TwinOptions o) {
  o.tracker_position_sigma_m = 0.0;
  o.tracker_orientation_sigma_rad = 0.0;
  o.ft_force_sigma_n = 0.0;
  o.ft_moment_sigma_nm = 0.0;
  o.temperature_sigma_c = 0.0;
  return o;
}

KinematicChain nominalChain() {
  return chainFromUrdfFile(kIrb, "base_link", "tmac", {"ft_sensor"});
}

Pose fk(const KinematicChain& chain, const JointVector& q) {
  ChainWorkspace ws;
  EXPECT_TRUE(forwardKinematics(chain, q, ws));
  return tipPose(ws);
}

// The true temperature of row seq under the default profile: 20 °C ± 3 °C, period 300 rows.
double defaultProfile_c(int64_t seq) {
  return 20.0 + 3.0 * std::sin(2.0 * kPi * static_cast<double>(seq) / 300.0);
}

using test::expectSameRows;

TEST(Twin, SameSeedSameCampaignDifferentSeedDifferent) {
  nlohmann::json truth_a, truth_b, truth_c;
  const Campaign a = simulateCampaign(paperOptions(7), &truth_a);
  const Campaign b = simulateCampaign(paperOptions(7), &truth_b);
  expectSameRows(a, b);
  EXPECT_EQ(truth_a, truth_b);

  const Campaign c = simulateCampaign(paperOptions(8), &truth_c);
  ASSERT_EQ(a.rows.size(), c.rows.size());
  EXPECT_NE(a.rows[0].q_rad, c.rows[0].q_rad);
  EXPECT_NE(a.rows[0].p_TipInTracker_m, c.rows[0].p_TipInTracker_m);
  EXPECT_NE(truth_a.at("X_TrackerBase_m"), truth_c.at("X_TrackerBase_m"));
}

TEST(Twin, NoiseAndMechanismsDoNotShiftOtherDraws) {
  TwinOptions plain = noiseless(paperOptions(3));
  plain.protocol = "geometry";
  plain.geometric_errors = false;
  TwinOptions full = paperOptions(3);
  full.protocol = "geometry";
  nlohmann::json truth_plain, truth_full;
  const Campaign a = simulateCampaign(plain, &truth_plain);
  const Campaign b = simulateCampaign(full, &truth_full);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (size_t i = 0; i < a.rows.size(); ++i) EXPECT_EQ(a.rows[i].q_rad, b.rows[i].q_rad);
  EXPECT_EQ(truth_plain.at("X_TrackerBase_m"), truth_full.at("X_TrackerBase_m"));
}

TEST(Twin, PaperProtocolRows) {
  const Campaign c = simulateCampaign(paperOptions(), nullptr);
  EXPECT_EQ(c.base_link, "base_link");
  EXPECT_EQ(c.tip_link, "tmac");
  EXPECT_EQ(c.sensor_link, "ft_sensor");
  EXPECT_EQ(c.joint_count, 6);
  EXPECT_TRUE(c.tracker.stated);
  EXPECT_DOUBLE_EQ(c.tracker.position_sigma_m, 10e-6);
  ASSERT_TRUE(c.gravity_in_base.has_value());
  EXPECT_EQ(*c.gravity_in_base, Vec3(0, 0, -9.80665));
  EXPECT_EQ(c.urdf_xml, readTextFile(kIrb));

  ASSERT_EQ(c.rows.size(), 1070u);
  std::map<std::pair<RowSet, double>, int> count;
  std::map<std::string, std::vector<const Measurement*>> by_pose;
  for (size_t i = 0; i < c.rows.size(); ++i) {
    const Measurement& m = c.rows[i];
    EXPECT_EQ(m.seq, static_cast<int64_t>(i + 1));
    EXPECT_EQ(m.q_rad.size(), 6);
    EXPECT_TRUE(m.has_orientation);
    EXPECT_TRUE(m.has_wrench);
    ASSERT_TRUE(m.temp_c.has_value());
    EXPECT_NEAR(*m.temp_c, defaultProfile_c(m.seq), 0.5);
    ++count[{m.set, m.load_kg}];
    by_pose[m.pose_id].push_back(&m);
  }
  const std::map<std::pair<RowSet, double>, int> expected = {
      {{RowSet::kGeometry, 0.0}, 80},    {{RowSet::kStiffness, 0.0}, 80},
      {{RowSet::kStiffness, 20.0}, 80},  {{RowSet::kStiffness, 30.0}, 80},
      {{RowSet::kStiffness, 40.0}, 80},  {{RowSet::kResidual, 20.0}, 100},
      {{RowSet::kResidual, 30.0}, 100},  {{RowSet::kResidual, 40.0}, 100},
      {{RowSet::kValidation, 0.0}, 80},  {{RowSet::kValidation, 20.0}, 80},
      {{RowSet::kValidation, 30.0}, 80}, {{RowSet::kValidation, 40.0}, 80},
      {{RowSet::kValidation, 55.0}, 50}};
  EXPECT_EQ(count, expected);

  // One pose_id per commanded joint set; its rows differ only in the load.
  std::map<std::string, int> poses_per_prefix;
  std::set<std::vector<double>> distinct_q;
  for (const auto& [id, rows] : by_pose) {
    ++poses_per_prefix[id.substr(0, id.find('-'))];
    std::set<double> loads;
    for (const Measurement* m : rows) {
      EXPECT_EQ(m->q_rad, rows.front()->q_rad) << id;
      EXPECT_EQ(m->set, rows.front()->set) << id;
      loads.insert(m->load_kg);
    }
    EXPECT_EQ(loads.size(), rows.size()) << id;
    const JointVector& q = rows.front()->q_rad;
    distinct_q.insert(std::vector<double>(q.data(), q.data() + q.size()));
  }
  const std::map<std::string, int> expected_poses = {{"geo", 80},  {"geov", 50}, {"stf", 80},
                                                     {"stfv", 30}, {"res", 100}, {"resv", 50},
                                                     {"ext", 50}};
  EXPECT_EQ(poses_per_prefix, expected_poses);
  EXPECT_EQ(distinct_q.size(), by_pose.size());

  // Every commanded pose keeps away from the wrist singularity.
  for (const Measurement& m : c.rows) EXPECT_GE(std::abs(m.q_rad(4)), 15.0 * kRadPerDeg);

  TwinOptions geometry = paperOptions();
  geometry.protocol = "geometry";
  const Campaign g = simulateCampaign(geometry, nullptr);
  EXPECT_EQ(g.rowsIn(RowSet::kGeometry).size(), 80u);
  EXPECT_EQ(g.rowsIn(RowSet::kValidation).size(), 50u);
  EXPECT_EQ(g.rows.size(), 130u);
}

TEST(Twin, NoiselessNominalRobotIsTrackerTimesNominalFk) {
  TwinOptions o = noiseless(paperOptions(5));
  o.geometric_errors = false;
  o.compliance = false;
  nlohmann::json truth;
  const Campaign c = simulateCampaign(o, &truth);
  const Pose X_TrackerBase = TwinRobot::fromTruthJson(truth).X_TrackerBase();
  const KinematicChain nominal = nominalChain();
  for (const Measurement& m : c.rows) {
    const Pose expected = X_TrackerBase * fk(nominal, m.q_rad);
    const Pose measured = m.X_TrackerTip();
    EXPECT_LT((measured.translation() - expected.translation()).norm(), 1e-12) << m.pose_id;
    EXPECT_LT((measured.linear() - expected.linear()).norm(), 1e-12) << m.pose_id;
    if (m.load_kg == 0.0) {
      EXPECT_EQ(m.wrench_Sensor, Vec6::Zero());
    }
    EXPECT_NEAR(*m.temp_c, defaultProfile_c(m.seq), 1e-12);
  }
  EXPECT_FALSE(c.tracker.stated);
}

// Spatial twist (base frame, base origin) that takes X_a to X_b.
Vec6 spatialDifference(const Pose& X_a, const Pose& X_b) {
  return lie::logSE3(X_b * X_a.inverse());
}

// Payload wrench at the base origin in base axes, at link angles theta.
Vec6 payloadWrench(const TwinRobot& robot, const JointVector& theta, double load_kg) {
  ChainWorkspace ws;
  forwardKinematics(robot.trueChain(), theta, ws);
  const Vec3 p = framePose(robot.trueChain(), ws, robot.sensorFrame()) * robot.p_CoGInSensor_m();
  const Vec3 f = load_kg * robot.gravityInBase();
  Vec6 W;
  W.head<3>() = f;
  W.tail<3>() = p.cross(f);
  return W;
}

Jacobian spatialJacobianAt(const TwinRobot& robot, const JointVector& theta) {
  ChainWorkspace ws;
  forwardKinematics(robot.trueChain(), theta, ws);
  Jacobian J;
  spatialJacobian(robot.trueChain(), ws, J);
  return J;
}

TEST(Twin, SmallLoadDeflectionMatchesLinearisedStiffnessModel) {
  const TwinOptions o = paperOptions(11);
  const TwinRobot robot(o);
  const Campaign c = simulateCampaign(o, nullptr);
  Eigen::Matrix<double, 6, 1> compliance;
  for (int i = 0; i < 6; ++i) compliance(i) = 1.0 / o.stiffness_nm_per_rad[static_cast<size_t>(i)];
  const double load_kg = 1.0;
  double worst = 0.0;
  for (const Measurement* m : c.rowsIn(RowSet::kGeometry)) {
    const JointVector& q = m->q_rad;
    const Jacobian J = spatialJacobianAt(robot, q);
    // docs/method.md eq. 17: ΔX = J K⁻¹ Jᵀ F.
    const Vec6 predicted =
        J * (compliance.asDiagonal() * (J.transpose() * payloadWrench(robot, q, load_kg)));
    const Vec6 simulated = spatialDifference(robot.X_BaseTip(q, 0.0), robot.X_BaseTip(q, load_kg));
    const double v_err = (simulated.head<3>() - predicted.head<3>()).norm() /
                         predicted.head<3>().norm();
    const double w_err = (simulated.tail<3>() - predicted.tail<3>()).norm() /
                         predicted.tail<3>().norm();
    worst = std::max({worst, v_err, w_err});
  }
  std::printf("[twin] 1 kg deflection vs J K^-1 J^T F: worst relative difference %.2e\n", worst);
  EXPECT_LT(worst, 1e-3);
}

TEST(Twin, LinkAnglesAreTheExactFixedPoint) {
  const TwinOptions o = paperOptions(12);
  const TwinRobot robot(o);
  const Campaign c = simulateCampaign(o, nullptr);
  for (const Measurement* m : c.rowsIn(RowSet::kResidual)) {
    for (double load_kg : {20.0, 55.0}) {
      const JointVector theta = robot.linkAngles(m->q_rad, load_kg);
      const JointVector tau = spatialJacobianAt(robot, theta).transpose() *
                              payloadWrench(robot, theta, load_kg);
      for (int i = 0; i < 6; ++i) {
        const double expected =
            m->q_rad(i) + tau(i) / o.stiffness_nm_per_rad[static_cast<size_t>(i)];
        EXPECT_NEAR(theta(i), expected, 1e-12) << m->pose_id << " joint " << i + 1;
      }
      // The tip pose is the exact FK at the deflected angles.
      const Pose expected = fk(robot.trueChain(), theta);
      EXPECT_LT((robot.X_BaseTip(m->q_rad, load_kg).matrix() - expected.matrix()).norm(), 1e-15);
    }
    EXPECT_EQ(robot.linkAngles(m->q_rad, 0.0), m->q_rad);
  }
}

TEST(Twin, TipDeflectionUnderPayload) {
  const TwinOptions o = paperOptions(1);
  const TwinRobot robot(o);
  const Campaign c = simulateCampaign(o, nullptr);
  std::printf("[twin] tip deflection over every commanded pose of a paper campaign:\n");
  double mean_40 = 0.0;
  for (double load_kg : {20.0, 30.0, 40.0, 55.0}) {
    double sum = 0.0, worst = 0.0, sum_deg = 0.0;
    std::set<std::string> seen;
    for (const Measurement& m : c.rows) {
      if (!seen.insert(m.pose_id).second) continue;
      const Pose X0 = robot.X_BaseTip(m.q_rad, 0.0);
      const Pose X = robot.X_BaseTip(m.q_rad, load_kg);
      const double d = (X.translation() - X0.translation()).norm();
      sum += d;
      worst = std::max(worst, d);
      sum_deg += lie::angleBetween(X0.linear(), X.linear()) / kRadPerDeg;
    }
    const double mean = sum / static_cast<double>(seen.size());
    if (load_kg == 40.0) mean_40 = mean;
    std::printf("[twin]   %4.0f kg: mean %.3f mm, max %.3f mm, mean rotation %.4f deg\n", load_kg,
                1e3 * mean, 1e3 * worst, sum_deg / static_cast<double>(seen.size()));
  }
  EXPECT_GT(mean_40, 0.2e-3);
  EXPECT_LT(mean_40, 3e-3);
}

TEST(Twin, SensorReadsThePayloadWeight) {
  const TwinOptions o = paperOptions(4);
  const TwinRobot robot(o);
  const Campaign c = simulateCampaign(o, nullptr);
  const double g = o.gravity_in_base_m_per_s2.norm();
  for (const Measurement* m : c.rowsIn(RowSet::kStiffness)) {
    const Vec6 W = robot.sensorWrench(m->q_rad, m->load_kg);
    EXPECT_NEAR(W.head<3>().norm(), m->load_kg * g, 1e-12 * (1.0 + m->load_kg * g));
    EXPECT_LT((W.tail<3>() - o.p_CoGInSensor_m.cross(W.head<3>())).norm(), 1e-12);
    // Direction: in base axes the force is m·g, at the true deflected pose.
    ChainWorkspace ws;
    forwardKinematics(robot.trueChain(), robot.linkAngles(m->q_rad, m->load_kg), ws);
    const Mat3 R_BaseSensor = framePose(robot.trueChain(), ws, robot.sensorFrame()).linear();
    EXPECT_LT((R_BaseSensor * W.head<3>() - m->load_kg * o.gravity_in_base_m_per_s2).norm(),
              1e-12);
    // The noisy reading is close to it.
    EXPECT_LT((m->wrench_Sensor.head<3>() - W.head<3>()).norm(), 6 * 0.2 * std::sqrt(3.0));
  }
}

TEST(Twin, TruthJsonRoundTrip) {
  const TwinOptions o = paperOptions(21);
  const TwinRobot robot(o);
  const nlohmann::json truth = robot.truthJson();
  EXPECT_EQ(truth.at("format"), "stepcal-twin-truth/1");
  EXPECT_EQ(truth.at("seed"), 21u);
  EXPECT_EQ(truth.at("initial_poses_m").size(), 7u);
  EXPECT_EQ(truth.at("effects").at(0).at("stiffness_nm_per_rad"), o.stiffness_nm_per_rad);
  // Through text, as the file is used.
  const TwinRobot copy = TwinRobot::fromTruthJson(nlohmann::json::parse(truth.dump()));
  EXPECT_EQ(copy.truthJson(), truth);
  const Campaign c = simulateCampaign(o, nullptr);
  for (size_t i = 0; i < c.rows.size(); i += 7) {
    const Measurement& m = c.rows[i];
    EXPECT_EQ(robot.X_TrackerTip(m.q_rad, m.load_kg).matrix(),
              copy.X_TrackerTip(m.q_rad, m.load_kg).matrix());
    EXPECT_EQ(robot.sensorWrench(m.q_rad, m.load_kg), copy.sensorWrench(m.q_rad, m.load_kg));
  }

  nlohmann::json broken = truth;
  broken.erase("X_TrackerBase_m");
  EXPECT_THROW(TwinRobot::fromTruthJson(broken), InputError);
  broken = truth;
  broken["format"] = "something-else/9";
  EXPECT_THROW(TwinRobot::fromTruthJson(broken), InputError);
}

TEST(Twin, WriteSimulationWritesCampaignAndTruth) {
  TwinOptions o = paperOptions(2);
  o.protocol = "geometry";
  const test::TempDir temp;
  const std::string dir = (temp.path() / "campaign").string();
  writeSimulation(o, dir);
  const Campaign read = readCampaign(dir);
  nlohmann::json truth;
  const Campaign simulated = simulateCampaign(o, &truth);
  expectSameRows(read, simulated);
  std::ifstream in(dir + "/truth.json");
  const nlohmann::json written = nlohmann::json::parse(in);
  EXPECT_EQ(written, truth);
}

TEST(Twin, NoiseStatisticsMatchTheOptions) {
  const TwinOptions noisy = paperOptions(9);
  const Campaign a = simulateCampaign(noisy, nullptr);
  const Campaign b = simulateCampaign(noiseless(noisy), nullptr);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  Eigen::Matrix<double, 4, 3> sum = Eigen::Matrix<double, 4, 3>::Zero();
  Eigen::Matrix<double, 4, 3> sum_sq = Eigen::Matrix<double, 4, 3>::Zero();
  for (size_t i = 0; i < a.rows.size(); ++i) {
    Eigen::Matrix<double, 4, 3> d;
    d.row(0) = (a.rows[i].p_TipInTracker_m - b.rows[i].p_TipInTracker_m).transpose();
    d.row(1) = lie::logSO3(a.rows[i].X_TrackerTip().linear() *
                           b.rows[i].X_TrackerTip().linear().transpose())
                   .transpose();
    d.row(2) = (a.rows[i].wrench_Sensor - b.rows[i].wrench_Sensor).head<3>().transpose();
    d.row(3) = (a.rows[i].wrench_Sensor - b.rows[i].wrench_Sensor).tail<3>().transpose();
    sum += d;
    sum_sq += d.cwiseProduct(d);
  }
  const double n = static_cast<double>(a.rows.size());
  const double sigma[4] = {noisy.tracker_position_sigma_m, noisy.tracker_orientation_sigma_rad,
                           noisy.ft_force_sigma_n, noisy.ft_moment_sigma_nm};
  const char* what[4] = {"position (m)", "orientation (rad)", "force (N)", "moment (N m)"};
  for (int k = 0; k < 4; ++k) {
    for (int axis = 0; axis < 3; ++axis) {
      const double mean = sum(k, axis) / n;
      const double std = std::sqrt((sum_sq(k, axis) - n * mean * mean) / (n - 1.0));
      std::printf("[twin] noise %-18s axis %d: std %.4g (sigma %.4g), mean %.2g\n", what[k], axis,
                  std, sigma[k], mean);
      EXPECT_NEAR(std, sigma[k], 0.1 * sigma[k]) << what[k] << " axis " << axis;
      EXPECT_LT(std::abs(mean), 4.0 * sigma[k] / std::sqrt(n)) << what[k] << " axis " << axis;
    }
  }
}

// Errors of the nominal model against the true robot, unloaded, in base_link.
std::pair<double, double> uncalibratedErrors(uint64_t seed, double* max_mm, bool print) {
  TwinOptions o = paperOptions(seed);
  o.protocol = "geometry";
  const TwinRobot robot(o);
  const Campaign c = simulateCampaign(o, nullptr);
  const KinematicChain nominal = nominalChain();
  double sum_p = 0.0, sum_r = 0.0, worst_p = 0.0, worst_r = 0.0;
  for (const Measurement& m : c.rows) {
    const Pose X_true = robot.X_BaseTip(m.q_rad, 0.0);
    const Pose X_nominal = fk(nominal, m.q_rad);
    const double dp = (X_true.translation() - X_nominal.translation()).norm();
    const double dr = lie::angleBetween(X_true.linear(), X_nominal.linear());
    sum_p += dp;
    sum_r += dr;
    worst_p = std::max(worst_p, dp);
    worst_r = std::max(worst_r, dr);
  }
  const double n = static_cast<double>(c.rows.size());
  if (print) {
    std::printf("[twin] seed %2llu nominal vs true, %zu unloaded poses: position mean %.2f mm, "
                "max %.2f mm; orientation mean %.3f deg, max %.3f deg\n",
                static_cast<unsigned long long>(seed), c.rows.size(), 1e3 * sum_p / n,
                1e3 * worst_p, sum_r / n / kRadPerDeg, worst_r / kRadPerDeg);
  }
  if (max_mm) *max_mm = 1e3 * worst_p;
  return {1e3 * sum_p / n, sum_r / n / kRadPerDeg};
}

TEST(Twin, UncalibratedErrorsLookLikeThePaper) {
  // The paper: 5.10 mm and 1.28 deg mean before calibration.
  double over_seeds_mm = 0.0, over_seeds_deg = 0.0;
  const int seeds = 10;
  for (int seed = 1; seed <= seeds; ++seed) {
    double max_mm = 0.0;
    const auto [mm, deg] = uncalibratedErrors(static_cast<uint64_t>(seed), &max_mm, true);
    EXPECT_GT(mm, 2.0);
    EXPECT_LT(mm, 10.0);
    EXPECT_GT(deg, 0.9);
    EXPECT_LT(deg, 1.7);
    over_seeds_mm += mm;
    over_seeds_deg += deg;
  }
  std::printf("[twin] mean over %d seeds: %.2f mm, %.3f deg\n", seeds, over_seeds_mm / seeds,
              over_seeds_deg / seeds);
}

TEST(Twin, BadOptionsAreRefusedWithTheValue) {
  TwinOptions o = paperOptions();
  o.protocol = "papper";
  try {
    simulateCampaign(o, nullptr);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("papper"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("geometry"), std::string::npos) << e.what();
  }
  o = paperOptions();
  o.stiffness_nm_per_rad = {1.0, 2.0};
  EXPECT_THROW(TwinRobot{o}, InputError);
  o = paperOptions();
  o.stiffness_nm_per_rad[3] = -5.0;
  EXPECT_THROW(TwinRobot{o}, InputError);
  o = paperOptions();
  o.tracker_position_sigma_m = -1e-6;
  EXPECT_THROW(TwinRobot{o}, InputError);
  o = paperOptions();
  o.urdf_path = "/nonexistent/robot.urdf";
  EXPECT_THROW(TwinRobot{o}, InputError);
  o = paperOptions();
  o.sensor_link = "no_such_link";
  EXPECT_THROW(TwinRobot{o}, InputError);
  o = paperOptions();
  o.min_tip_forward_m = 50.0;
  EXPECT_THROW(simulateCampaign(o, nullptr), InputError);
}

/// A self_weight object with these link entries.
nlohmann::json selfWeight(const nlohmann::json& links) {
  return {{"name", "self_weight"}, {"links", links}};
}

/// self_weight, thermal_expansion and sensor_bias at sizes a tracker and an F/T sensor see.
std::vector<nlohmann::json> selfWeightThermalAndBias() {
  return {selfWeight({{{"link", 2}, {"mass_kg", 40.0}, {"com_m", {0.3, 0.0, 0.1}}},
                      {{"link", 3}, {"mass_kg", 25.0}, {"com_m", {0.2, -0.02, 0.05}}}}),
          {{"name", "thermal_expansion"}, {"expansion_per_k", 1.2e-5}, {"reference_temp_c", 20.0}},
          {{"name", "sensor_bias"},
           {"force_n", {1.5, -2.0, 0.8}},
           {"moment_nm", {0.12, -0.05, 0.03}}}};
}

/// One of each link-angle mechanism, at a size a tracker sees.
std::vector<nlohmann::json> everyHiddenEffect() {
  return {{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", 2e-4}},
          {{"name", "transmission_error"}, {"joint", 3}, {"harmonic", 2}, {"sin_rad", 1e-4},
           {"cos_rad", -5e-5}},
          {{"name", "nonlinear_stiffness"}, {"joint", 4}, {"extra_compliance_rad_per_nm", 4e-6},
           {"saturation_torque_nm", 40.0}},
          {{"name", "joint_coupling"}, {"joints", {4, 6}}, {"ratio", 2e-3}}};
}

/// The link-angle effect a truth.json object describes.
std::shared_ptr<const LinkAngleEffect> linkAngleEffect(const nlohmann::json& spec) {
  EffectSet set;
  set.add(spec, 6);
  EXPECT_EQ(set.link_angle.size(), 1u);
  return set.link_angle.at(0);
}

TEST(Twin, HiddenEffectsFollowTheirClosedForms) {
  JointVector q(6), tau(6);
  q << 0.3, -0.7, 1.1, 2.5, -0.4, 0.9;
  tau << 10.0, -250.0, 80.0, -30.0, 5.0, 0.5;
  // (q + Δ) − q: exact to the rounding of the sum, 1e-15 rad here.
  const auto delta = [&](const LinkAngleEffect& effect) {
    JointVector theta = q;
    effect.apply(q, tau, theta);
    return JointVector(theta - q);
  };
  const std::vector<nlohmann::json> specs = everyHiddenEffect();
  JointVector expected = JointVector::Zero(6);
  expected(1) = 2e-4 * std::tanh(-250.0);  // taken up against the load: −b
  EXPECT_LT((delta(*linkAngleEffect(specs[0])) - expected).norm(), 1e-15);
  EXPECT_NEAR(expected(1), -2e-4, 1e-18);
  expected.setZero();
  expected(2) = 1e-4 * std::sin(2 * 1.1) - 5e-5 * std::cos(2 * 1.1);
  EXPECT_LT((delta(*linkAngleEffect(specs[1])) - expected).norm(), 1e-15);
  expected.setZero();
  expected(3) = 4e-6 * -30.0 * 40.0 / (40.0 + 30.0);
  EXPECT_LT((delta(*linkAngleEffect(specs[2])) - expected).norm(), 1e-15);
  expected.setZero();
  expected(5) = 2e-3 * 2.5;
  EXPECT_LT((delta(*linkAngleEffect(specs[3])) - expected).norm(), 1e-15);

  // Nonlinear stiffness: the slope of Δθ in τ is c at zero torque and falls with |τ| (softer at
  // small torque), checked by central differences.
  const auto nonlinear = linkAngleEffect(specs[2]);
  const auto slope = [&](double torque) {
    const double h = 1e-3;
    JointVector plus = q, minus = q, t = tau;
    t(3) = torque + h;
    nonlinear->apply(q, t, plus);
    t(3) = torque - h;
    nonlinear->apply(q, t, minus);
    return (plus(3) - minus(3)) / (2 * h);
  };
  EXPECT_NEAR(slope(0.5), 4e-6 * 40.0 * 40.0 / (40.5 * 40.5), 1e-12);
  EXPECT_GT(slope(1.0), 2.0 * slope(60.0));
}

TEST(Twin, HiddenEffectsMoveTheTipAndRoundTripThroughTruthJson) {
  TwinOptions o = noiseless(paperOptions(8));
  const TwinRobot plain(o);
  o.hidden_effects = everyHiddenEffect();
  const TwinRobot hidden(o);
  const nlohmann::json truth = hidden.truthJson();
  ASSERT_EQ(truth.at("effects").size(), 5u);
  EXPECT_EQ(truth.at("effects").at(1).at("name"), "backlash");
  EXPECT_EQ(truth.at("options").at("hidden_effects").size(), 4u);
  const TwinRobot copy = TwinRobot::fromTruthJson(nlohmann::json::parse(truth.dump()));
  const Campaign c = simulateCampaign(o, nullptr);
  double largest_m = 0.0;
  for (size_t i = 0; i < c.rows.size(); i += 5) {
    const Measurement& m = c.rows[i];
    EXPECT_EQ(hidden.X_TrackerTip(m.q_rad, m.load_kg).matrix(),
              copy.X_TrackerTip(m.q_rad, m.load_kg).matrix());
    largest_m = std::max(largest_m, (hidden.X_TrackerTip(m.q_rad, m.load_kg).translation() -
                                     plain.X_TrackerTip(m.q_rad, m.load_kg).translation())
                                        .norm());
  }
  EXPECT_GT(largest_m, 0.2e-3) << "the mechanisms move the tip by far more than the tracker noise";
  EXPECT_LT(largest_m, 5e-3);
}

TEST(Twin, BadHiddenEffectsAreRefusedWithTheValue) {
  const std::vector<std::pair<nlohmann::json, std::string>> cases = {
      {{{"name", "backlash"}, {"joint", 0}, {"lost_motion_rad", 1e-4}}, "joint = 0"},
      {{{"name", "backlash"}, {"joint", 7}, {"lost_motion_rad", 1e-4}}, "expected a joint 1 … 6"},
      {{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", -1e-4}}, "lost_motion_rad"},
      {{{"name", "transmission_error"}, {"joint", 2}, {"harmonic", 0}}, "harmonic = 0"},
      {{{"name", "transmission_error"}, {"joint", 2}, {"harmonic", 1}, {"sin_rad", 0.5}}, "sin_rad"},
      {{{"name", "nonlinear_stiffness"}, {"joint", 2}, {"extra_compliance_rad_per_nm", 1e-6},
        {"saturation_torque_nm", 0.0}}, "saturation_torque_nm"},
      {{{"name", "joint_coupling"}, {"joints", {5, 5}}, {"ratio", 1e-3}}, "two different joints"},
      {{{"name", "joint_coupling"}, {"joints", {5}}, {"ratio", 1e-3}}, "[from_joint, to_joint]"},
      {{{"name", "backlash"}, {"joint", 2}}, "hidden effect"},
      {{{"name", "gear_wobble"}},
       "unknown effect 'gear_wobble'; expected one of joint_compliance, backlash, "
       "transmission_error, nonlinear_stiffness, joint_coupling, self_weight, "
       "thermal_expansion, sensor_bias"},
      {selfWeight({{{"link", 0}, {"mass_kg", 40.0}, {"com_m", {0.3, 0.0, 0.1}}}}),
       "self_weight.links[0].link = 0; expected a link 1 … 6"},
      {selfWeight({{{"link", 2}, {"mass_kg", 40.0}, {"com_m", {0.3, 0.0, 0.1}}},
                   {{"link", 7}, {"mass_kg", 40.0}, {"com_m", {0.3, 0.0, 0.1}}}}),
       "self_weight.links[1].link = 7"},
      {selfWeight({{{"link", 2}, {"mass_kg", -4.0}, {"com_m", {0.3, 0.0, 0.1}}}}),
       "self_weight.links[0].mass_kg = -4 kg; expected a finite value in (0, 2000) kg"},
      {selfWeight({{{"link", 2}, {"mass_kg", 2500.0}, {"com_m", {0.3, 0.0, 0.1}}}}),
       "mass_kg = 2500 kg"},
      {selfWeight({{{"link", 2}, {"mass_kg", 40.0}, {"com_m", {6.0, 0.0, 0.0}}}}),
       "self_weight.links[0].com_m = [6, 0, 0] m; expected finite values with norm < 5 m"},
      {selfWeight({{{"link", 2}, {"mass_kg", 40.0}, {"com_m", {0.3, 0.1}}}}),
       "self_weight.links[0].com_m = [0.3,0.1]; expected three numbers"},
      {selfWeight({{{"link", 2}, {"mass_kg", 40.0}, {"com_m", {0.3, 0.0, 0.1}}},
                   {{"link", 2}, {"mass_kg", 10.0}, {"com_m", {0.1, 0.0, 0.0}}}}),
       "self_weight.links[1].link = 2 appears twice"},
      {selfWeight(nlohmann::json::array()), "self_weight.links is empty"},
      {{{"name", "self_weight"}, {"links", {{"link", 2}}}},
       "self_weight.links = {\"link\":2}; expected an array"},
      {selfWeight({{{"link", 2}, {"mass_kg", 40.0}}}), "hidden effect"},
      {{{"name", "thermal_expansion"}, {"expansion_per_k", 2e-4}, {"reference_temp_c", 20.0}},
       "thermal_expansion.expansion_per_k = 0.0002 1/K; expected a finite value with |value| < "
       "0.0001 1/K"},
      {{{"name", "thermal_expansion"}, {"expansion_per_k", 1e-5},
        {"reference_temp_c", std::nan("")}},
       "thermal_expansion.reference_temp_c = nan"},
      {{{"name", "thermal_expansion"}, {"expansion_per_k", 1e-5}}, "reference_temp_c"},
      {{{"name", "sensor_bias"}, {"force_n", {600.0, 0.0, 0.0}}, {"moment_nm", {0.0, 0.0, 0.0}}},
       "sensor_bias.force_n = [600, 0, 0] N; expected finite values with norm < 500 N"},
      {{{"name", "sensor_bias"}, {"force_n", {1.0, 0.0, 0.0}}, {"moment_nm", {0.0, 0.0, -150.0}}},
       "sensor_bias.moment_nm = [0, 0, -150] N·m"},
      {{{"name", "sensor_bias"}, {"force_n", {1.0, 0.0, 0.0}}}, "moment_nm"},
      {{{"name", "joint_zero_drift"}, {"joint", 0}, {"drift_rad_per_k", 3e-5},
        {"reference_temp_c", 20.0}},
       "joint_zero_drift.joint = 0; expected a joint 1 … 6"},
      {{{"name", "joint_zero_drift"}, {"joint", 2}, {"drift_rad_per_k", 2e-3},
        {"reference_temp_c", 20.0}},
       "joint_zero_drift.drift_rad_per_k = 0.002 rad/K; expected a finite value with |value| < "
       "0.001 rad/K"},
      {{{"name", "joint_zero_drift"}, {"joint", 2}, {"drift_rad_per_k", 3e-5},
        {"reference_temp_c", std::nan("")}},
       "joint_zero_drift.reference_temp_c = nan"},
      {{{"name", "joint_zero_drift"}, {"joint", 2}, {"reference_temp_c", 20.0}}, "drift_rad_per_k"},
      {{{"name", "registration_drift"}, {"translation_m", {0.02, 0.0, 0.0}},
        {"rotation_rad", {0.0, 0.0, 0.0}}},
       "registration_drift.translation_m = [0.02, 0, 0] m; expected finite values with norm < "
       "0.01 m"},
      {{{"name", "registration_drift"}, {"translation_m", {1e-4, 0.0, 0.0}},
        {"rotation_rad", {0.0, 0.05, 0.0}}},
       "registration_drift.rotation_rad = [0, 0.05, 0] rad"},
      {{{"name", "registration_drift"}, {"translation_m", {1e-4, 0.0}},
        {"rotation_rad", {0.0, 0.0, 0.0}}},
       "registration_drift.translation_m = [0.0001,0.0]; expected three numbers"},
      {{{"name", "registration_drift"}, {"translation_m", {1e-4, 0.0, 0.0}},
        {"rotation_rad", {0.0, 0.0, 0.0}}, {"settling_rows", -5.0}},
       "registration_drift.settling_rows = -5; expected a finite number of rows ≥ 0"},
  };
  for (const auto& [spec, message] : cases) {
    TwinOptions o = paperOptions();
    o.hidden_effects = {spec};
    try {
      TwinRobot robot(o);
      ADD_FAILURE() << "accepted " << spec.dump();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

TEST(Twin, DefaultUrdfIsTheShippedIrb4400) {
  TwinOptions o;
  o.protocol = "geometry";
  const Campaign c = simulateCampaign(o, nullptr);
  EXPECT_EQ(c.urdf_xml, readTextFile(kIrb));
}

// Any robot from its URDF: the UR10 is drawn within its joint limits, its stiffness from its
// rated torques, its own weight from its inertials; the paper's robot keeps the paper's values.
TEST(Twin, AnyRobotTakesRangesStiffnessAndSelfWeightFromItsUrdf) {
  const std::string ur10 = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";
  const TwinOptions o = twinOptionsForRobot(ur10, "base_link", "tool0", "");
  EXPECT_EQ(o.urdf_path, ur10);
  EXPECT_EQ(o.tip_link, "tool0");
  EXPECT_EQ(o.sensor_link, "");
  EXPECT_EQ(o.protocol, "geometry");
  const std::vector<double> effort = {330, 330, 150, 54, 54, 54};
  ASSERT_EQ(o.stiffness_nm_per_rad.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_DOUBLE_EQ(o.stiffness_nm_per_rad[i], effort[i] / kRatedTorqueDeflection_rad);
  }
  const KinematicChain chain = chainFromUrdfFile(ur10, "base_link", "tool0");
  ASSERT_EQ(o.pose_ranges.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(o.pose_ranges[i].lower_rad, chain.joints()[i].lower_rad);
    EXPECT_EQ(o.pose_ranges[i].upper_rad, chain.joints()[i].upper_rad);
    EXPECT_EQ(o.pose_ranges[i].min_abs_rad, 0.0);
  }
  ASSERT_TRUE(o.min_link_height_m.has_value());
  EXPECT_EQ(*o.min_link_height_m, 0.1);
  // The UR10's reach (its initial poses after joint 1's): 0.1273 + 0.612 + 0.5723 + 0.163941 +
  // 0.1157 + 0.0922 m.
  EXPECT_NEAR(o.min_tip_forward_m, 0.3 * 1.683441, 1e-12);
  EXPECT_NEAR(o.min_tip_height_m, 0.1 * 1.683441, 1e-12);
  ASSERT_EQ(o.hidden_effects.size(), 1u);
  const nlohmann::json& self_weight = o.hidden_effects[0];
  EXPECT_EQ(self_weight.at("name"), "self_weight");
  const std::vector<double> bodies =
      *bodyMassesFromUrdf(readTextFile(ur10), "base_link", "tool0", ur10);
  ASSERT_EQ(self_weight.at("links").size(), 6u);
  for (int k = 0; k < 6; ++k) {
    const nlohmann::json& link = self_weight.at("links").at(static_cast<size_t>(k));
    EXPECT_EQ(link.at("link"), k + 1);
    EXPECT_DOUBLE_EQ(link.at("mass_kg").get<double>(), bodies[4 * k]);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(link.at("com_m").at(static_cast<size_t>(a)).get<double>() * bodies[4 * k],
                  bodies[4 * k + 1 + a], 1e-15);
    }
  }
  EXPECT_DOUBLE_EQ(self_weight.at("links").at(1).at("mass_kg").get<double>(), 12.93);

  const TwinOptions irb = twinOptionsForRobot(kIrb, "base_link", "tmac", "ft_sensor");
  const TwinOptions paper;
  EXPECT_EQ(irb.protocol, "paper");
  EXPECT_EQ(irb.stiffness_nm_per_rad, paper.stiffness_nm_per_rad);
  EXPECT_EQ(toJson(irb).at("pose_ranges"), toJson(paper).at("pose_ranges"));
  EXPECT_TRUE(irb.hidden_effects.empty());
  EXPECT_FALSE(irb.min_link_height_m.has_value());
  // So the IRB4400's campaigns stay as they were.
  TwinOptions a = paperOptions(4), b = irb;
  b.seed = 4;
  expectSameRows(simulateCampaign(a, nullptr), simulateCampaign(b, nullptr));
}

// A robot without an F/T sensor: every row unloaded and without a reading; every nominal link
// above the floor; the truth round trips without a sensor frame; its own weight deflects it.
TEST(Twin, RobotWithoutASensorIsMeasuredUnloadedWithoutAWrench) {
  const std::string ur10 = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";
  TwinOptions o = twinOptionsForRobot(ur10, "base_link", "tool0", "");
  o.seed = 2;
  nlohmann::json truth;
  const Campaign c = simulateCampaign(o, &truth);
  EXPECT_EQ(c.sensor_link, "");
  ASSERT_EQ(c.rows.size(), 130u);
  const KinematicChain nominal = chainFromUrdfFile(ur10, "base_link", "tool0");
  ChainWorkspace ws;
  for (const Measurement& m : c.rows) {
    EXPECT_EQ(m.load_kg, 0.0);
    EXPECT_FALSE(m.has_wrench);
    forwardKinematics(nominal, m.q_rad, ws);
    for (int k = 2; k <= 7; ++k) {
      EXPECT_GE(ws.X_RootFrame[static_cast<size_t>(k)].translation().z(), 0.1) << m.pose_id;
    }
    EXPECT_GE(tipPose(ws).translation().x(), o.min_tip_forward_m);
  }
  EXPECT_TRUE(truth.at("sensor_frame").is_null());
  const TwinRobot robot(o);
  const TwinRobot back = TwinRobot::fromTruthJson(truth);
  EXPECT_EQ(back.sensorFrame(), -1);
  const JointVector& q = c.rows[7].q_rad;
  EXPECT_EQ(back.X_TrackerTip(q, 0.0).matrix(), robot.X_TrackerTip(q, 0.0).matrix());
  EXPECT_EQ(robot.sensorReading(q, 0.0), Vec6::Zero());
  // Its own weight on the shoulder and elbow (110 000 and 50 000 N·m/rad) moves the tip by
  // about a millimetre.
  TwinOptions weightless = o;
  weightless.hidden_effects.clear();
  double largest_m = 0.0;
  for (const Measurement& m : c.rows) {
    largest_m = std::max(largest_m, (TwinRobot(weightless).X_BaseTip(m.q_rad, 0.0).translation() -
                                     robot.X_BaseTip(m.q_rad, 0.0).translation())
                                        .norm());
  }
  EXPECT_GT(largest_m, 0.5e-3);
  EXPECT_LT(largest_m, 5e-3);
}

TEST(Twin, PaperProtocolPayloadsAndStiffnessNeedTheirLinkAndLimits) {
  const std::string ur10 = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";
  TwinOptions o = twinOptionsForRobot(ur10, "base_link", "tool0", "");
  o.protocol = "paper";
  const auto refused = [](const TwinOptions& options, const std::string& message) {
    try {
      simulateCampaign(options, nullptr);
      ADD_FAILURE() << "accepted; expected " << message;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  refused(o, "TwinOptions.protocol = 'paper' without a sensor_link");
  o.protocol = "geometry";
  const JointVector q = JointVector::Constant(6, 0.3);
  o.planned_fit_rows = {{"p", 0.0, q, 2}, {"p", 10.0, q, 3}};
  refused(o, "pose 'p' at 10.000000 kg, but the robot has no sensor_link");
  // With a link to hang from (the flange), the payload is measured.
  TwinOptions flange = twinOptionsForRobot(ur10, "base_link", "tool0", "tool0");
  flange.planned_fit_rows = o.planned_fit_rows;
  const Campaign loaded = simulateCampaign(flange, nullptr);
  EXPECT_EQ(loaded.rowsIn(RowSet::kStiffness).size(), 1u);
  // 10 kg's weight, read with 0.2 N of noise per axis.
  EXPECT_NEAR(loaded.rowsIn(RowSet::kStiffness)[0]->wrench_Sensor.head<3>().norm(), 98.07, 1.5);
  // A robot the paper does not give and whose URDF has no effort limits: stiffness to be given.
  std::string unnamed = readTextFile(kIrb);
  unnamed.replace(unnamed.find(kPaperRobotName), std::string(kPaperRobotName).size(), "my_arm");
  const test::TempDir dir;
  const std::string path = (dir.path() / "my_arm.urdf").string();
  std::ofstream(path) << unnamed;
  TwinOptions mine = twinOptionsForRobot(path, "base_link", "tmac", "ft_sensor");
  EXPECT_TRUE(mine.stiffness_nm_per_rad.empty());
  refused(mine, "--stiffness K1,...,Kn");
  mine.stiffness_nm_per_rad = kPaperStiffnessNmPerRad;
  EXPECT_EQ(simulateCampaign(mine, nullptr).rows.size(), 1070u);
}

TEST(Twin, SecondSelfWeightThermalOrBiasIsRefused) {
  for (const nlohmann::json& spec : selfWeightThermalAndBias()) {
    TwinOptions o = paperOptions();
    o.hidden_effects = {spec, spec};
    const std::string name = spec.at("name");
    try {
      TwinRobot robot(o);
      ADD_FAILURE() << "accepted two " << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name + " is given twice; expected at most one"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(Twin, ASecondDriftOfAJointOrOfTheTrackerIsRefused) {
  const nlohmann::json warm = {{"name", "joint_zero_drift"}, {"joint", 2},
                               {"drift_rad_per_k", 3e-5}, {"reference_temp_c", 20.0}};
  nlohmann::json other_joint = warm;
  other_joint["joint"] = 3;
  const nlohmann::json settling = {{"name", "registration_drift"},
                                   {"translation_m", {1e-4, 0.0, 0.0}},
                                   {"rotation_rad", {0.0, 0.0, 1e-5}}};
  TwinOptions o = paperOptions();
  o.hidden_effects = {warm, other_joint, settling};
  EXPECT_NO_THROW(TwinRobot robot(o)) << "one drift per joint and one of the tracker";
  for (const auto& [specs, message] :
       {std::pair{std::vector<nlohmann::json>{warm, warm},
                  std::string("joint_zero_drift of joint 2 is given twice; expected at most one "
                              "per joint")},
        std::pair{std::vector<nlohmann::json>{settling, settling},
                  std::string("registration_drift is given twice; expected at most one")}}) {
    o.hidden_effects = specs;
    try {
      TwinRobot robot(o);
      ADD_FAILURE() << "accepted " << message;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

TEST(Twin, BadTemperatureProfileIsRefusedWithTheKey) {
  const std::vector<std::pair<double, double>> cases = {
      {-1.0, 400.0}, {30.0, 400.0}, {std::nan(""), 400.0}, {3.0, 0.0}, {3.0, -5.0},
      {3.0, std::numeric_limits<double>::infinity()}};
  for (const auto& [swing_c, period_rows] : cases) {
    TwinOptions o = paperOptions();
    o.temperature_swing_c = swing_c;
    o.temperature_period_rows = period_rows;
    const std::string key =
        period_rows > 0.0 && std::isfinite(period_rows) ? "TwinOptions.temperature_swing_c = "
                                                        : "TwinOptions.temperature_period_rows = ";
    try {
      TwinRobot robot(o);
      ADD_FAILURE() << "accepted swing " << swing_c << " °C, period " << period_rows;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

TEST(Twin, TemperatureFollowsTheSinusoidAndShiftsNoOtherDraw) {
  const TwinOptions swinging = paperOptions(16);
  TwinOptions constant = swinging;
  constant.temperature_swing_c = 0.0;
  const Campaign a = simulateCampaign(swinging, nullptr);
  const Campaign b = simulateCampaign(constant, nullptr);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  double sum = 0.0, sum_sq = 0.0, worst = 0.0;
  struct Span {
    double min_c, max_c;
    int rows;
  };
  std::map<std::pair<std::string, double>, Span> spans;  // by pose_id prefix and load
  for (size_t i = 0; i < a.rows.size(); ++i) {
    const Measurement& x = a.rows[i];
    const Measurement& y = b.rows[i];
    // Without a thermal mechanism only temp_c changes, and the noise stream is the same.
    EXPECT_EQ(x.q_rad, y.q_rad);
    EXPECT_EQ(x.p_TipInTracker_m, y.p_TipInTracker_m);
    EXPECT_EQ(x.q_TrackerTip.coeffs(), y.q_TrackerTip.coeffs());
    EXPECT_EQ(x.wrench_Sensor, y.wrench_Sensor);
    const double T = defaultProfile_c(x.seq);
    EXPECT_NEAR(*x.temp_c - *y.temp_c, T - 20.0, 1e-12) << x.seq;
    const double r = *x.temp_c - T;
    sum += r;
    sum_sq += r * r;
    worst = std::max(worst, std::abs(r));
    Span& span = spans.try_emplace({x.pose_id.substr(0, x.pose_id.find('-')), x.load_kg},
                                   Span{T, T, 0})
                     .first->second;
    span.min_c = std::min(span.min_c, T);
    span.max_c = std::max(span.max_c, T);
    ++span.rows;
  }
  const double n = static_cast<double>(a.rows.size());
  const double sigma = swinging.temperature_sigma_c;
  const double mean = sum / n;
  const double std = std::sqrt((sum_sq - n * mean * mean) / (n - 1.0));
  EXPECT_NEAR(std, sigma, 0.1 * sigma);
  EXPECT_LT(std::abs(mean), 4.0 * sigma / std::sqrt(n));
  EXPECT_LT(worst, 6.0 * sigma);
  // Not one temperature per block: within every fitted group of 80 rows or more (geometry,
  // stiffness and residual at each load) the true temperature spans more than 1.5 °C.
  for (const auto& [group, span] : spans) {
    if (span.rows < 80) continue;
    EXPECT_GT(span.max_c - span.min_c, 1.5) << group.first << " at " << group.second << " kg";
  }
}

TEST(Twin, SelfWeightDeflectsEachJointByItsComplianceTimesTheGravityTorque) {
  TwinOptions o = noiseless(paperOptions(6));
  const double mass_kg = 60.0;
  const Vec3 p_ComInLink6_m(0.05, -0.04, 0.12);
  o.hidden_effects = {selfWeight(
      {{{"link", 6}, {"mass_kg", mass_kg}, {"com_m", {0.05, -0.04, 0.12}}}})};
  const TwinRobot robot(o);
  const KinematicChain& chain = robot.trueChain();
  const Vec3 g = robot.gravityInBase();
  // The point mass's potential V(θ) = −m g·p(θ); its torque on joint j is τ_j = −∂V/∂θ_j
  // (the generalised force, the direction the joint is pushed), here by central differences
  // with h = 1e-5 rad: error ~1e-8 N·m, ~1e-13 rad after the compliance.
  const auto potential = [&](const JointVector& theta) {
    ChainWorkspace ws;
    forwardKinematics(chain, theta, ws);
    return -mass_kg * g.dot(ws.X_RootFrame[6] * p_ComInLink6_m);
  };
  // The physical model's self_weight (common/mechanisms.hpp): first moment h = m · com.
  std::vector<double> model_parameters(24, 0.0);
  model_parameters[20] = mass_kg;
  for (int a = 0; a < 3; ++a) {
    model_parameters[static_cast<size_t>(21 + a)] = mass_kg * p_ComInLink6_m(a);
  }
  const Campaign c = simulateCampaign(o, nullptr);
  double largest_rad = 0.0;
  for (const Measurement* m : c.rowsIn(RowSet::kGeometry)) {
    const JointVector theta = robot.linkAngles(m->q_rad, 0.0);
    JointVector tau(6);
    for (int j = 0; j < 6; ++j) {
      const double h = 1e-5;
      JointVector plus = theta, minus = theta;
      plus(j) += h;
      minus(j) -= h;
      tau(j) = -(potential(plus) - potential(minus)) / (2.0 * h);
      const double compliance = 1.0 / o.stiffness_nm_per_rad[static_cast<size_t>(j)];
      EXPECT_NEAR(theta(j) - m->q_rad(j), compliance * tau(j), 1e-11)
          << m->pose_id << " joint " << j + 1;
      largest_rad = std::max(largest_rad, std::abs(theta(j) - m->q_rad(j)));
    }
    ChainWorkspace ws;
    forwardKinematics(chain, theta, ws);
    JointVector tau_model;
    selfWeightTorques(chain, ws, g, model_parameters, tau_model);
    EXPECT_LT((tau_model - tau).cwiseAbs().maxCoeff(), 1e-6) << m->pose_id;
    // The sensor sees only the payload: unloaded it reads nothing.
    EXPECT_EQ(robot.sensorReading(m->q_rad, 0.0), Vec6::Zero());
  }
  // Unloaded rows deflect: 60 kg half a metre or more out on the wrist.
  EXPECT_GT(largest_rad, 1e-4);
}

TEST(Twin, SelfWeightAtThePayloadsCoGActsLikeThePayload) {
  TwinOptions o = noiseless(paperOptions(19));
  const TwinRobot loaded(o);
  const AttachedFrame& sensor =
      loaded.trueChain().frames()[static_cast<size_t>(loaded.sensorFrame())];
  ASSERT_EQ(sensor.parent, 6);
  const Vec3 p_CoGInLink6_m = sensor.X_ParentFrame * o.p_CoGInSensor_m;
  o.hidden_effects = {selfWeight(
      {{{"link", 6}, {"mass_kg", 40.0},
        {"com_m", {p_CoGInLink6_m.x(), p_CoGInLink6_m.y(), p_CoGInLink6_m.z()}}}})};
  const TwinRobot weighted(o);
  const Campaign c = simulateCampaign(o, nullptr);
  for (const Measurement* m : c.rowsIn(RowSet::kResidual)) {
    // Both are fixed points of the same equation, each to 1e-12 rad.
    EXPECT_LT((weighted.linkAngles(m->q_rad, 0.0) - loaded.linkAngles(m->q_rad, 40.0))
                  .cwiseAbs()
                  .maxCoeff(),
              2e-12)
        << m->pose_id;
    // Payload and link weight add up.
    EXPECT_LT((weighted.linkAngles(m->q_rad, 20.0) - loaded.linkAngles(m->q_rad, 60.0))
                  .cwiseAbs()
                  .maxCoeff(),
              2e-12)
        << m->pose_id;
  }
}

TEST(Twin, ThermalExpansionScalesTheArmBeyondJointOne) {
  TwinOptions o = noiseless(paperOptions(14));
  o.protocol = "geometry";
  o.hidden_effects = {selfWeightThermalAndBias()[1]};  // α = 1.2e-5 /K, T_ref = 20 °C
  const TwinRobot robot(o);
  const KinematicChain& chain = robot.trueChain();
  // Joint 1 turns about an axis through its frame's origin, which T_{0,1}(0) (never scaled)
  // places; everything beyond it is the links, scaled by s = 1 + α (T − T_ref).
  ASSERT_TRUE(chain.joints()[0].twist_Local.head<3>().isZero(0.0));
  const Vec3 p_Joint1InBase = chain.initialPose(0).translation();
  const Campaign c = simulateCampaign(o, nullptr);
  for (const Measurement& m : c.rows) {
    const Pose X_ref = robot.X_BaseTip(m.q_rad, 0.0, 20.0);
    EXPECT_EQ(X_ref.matrix(), robot.X_BaseTip(m.q_rad, 0.0).matrix());  // NaN: reference length
    EXPECT_EQ(X_ref.matrix(), fk(chain, m.q_rad).matrix());
    const Vec3 arm_ref = X_ref.translation() - p_Joint1InBase;
    for (double temp_c : {35.0, -5.0, 23.7}) {
      const double scale = 1.0 + 1.2e-5 * (temp_c - 20.0);
      const Pose X = robot.X_BaseTip(m.q_rad, 0.0, temp_c);
      const Vec3 arm = X.translation() - p_Joint1InBase;
      EXPECT_LT((arm - scale * arm_ref).norm(), 1e-13) << m.pose_id << " at " << temp_c << " °C";
      EXPECT_NEAR(arm.norm() / arm_ref.norm(), scale, 1e-14);
      EXPECT_LT((X.linear() - X_ref.linear()).norm(), 1e-15);
    }
  }
}

TEST(Twin, ThermalCampaignMeasuresEachRowAtItsTrueTemperature) {
  TwinOptions swinging = noiseless(paperOptions(15));
  const double alpha_per_k = 1.2e-5;
  swinging.hidden_effects = {selfWeightThermalAndBias()[1]};
  TwinOptions constant = swinging;
  constant.temperature_swing_c = 0.0;  // always at T_ref = 20 °C: scale 1
  const TwinRobot robot(swinging);
  const KinematicChain& chain = robot.trueChain();
  const Vec3 p_Joint1InBase = chain.initialPose(0).translation();
  const Campaign a = simulateCampaign(swinging, nullptr);
  const Campaign b = simulateCampaign(constant, nullptr);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  double largest_m = 0.0;
  for (size_t i = 0; i < a.rows.size(); ++i) {
    const Measurement& x = a.rows[i];
    const double temp_c = defaultProfile_c(x.seq);
    const double scale = 1.0 + alpha_per_k * (temp_c - 20.0);
    ASSERT_EQ(x.q_rad, b.rows[i].q_rad);
    EXPECT_NEAR(*x.temp_c, temp_c, 1e-12);
    EXPECT_LT((x.p_TipInTracker_m - robot.X_TrackerTip(x.q_rad, x.load_kg, temp_c).translation())
                  .norm(),
              1e-12);
    if (x.load_kg == 0.0) {
      // Unloaded, the link angles are the commanded ones: the arm beyond joint 1 scales.
      const Vec3 p_ref = robot.X_TrackerBase().inverse() * b.rows[i].p_TipInTracker_m;
      const Vec3 expected =
          robot.X_TrackerBase() * (p_Joint1InBase + scale * (p_ref - p_Joint1InBase));
      EXPECT_LT((x.p_TipInTracker_m - expected).norm(), 1e-12) << x.pose_id;
      largest_m = std::max(largest_m, (x.p_TipInTracker_m - b.rows[i].p_TipInTracker_m).norm());
      continue;
    }
    // Loaded, the compliance's fixed point uses the scaled lever arms.
    const JointVector theta = robot.linkAngles(x.q_rad, x.load_kg, temp_c);
    ChainWorkspace ws;
    forwardKinematics(chain, theta, ws, scale);
    Jacobian J;
    spatialJacobian(chain, ws, J);
    const Vec3 p_CoGInBase = framePose(chain, ws, robot.sensorFrame()) * robot.p_CoGInSensor_m();
    Vec6 W;
    W.head<3>() = x.load_kg * robot.gravityInBase();
    W.tail<3>() = p_CoGInBase.cross(W.head<3>());
    const JointVector tau = J.transpose() * W;
    for (int j = 0; j < 6; ++j) {
      const double stiffness = swinging.stiffness_nm_per_rad[static_cast<size_t>(j)];
      EXPECT_NEAR(theta(j), x.q_rad(j) + tau(j) / stiffness, 1e-12)
          << x.pose_id << " joint " << j + 1;
    }
  }
  // ±3 °C on a ~2 m arm: tens of µm, several times the tracker's noise.
  std::printf("[twin] thermal expansion 1.2e-5/K, 20 +- 3 degC: largest unloaded tip change "
              "%.1f um\n",
              1e6 * largest_m);
  EXPECT_GT(largest_m, 30e-6);
  EXPECT_LT(largest_m, 120e-6);
}

TEST(Twin, SensorBiasOffsetsEveryReadingAndNothingElse) {
  const TwinOptions clean = paperOptions(17);  // with noise: the same draws in both
  TwinOptions biased = clean;
  biased.hidden_effects = {selfWeightThermalAndBias()[2]};
  Vec6 bias;
  bias << 1.5, -2.0, 0.8, 0.12, -0.05, 0.03;
  const TwinRobot robot(biased);
  const TwinRobot clean_robot(clean);
  EXPECT_EQ(robot.effects().sensorBias_Sensor(), bias);
  const Campaign a = simulateCampaign(biased, nullptr);
  const Campaign b = simulateCampaign(clean, nullptr);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  Vec6 unloaded_sum = Vec6::Zero();
  int unloaded = 0;
  for (size_t i = 0; i < a.rows.size(); ++i) {
    const Measurement& x = a.rows[i];
    const Measurement& y = b.rows[i];
    EXPECT_EQ(x.p_TipInTracker_m, y.p_TipInTracker_m);  // the robot's physics is unaffected
    EXPECT_EQ(x.q_TrackerTip.coeffs(), y.q_TrackerTip.coeffs());
    // Readings reach 540 N at 55 kg: their sum rounds at 1e-13.
    EXPECT_LT((x.wrench_Sensor - y.wrench_Sensor - bias).cwiseAbs().maxCoeff(), 1e-12) << x.seq;
    if (x.load_kg == 0.0) {
      unloaded_sum += x.wrench_Sensor;
      ++unloaded;
    }
  }
  // Unloaded rows read the bias plus noise.
  const Vec6 mean = unloaded_sum / unloaded;
  for (int k = 0; k < 6; ++k) {
    const double sigma = k < 3 ? clean.ft_force_sigma_n : clean.ft_moment_sigma_nm;
    EXPECT_NEAR(mean(k), bias(k), 4.0 * sigma / std::sqrt(static_cast<double>(unloaded))) << k;
  }
  const JointVector& q = a.rows[500].q_rad;
  EXPECT_EQ(robot.sensorWrench(q, 30.0), clean_robot.sensorWrench(q, 30.0));
  EXPECT_LT((robot.sensorReading(q, 30.0) - robot.sensorWrench(q, 30.0) - bias).norm(), 1e-12);
}

TEST(Twin, EveryMechanismRoundTripsThroughTruthJson) {
  TwinOptions o = noiseless(paperOptions(18));
  // Given first, listed after the link-angle effects: truth.json follows the pipeline.
  o.hidden_effects = selfWeightThermalAndBias();
  for (const nlohmann::json& e : everyHiddenEffect()) o.hidden_effects.push_back(e);
  const TwinRobot robot(o);
  const nlohmann::json truth = robot.truthJson();
  const nlohmann::json& effects = truth.at("effects");
  ASSERT_EQ(effects.size(), 8u);
  EXPECT_EQ(effects.at(0).at("name"), "joint_compliance");
  for (size_t k = 0; k < 4; ++k) EXPECT_EQ(effects.at(1 + k), everyHiddenEffect()[k]);
  for (size_t k = 0; k < 3; ++k) EXPECT_EQ(effects.at(5 + k), selfWeightThermalAndBias()[k]);
  EXPECT_EQ(truth.at("options").at("temperature_swing_c"), 3.0);
  EXPECT_EQ(truth.at("options").at("temperature_period_rows"), 300.0);

  const TwinRobot copy = TwinRobot::fromTruthJson(nlohmann::json::parse(truth.dump()));
  EXPECT_EQ(copy.truthJson(), truth);
  const Campaign c = simulateCampaign(o, nullptr);
  for (size_t i = 0; i < c.rows.size(); i += 9) {
    const Measurement& m = c.rows[i];
    for (double temp_c : {kNoThermalExpansion, 14.0, 26.5}) {
      EXPECT_EQ(robot.X_TrackerTip(m.q_rad, m.load_kg, temp_c).matrix(),
                copy.X_TrackerTip(m.q_rad, m.load_kg, temp_c).matrix());
      EXPECT_EQ(robot.sensorReading(m.q_rad, m.load_kg, temp_c),
                copy.sensorReading(m.q_rad, m.load_kg, temp_c));
    }
    // The noiseless campaign is the robot at each row's true temperature, bias included.
    const double temp_c = defaultProfile_c(m.seq);
    EXPECT_LT((m.p_TipInTracker_m - copy.X_TrackerTip(m.q_rad, m.load_kg, temp_c).translation())
                  .norm(),
              1e-12);
    EXPECT_LT((m.wrench_Sensor - copy.sensorReading(m.q_rad, m.load_kg, temp_c)).norm(), 1e-12);
  }

  nlohmann::json twice = truth;
  twice["effects"].push_back(selfWeightThermalAndBias()[1]);
  try {
    TwinRobot::fromTruthJson(twice);
    ADD_FAILURE() << "accepted two thermal_expansion";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("thermal_expansion is given twice"), std::string::npos)
        << e.what();
  }
}


// Where the tracker stands in base_link: the translation of X_BaseTracker, m.
Vec3 p_TrackerInBase_m(const TwinRobot& robot) {
  return robot.X_TrackerBase().inverse().translation();
}

TEST(Twin, AnotherStationIsTheSameRobotSeenFromElsewhere) {
  TwinOptions o = paperOptions(12);
  o.protocol = "geometry";
  o.hidden_effects = selfWeightThermalAndBias();
  for (const nlohmann::json& e : everyHiddenEffect()) o.hidden_effects.push_back(e);
  std::vector<TwinOptions> options;
  std::vector<TwinRobot> robots;
  std::vector<Campaign> campaigns;
  std::vector<nlohmann::json> truths(3);
  for (int k = 0; k < 3; ++k) {
    options.push_back(o);
    options.back().station = k;
    robots.emplace_back(options.back());
    campaigns.push_back(simulateCampaign(options.back(), &truths[static_cast<size_t>(k)]));
  }
  const KinematicChain& chain_0 = robots[0].trueChain();
  for (size_t k = 1; k < 3; ++k) {
    SCOPED_TRACE("station " + std::to_string(k));
    const TwinRobot& robot = robots[k];
    const nlohmann::json& truth = truths[k];
    // The same robot, exactly: geometry, joints, every mechanism.
    const KinematicChain& chain = robot.trueChain();
    ASSERT_EQ(chain.initialPoses().size(), chain_0.initialPoses().size());
    for (size_t i = 0; i < chain.initialPoses().size(); ++i) {
      EXPECT_EQ(chain.initialPoses()[i].matrix(), chain_0.initialPoses()[i].matrix()) << i;
    }
    ASSERT_EQ(chain.joints().size(), chain_0.joints().size());
    for (size_t i = 0; i < chain.joints().size(); ++i) {
      EXPECT_EQ(chain.joints()[i].twist_Local, chain_0.joints()[i].twist_Local) << i;
    }
    EXPECT_EQ(truth.at("effects"), truths[0].at("effects"));
    EXPECT_EQ(truth.at("initial_pose_errors_m_rad"), truths[0].at("initial_pose_errors_m_rad"));
    EXPECT_EQ(truth.at("options").at("station"), k);

    // The tracker elsewhere: more than a few cm from every other station, within the placement
    // (TwinOptions::tracker_distance_min_m).
    const Vec3 p = p_TrackerInBase_m(robot);
    for (size_t other = 0; other < k; ++other) {
      EXPECT_GT((p - p_TrackerInBase_m(robots[other])).norm(), 0.05) << "station " << other;
    }
    const double distance_m = std::hypot(p.x(), p.y());
    EXPECT_GE(distance_m, o.tracker_distance_min_m);
    EXPECT_LE(distance_m, o.tracker_distance_max_m);
    EXPECT_LE(std::abs(std::atan2(p.y(), p.x())), 60.0 * kRadPerDeg);
    EXPECT_GE(p.z(), 0.8);
    EXPECT_LE(p.z(), 1.6);
    // Levelled: ±2° about x and y tilt its z axis by at most acos(cos² 2°) < √2 · 2°.
    const Vec3 z_TrackerInBase = robot.X_TrackerBase().linear().transpose().col(2);
    EXPECT_LE(std::acos(z_TrackerInBase.z()), std::sqrt(2.0) * 2.0 * kRadPerDeg);

    // truth.json rebuilds the station's tracker.
    const TwinRobot copy = TwinRobot::fromTruthJson(nlohmann::json::parse(truth.dump()));
    EXPECT_EQ(copy.X_TrackerBase().matrix(), robot.X_TrackerBase().matrix());
    EXPECT_EQ(copy.truthJson(), truth);

    // Other poses, other noise: no row has another station's joint angles or temperature
    // reading.
    const Campaign& c = campaigns[k];
    ASSERT_EQ(c.rows.size(), 130u);
    for (size_t other = 0; other < k; ++other) {
      const Campaign& d = campaigns[other];
      ASSERT_EQ(d.rows.size(), c.rows.size());
      int same_q = 0, same_temp = 0;
      for (size_t i = 0; i < c.rows.size(); ++i) {
        same_q += c.rows[i].q_rad == d.rows[i].q_rad;
        same_temp += *c.rows[i].temp_c == *d.rows[i].temp_c;
      }
      EXPECT_EQ(same_q, 0) << "station " << other;
      EXPECT_EQ(same_temp, 0) << "station " << other;
    }
    // Each row is the robot seen from this station, noise apart (6 σ).
    for (size_t i = 0; i < c.rows.size(); i += 11) {
      const Measurement& m = c.rows[i];
      const Pose X_TrackerTip = robot.X_TrackerTip(m.q_rad, m.load_kg, defaultProfile_c(m.seq));
      EXPECT_LT((m.p_TipInTracker_m - X_TrackerTip.translation()).norm(),
                6 * o.tracker_position_sigma_m * std::sqrt(3.0))
          << "row " << i;
    }
    // The random campaign's pose list is the station's own too.
    EXPECT_NE(randomPoseList(options[k], 5, {0.0}).front().q_rad,
              randomPoseList(options[0], 5, {0.0}).front().q_rad);
  }
}

TEST(Twin, StationZeroIsTheSeedsOwnCampaignAndANegativeOneIsRefused) {
  TwinOptions o = paperOptions(12);
  o.protocol = "geometry";
  TwinOptions zero = o;
  zero.station = 0;
  nlohmann::json truth_default, truth_zero;
  const Campaign a = simulateCampaign(o, &truth_default);
  const Campaign b = simulateCampaign(zero, &truth_zero);
  expectSameRows(a, b, test::DoubleMatch::kSameBits);
  EXPECT_EQ(truth_default, truth_zero);
  EXPECT_EQ(truth_default.at("options").at("station"), 0);

  o.station = -1;
  try {
    simulateCampaign(o, nullptr);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("TwinOptions.station = -1; expected a tracker station >= 0"),
              std::string::npos)
        << what;
  }
  EXPECT_THROW(TwinRobot{o}, InputError);
}

}  // namespace
}  // namespace stepcal::twin
