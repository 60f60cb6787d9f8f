// The twin of a calibrated robot (model_twin.hpp) on simulated campaigns: without noise it is the
// model's physical layer as the trainer evaluates it, row by row (a calibrated model with its
// compliance, and an extended one with its mechanisms); planned payloads read their weight at the
// pose they deflect the arm to; the noise is the campaign's stated one; bad input is refused
// naming what is wrong.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/model_twin.hpp"
#include "stepcal/twin/twin.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

const std::string kRobots = STEPCAL_ROBOTS_DIR;

template <typename Call>
void expectRefused(Call&& call, const std::vector<std::string>& parts) {
  const std::string what = test::refusalOf(std::forward<Call>(call)).what;
  for (const std::string& part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
}

/// A simulated IRB4400 campaign (paper protocol, seed 3, a backlash on joint 2) written into
/// dir/campaign, its calibrated model (poe + stiffness + GPR) and, when asked, its extended one
/// (diagnose, which names the backlash) written beside it.
struct Calibrated {
  std::string campaign_dir, model_path, extended_path;
  Campaign campaign;
  CalibratedModel model, extended;
};

Calibrated calibrated(const test::TempDir& dir, bool extended = false) {
  twin::TwinOptions o;
  o.urdf_path = kRobots + "/irb4400.urdf";
  o.seed = 3;
  o.hidden_effects = {{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", 2e-4}}};
  Calibrated c;
  c.campaign_dir = (dir.path() / "campaign").string();
  twin::writeSimulation(o, c.campaign_dir);
  c.campaign = readCampaign(c.campaign_dir);
  c.model = trainer::modelFromOutcome(c.campaign, trainer::calibrateCampaign(c.campaign));
  c.model_path = (dir.path() / "model.stepcal").string();
  writeModelFile(c.model, c.model_path);
  if (extended) {
    c.extended = trainer::diagnose(c.campaign, c.model).extended_model;
    c.extended_path = (dir.path() / "extended.stepcal").string();
    writeModelFile(c.extended, c.extended_path);
  }
  return c;
}

twin::ModelTwinOptions noiseless(const std::string& model_path, const std::string& campaign_dir) {
  twin::ModelTwinOptions o;
  o.model_path = model_path;
  o.campaign_dir = campaign_dir;
  o.tracker_position_sigma_m = 0.0;
  o.tracker_orientation_sigma_rad = 0.0;
  o.ft_force_sigma_n = 0.0;
  o.ft_moment_sigma_nm = 0.0;
  return o;
}

TEST(ModelTwin, NoiselessItIsTheModelsPhysicalLayer) {
  const test::TempDir dir;
  const Calibrated c = calibrated(dir, true);
  ASSERT_FALSE(c.extended.mechanisms.empty());
  for (const auto& [path, model, layer] :
       {std::make_tuple(c.model_path, c.model, std::string(trainer::kMethodPoeStiffness)),
        std::make_tuple(c.extended_path, c.extended, std::string(trainer::kMethodExtended))}) {
    const Campaign twin = twin::simulateFromModel(noiseless(path, c.campaign_dir), nullptr);
    trainer::PoseModel predict;
    for (const auto& [name, pose_model] : trainer::modelLayers(model)) {
      if (name == layer) predict = pose_model;
    }
    ASSERT_TRUE(predict) << layer;
    ASSERT_EQ(twin.rows.size(), c.campaign.rows.size());
    EXPECT_EQ(twin.urdf_xml, c.campaign.urdf_xml);
    EXPECT_EQ(twin.sensor_link, "ft_sensor");
    EXPECT_FALSE(twin.tracker.stated);  // zero noise is no statement
    double worst_m = 0.0, worst_rad = 0.0;
    for (size_t i = 0; i < twin.rows.size(); ++i) {
      const Measurement& t = twin.rows[i];
      const Measurement& r = c.campaign.rows[i];
      // The campaign's rows as they were, only the tracker's reading replaced.
      EXPECT_EQ(t.seq, r.seq);
      EXPECT_EQ(t.pose_id, r.pose_id);
      EXPECT_EQ(t.set, r.set);
      EXPECT_EQ(t.q_rad, r.q_rad);
      EXPECT_EQ(t.wrench_Sensor, r.wrench_Sensor);
      EXPECT_EQ(t.temp_c, r.temp_c);
      const Pose X = predict(t);
      worst_m = std::max(worst_m, (X.translation() - t.p_TipInTracker_m).norm());
      worst_rad = std::max(
          worst_rad, lie::logSO3(X.linear().transpose() * t.q_TrackerTip.toRotationMatrix()).norm());
    }
    EXPECT_LT(worst_m, 1e-12) << layer;
    EXPECT_LT(worst_rad, 1e-12) << layer;
    // The model moves the tip by millimetres under load: the rows are no copy of the real ones.
    EXPECT_GT((twin.rows.back().p_TipInTracker_m - c.campaign.rows.back().p_TipInTracker_m).norm(),
              1e-6);
  }
}

TEST(ModelTwin, PlannedPayloadsReadTheirWeightAtTheDeflectedPose) {
  const test::TempDir dir;
  const Calibrated c = calibrated(dir);
  twin::ModelTwinOptions o = noiseless(c.model_path, c.campaign_dir);
  std::vector<JointVector> q = {c.campaign.rows[0].q_rad, c.campaign.rows[1].q_rad};
  o.planned_fit_rows = {{"p0", 0.0, q[0], 2}, {"p1", 0.0, q[1], 3}, {"p0", 40.0, q[0], 4},
                        {"p1", 40.0, q[1], 5}};
  o.p_CoGInSensor_m = Vec3(0.05, 0.0, 0.2);
  const Campaign twin = twin::simulateFromModel(o, nullptr);
  const size_t validation = c.campaign.rowsIn(RowSet::kValidation).size();
  ASSERT_EQ(twin.rows.size(), 4 + validation);
  const twin::ModelTwin robot(c.model);
  for (size_t i = 0; i < twin.rows.size(); ++i) {
    const Measurement& m = twin.rows[i];
    EXPECT_EQ(m.seq, static_cast<int64_t>(i + 1));
    EXPECT_EQ(m.set, i < 2 ? RowSet::kGeometry : i < 4 ? RowSet::kStiffness : RowSet::kValidation);
    ASSERT_TRUE(m.has_wrench);
    if (i >= 4) continue;
    // The reading is the payload's weight in sensor axes at the pose the arm deflects to.
    const double load_kg = m.load_kg;
    EXPECT_NEAR(m.wrench_Sensor.head<3>().norm(), load_kg * 9.80665, 1e-9);
    EXPECT_LT((m.wrench_Sensor.tail<3>() - o.p_CoGInSensor_m.cross(m.wrench_Sensor.head<3>()))
                  .norm(),
              1e-12);
    ChainWorkspace ws;
    JointVector theta, tau;
    const PhysicalModel& physical = robot.physical();
    physicalLinkAngles(physical, m.q_rad, m.wrench_Sensor, *m.temp_c, {ws, theta, tau});
    const Vec3 g_Sensor = framePose(physical.chain_Tracker, ws, physical.sensor_frame).linear().transpose() *
                          physical.gravity_Tracker;
    EXPECT_LT((m.wrench_Sensor.head<3>() - load_kg * g_Sensor).norm(), 1e-9 * (1 + load_kg));
    EXPECT_TRUE((robot.X_TrackerTip(m.q_rad, m.wrench_Sensor, *m.temp_c).translation() -
                 m.p_TipInTracker_m).norm() < 1e-12);
  }
  // The payload deflects the arm: loaded and unloaded rows of one pose differ by the deflection.
  EXPECT_GT((twin.rows[2].p_TipInTracker_m - twin.rows[0].p_TipInTracker_m).norm(), 1e-4);
  // Measured at the campaign's mean temperature.
  double mean_c = 0.0;
  for (const Measurement& row : c.campaign.rows) mean_c += *row.temp_c;
  EXPECT_NEAR(*twin.rows[0].temp_c, mean_c / static_cast<double>(c.campaign.rows.size()), 1e-9);
}

TEST(ModelTwin, AnOffAxisComplianceIsSwitchedOnAtARealisticSize) {
  // A base bearing 6e6 N·m/rad stiff across joint 1's axis: it moves the loaded rows by a tenth
  // of a millimetre or two, the unloaded ones only by their reading's noise.
  const test::TempDir dir;
  const Calibrated c = calibrated(dir);
  twin::ModelTwinOptions o = noiseless(c.model_path, c.campaign_dir);
  const Campaign plain = twin::simulateFromModel(o, nullptr);
  o.off_axis_compliance = {{0, 1.7e-7}};
  nlohmann::json truth;
  const Campaign tilted = twin::simulateFromModel(o, &truth);
  ASSERT_EQ(plain.rows.size(), tilted.rows.size());
  double sum_m = 0.0, largest_m = 0.0, largest_unloaded_m = 0.0;
  int loaded_55 = 0;
  for (size_t i = 0; i < plain.rows.size(); ++i) {
    const double moved_m = (tilted.rows[i].p_TipInTracker_m - plain.rows[i].p_TipInTracker_m).norm();
    if (plain.rows[i].load_kg == 0.0) {
      largest_unloaded_m = std::max(largest_unloaded_m, moved_m);
    } else if (plain.rows[i].load_kg == 55.0) {
      sum_m += moved_m;
      ++loaded_55;
    }
    largest_m = std::max(largest_m, moved_m);
  }
  ASSERT_GT(loaded_55, 0);
  const double mean_55_m = sum_m / loaded_55;
  EXPECT_GT(mean_55_m, 0.05e-3);
  EXPECT_LT(largest_m, 1e-3);
  EXPECT_LT(largest_unloaded_m, 0.01 * mean_55_m);
  std::printf("[ off_axis ] joint 1, 1.7e-7 rad/(N·m): 55 kg rows move by %.3f mm mean, %.3f mm "
              "at most, unloaded ones %.2g mm at most\n",
              1e3 * mean_55_m, 1e3 * largest_m, 1e3 * largest_unloaded_m);
  EXPECT_EQ(truth.at("added_mechanisms").at(0).at("joint"), 1);
  // Not a tilt against the moment, and not a second one on a joint.
  o.off_axis_compliance = {{0, -1e-7}};
  expectRefused([&] { twin::simulateFromModel(o, nullptr); }, {"off_axis_compliance", "≥ 0"});
  o.off_axis_compliance = {{0, 1e-7}, {0, 2e-7}};
  expectRefused([&] { twin::simulateFromModel(o, nullptr); }, {"holds one already"});
}

TEST(ModelTwin, AToolMountIsSwitchedOnAtARealisticSize) {
  // A mount 5e6 N/m stiff along the sensor's z: the loaded rows move by a few hundredths of a
  // millimetre, at most c times the 55 kg payload's weight; the unloaded ones not at all.
  const test::TempDir dir;
  const Calibrated c = calibrated(dir);
  twin::ModelTwinOptions o = noiseless(c.model_path, c.campaign_dir);
  const Campaign plain = twin::simulateFromModel(o, nullptr);
  o.tool_mount_compliance_m_per_n = 2e-7;
  nlohmann::json truth;
  const Campaign mounted = twin::simulateFromModel(o, &truth);
  ASSERT_EQ(plain.rows.size(), mounted.rows.size());
  double sum_m = 0.0, largest_m = 0.0, largest_unloaded_m = 0.0;
  int loaded_55 = 0;
  for (size_t i = 0; i < plain.rows.size(); ++i) {
    const double moved_m =
        (mounted.rows[i].p_TipInTracker_m - plain.rows[i].p_TipInTracker_m).norm();
    if (plain.rows[i].load_kg == 0.0) {
      largest_unloaded_m = std::max(largest_unloaded_m, moved_m);
    } else if (plain.rows[i].load_kg == 55.0) {
      sum_m += moved_m;
      ++loaded_55;
    }
    largest_m = std::max(largest_m, moved_m);
  }
  ASSERT_GT(loaded_55, 0);
  const double mean_55_m = sum_m / loaded_55;
  EXPECT_GT(mean_55_m, 0.01e-3);
  // The reading's force is the payload's weight plus its noise (0.2 N): c · 55 kg · g, and 1 %.
  EXPECT_LT(largest_m, 1.01 * 2e-7 * 55.0 * 9.81);
  EXPECT_LT(largest_unloaded_m, 0.01 * mean_55_m);
  std::printf("[ tool_mount ] 2e-7 m/N: 55 kg rows move by %.4f mm mean, %.4f mm at most, "
              "unloaded ones %.2g mm at most\n",
              1e3 * mean_55_m, 1e3 * largest_m, 1e3 * largest_unloaded_m);
  EXPECT_EQ(truth.at("added_mechanisms").at(0).at("name"), "tool_mount_compliance");
  // Not a mount that moves against its force.
  o.tool_mount_compliance_m_per_n = -1e-7;
  expectRefused([&] { twin::simulateFromModel(o, nullptr); }, {"tool_mount_compliance", "≥ 0"});
}

TEST(ModelTwin, NoiseIsTheCampaignsStatedNoiseAndTheSeedsOwn) {
  const test::TempDir dir;
  const Calibrated c = calibrated(dir);
  twin::ModelTwinOptions o;
  o.model_path = c.model_path;
  o.campaign_dir = c.campaign_dir;
  o.seed = 5;
  nlohmann::json truth;
  const Campaign noisy = twin::simulateFromModel(o, &truth);
  const Campaign clean = twin::simulateFromModel(noiseless(c.model_path, c.campaign_dir), nullptr);
  EXPECT_TRUE(noisy.tracker.stated);
  EXPECT_EQ(noisy.tracker.position_sigma_m, c.campaign.tracker.position_sigma_m);
  EXPECT_EQ(noisy.tracker.orientation_sigma_rad, c.campaign.tracker.orientation_sigma_rad);
  EXPECT_EQ(truth.at("format"), "stepcal-model-twin/1");
  EXPECT_EQ(truth.at("seed"), 5);
  double sum_p = 0.0, sum_r = 0.0;
  for (size_t i = 0; i < noisy.rows.size(); ++i) {
    sum_p += (noisy.rows[i].p_TipInTracker_m - clean.rows[i].p_TipInTracker_m).squaredNorm();
    sum_r += lie::logSO3(clean.rows[i].q_TrackerTip.toRotationMatrix().transpose() *
                         noisy.rows[i].q_TrackerTip.toRotationMatrix())
                 .squaredNorm();
  }
  const double axes = 3.0 * static_cast<double>(noisy.rows.size());  // 3210 draws each
  // The sample σ of 3210 normal draws is within 5 % of σ with probability 1 − 1e-8.
  EXPECT_NEAR(std::sqrt(sum_p / axes) / c.campaign.tracker.position_sigma_m, 1.0, 0.05);
  EXPECT_NEAR(std::sqrt(sum_r / axes) / c.campaign.tracker.orientation_sigma_rad, 1.0, 0.05);

  const Campaign again = twin::simulateFromModel(o, nullptr);
  EXPECT_EQ(again.rows.back().p_TipInTracker_m, noisy.rows.back().p_TipInTracker_m);
  o.seed = 6;
  EXPECT_NE(twin::simulateFromModel(o, nullptr).rows.back().p_TipInTracker_m,
            noisy.rows.back().p_TipInTracker_m);
  // Given noise overrides the campaign's.
  o.tracker_position_sigma_m = 1e-3;
  EXPECT_EQ(twin::simulateFromModel(o, nullptr).tracker.position_sigma_m, 1e-3);
}

TEST(ModelTwin, BadInputIsRefusedWithWhatWasExpected) {
  const test::TempDir dir;
  const Calibrated c = calibrated(dir);
  twin::ModelTwinOptions o;
  o.model_path = (dir.path() / "campaign" / "campaign.yaml").string();  // no model file
  o.campaign_dir = c.campaign_dir;
  expectRefused([&] { twin::simulateFromModel(o, nullptr); },
                {"campaign.yaml", "not a stepcal model file"});

  // A model of another robot: the UR10's twin measured, the IRB4400's model.
  twin::TwinOptions ur10 = twin::twinOptionsForRobot(kRobots + "/ur10.urdf", "base_link", "tool0", "");
  const std::string ur10_dir = (dir.path() / "ur10").string();
  twin::writeSimulation(ur10, ur10_dir);
  o.model_path = c.model_path;
  o.campaign_dir = ur10_dir;
  expectRefused([&] { twin::simulateFromModel(o, nullptr); },
                {"model.stepcal", "the model's joints (joint_1, joint_2",
                 "are not the campaign's (shoulder_pan_joint", "base_link -> tool0"});

  // No stated noise, none given.
  Campaign unstated = c.campaign;
  unstated.tracker.stated = false;
  const std::string unstated_dir = (dir.path() / "unstated").string();
  writeCampaign(unstated, unstated_dir);
  o.campaign_dir = unstated_dir;
  expectRefused([&] { twin::simulateFromModel(o, nullptr); },
                {"unstated", "the campaign states no tracker noise",
                 "--tracker-position-sigma-mm"});
  o.tracker_position_sigma_m = -1.0;
  o.tracker_orientation_sigma_rad = 1e-4;
  expectRefused([&] { twin::simulateFromModel(o, nullptr); },
                {"tracker position noise -1", "expected a finite 1-sigma >= 0"});

  // A payload on the model of a robot without a sensor.
  const Campaign ur10_campaign = readCampaign(ur10_dir);
  const CalibratedModel ur10_model =
      trainer::modelFromOutcome(ur10_campaign, trainer::calibrateCampaign(ur10_campaign));
  const std::string ur10_model_path = (dir.path() / "ur10.stepcal").string();
  writeModelFile(ur10_model, ur10_model_path);
  twin::ModelTwinOptions loaded;
  loaded.model_path = ur10_model_path;
  loaded.campaign_dir = ur10_dir;
  loaded.planned_fit_rows = {{"p0", 0.0, ur10_campaign.rows[0].q_rad, 2},
                             {"p0", 10.0, ur10_campaign.rows[0].q_rad, 3}};
  const test::Refusal refusal = test::refusalOf([&] { twin::simulateFromModel(loaded, nullptr); });
  EXPECT_EQ(refusal.line, 3);
  EXPECT_NE(refusal.what.find("pose 'p0' at 10"), std::string::npos) << refusal.what;
  EXPECT_NE(refusal.what.find("the model has no F/T sensor frame"), std::string::npos);
  loaded.planned_fit_rows = {{"p0", 0.0, JointVector::Zero(5), 2}};
  expectRefused([&] { twin::simulateFromModel(loaded, nullptr); },
                {"a planned row has 5 joint angles; expected 6"});

  // The model's own campaign, gone.
  CalibratedModel moved = ur10_model;
  moved.provenance.campaign_path = (dir.path() / "gone").string();
  writeModelFile(moved, ur10_model_path);
  loaded.campaign_dir.clear();
  loaded.planned_fit_rows.clear();
  expectRefused([&] { twin::simulateFromModel(loaded, nullptr); },
                {"ur10.stepcal", "gone' (from its provenance) is not there", "--campaign DIR"});
}

}  // namespace
}  // namespace stepcal
