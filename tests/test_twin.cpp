// The simulated robot: reproducibility, the paper's protocol, the noiseless nominal case, the
// compliance fixed point against its linearisation, the F/T reading, truth.json round trips,
// noise statistics, and the size of the errors an uncalibrated model would make.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
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
    EXPECT_NEAR(*m.temp_c, 20.0, 0.5);
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
  for (const Measurement& m : c.rows) EXPECT_GE(std::abs(m.q_rad(4)), 15.0 * kDegToRad);

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
    EXPECT_EQ(*m.temp_c, 20.0);
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
    // METHOD.md eq. 17: ΔX = J K⁻¹ Jᵀ F.
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
      sum_deg += lie::angleBetween(X0.linear(), X.linear()) / kDegToRad;
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
                1e3 * worst_p, sum_r / n / kDegToRad, worst_r / kDegToRad);
  }
  if (max_mm) *max_mm = 1e3 * worst_p;
  return {1e3 * sum_p / n, sum_r / n / kDegToRad};
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

/// One of each hidden mechanism, at a size a tracker sees.
std::vector<nlohmann::json> everyHiddenEffect() {
  return {{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", 2e-4}},
          {{"name", "transmission_error"}, {"joint", 3}, {"harmonic", 2}, {"sin_rad", 1e-4},
           {"cos_rad", -5e-5}},
          {{"name", "nonlinear_stiffness"}, {"joint", 4}, {"extra_compliance_rad_per_nm", 4e-6},
           {"saturation_torque_nm", 40.0}},
          {{"name", "joint_coupling"}, {"joints", {4, 6}}, {"ratio", 2e-3}}};
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
  EXPECT_LT((delta(*linkAngleEffectFromJson(specs[0], 6)) - expected).norm(), 1e-15);
  EXPECT_NEAR(expected(1), -2e-4, 1e-18);
  expected.setZero();
  expected(2) = 1e-4 * std::sin(2 * 1.1) - 5e-5 * std::cos(2 * 1.1);
  EXPECT_LT((delta(*linkAngleEffectFromJson(specs[1], 6)) - expected).norm(), 1e-15);
  expected.setZero();
  expected(3) = 4e-6 * -30.0 * 40.0 / (40.0 + 30.0);
  EXPECT_LT((delta(*linkAngleEffectFromJson(specs[2], 6)) - expected).norm(), 1e-15);
  expected.setZero();
  expected(5) = 2e-3 * 2.5;
  EXPECT_LT((delta(*linkAngleEffectFromJson(specs[3], 6)) - expected).norm(), 1e-15);

  // Nonlinear stiffness: the slope of Δθ in τ is c at zero torque and falls with |τ| (softer at
  // small torque), checked by central differences.
  const auto nonlinear = linkAngleEffectFromJson(specs[2], 6);
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
      {{{"name", "gear_wobble"}}, "unknown link-angle effect 'gear_wobble'"},
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

}  // namespace
}  // namespace stepcal::twin
