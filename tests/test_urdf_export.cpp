// The calibrated URDF (urdf_export.hpp): read back by stepcal's loader and by urdfdom with a
// forward kinematics built here from its joints, it gives the model's chain to 1e-9 m and rad;
// check_urdf accepts it; `stepcal export urdf` writes it and refuses bad input by file name.
#include <gtest/gtest.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/common/urdf_export.hpp"
#include "support/command.hpp"
#include "support/files.hpp"
#include "support/input_error.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

const std::string kStepcal = std::string(STEPCAL_BIN_DIR) + "/stepcal";
constexpr double kTolerance = 1e-9;  // m and rad

RobotDescription shippedRobot(const std::string& name, const std::string& tip_link) {
  const std::string path = std::string(STEPCAL_ROBOTS_DIR) + "/" + name + ".urdf";
  return {readTextFile(path), "base_link", tip_link, path};
}

KinematicChain nominalChain(const RobotDescription& robot) {
  return chainFromUrdf(robot.urdf_xml, robot.base_link, robot.tip_link, {}, robot.source);
}

// A model shaped as `stepcal calibrate` writes one, without calibrating: every initial pose of
// the nominal chain corrected by a few mm and mrad, rooted at the tracker.
CalibratedModel calibratedLike(const KinematicChain& nominal_Base, const Pose& X_TrackerBase,
                               uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd delta(6 * (nominal_Base.dof() + 1));
  for (Eigen::Index i = 0; i < delta.size(); ++i) delta(i) = (i % 6 < 3 ? 2e-3 : 3e-3) * g(rng);
  CalibratedModel model;
  model.nominal_Base = nominal_Base;
  model.X_TrackerBase = X_TrackerBase;
  model.chain_Tracker = nominal_Base.corrected(delta).rerooted(X_TrackerBase);
  return model;
}

Pose trackerPose(const Vec3& rpy_rad, const Vec3& p_m) {
  Pose X = Pose::Identity();
  X.linear() = lie::rotationFromRpy(rpy_rad.x(), rpy_rad.y(), rpy_rad.z());
  X.translation() = p_m;
  return X;
}

// Identity, every joint at ±π and just short of it, alternating signs near π, then random
// angles over two turns.
std::vector<JointVector> testPoses(int dof, uint64_t seed) {
  std::vector<JointVector> poses;
  for (const double q : {0.0, kPi, -kPi, kPi - 1e-7, -(kPi - 1e-9)}) {
    poses.push_back(JointVector::Constant(dof, q));
  }
  JointVector alternating(dof);
  for (int j = 0; j < dof; ++j) alternating(j) = (j % 2 ? -1.0 : 1.0) * (kPi - 1e-6);
  poses.push_back(alternating);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-2 * kPi, 2 * kPi);
  for (int i = 0; i < 500; ++i) {
    JointVector q(dof);
    for (int j = 0; j < dof; ++j) q(j) = u(rng);
    poses.push_back(q);
  }
  return poses;
}

// Tip pose from urdfdom's parsed joints, root to tip: each joint's origin, then for a revolute
// one the turn about its axis by the angle of the model's joint of that name.
Pose urdfdomTipPose(const urdf::ModelInterface& robot, const std::string& tip,
                    const std::vector<ChainJoint>& chain_joints, const JointVector& q) {
  std::vector<urdf::JointConstSharedPtr> tip_to_root;
  for (urdf::LinkConstSharedPtr link = robot.getLink(tip); link->parent_joint;
       link = robot.getLink(link->parent_joint->parent_link_name)) {
    tip_to_root.push_back(link->parent_joint);
  }
  Pose X = Pose::Identity();
  for (auto joint = tip_to_root.rbegin(); joint != tip_to_root.rend(); ++joint) {
    const urdf::Pose& origin = (*joint)->parent_to_joint_origin_transform;
    X = X * Eigen::Translation3d(origin.position.x, origin.position.y, origin.position.z) *
        Eigen::Quaterniond(origin.rotation.w, origin.rotation.x, origin.rotation.y,
                           origin.rotation.z);
    if ((*joint)->type != urdf::Joint::REVOLUTE) continue;
    const auto same_name = [&](const ChainJoint& c) { return c.name == (*joint)->name; };
    const auto index = std::find_if(chain_joints.begin(), chain_joints.end(), same_name) -
                       chain_joints.begin();
    const Vec3 axis((*joint)->axis.x, (*joint)->axis.y, (*joint)->axis.z);
    X = X * Eigen::AngleAxisd(q(index), axis.normalized());
  }
  return X;
}

struct PoseErrors {
  double max_position_m = 0, max_orientation_rad = 0;
};

// Largest distance of tip_pose(q) from the model chain's tip over the poses.
template <typename TipPose>
PoseErrors maxErrors(const KinematicChain& chain, const std::vector<JointVector>& poses,
                     const TipPose& tip_pose) {
  PoseErrors e;
  ChainWorkspace ws;
  for (const JointVector& q : poses) {
    forwardKinematics(chain, q, ws);
    const Pose X = tip_pose(q);
    e.max_position_m =
        std::max(e.max_position_m, (X.translation() - tipPose(ws).translation()).norm());
    e.max_orientation_rad =
        std::max(e.max_orientation_rad, lie::angleBetween(X.linear(), tipPose(ws).linear()));
  }
  return e;
}

// Expects the URDF's world → tool through stepcal's loader and through urdfdom to be the
// model's chain on every test pose.
void expectSameKinematics(const CalibratedModel& model, const std::string& urdf_xml,
                          const std::string& label) {
  const std::vector<JointVector> poses = testPoses(model.chain_Tracker.dof(), 7);
  const KinematicChain loaded = chainFromUrdf(urdf_xml, kUrdfWorldLink, kUrdfToolLink);
  const PoseErrors own = maxErrors(model.chain_Tracker, poses, [&](const JointVector& q) {
    ChainWorkspace ws;
    forwardKinematics(loaded, q, ws);
    return tipPose(ws);
  });
  const urdf::ModelInterfaceSharedPtr parsed = urdf::parseURDF(urdf_xml);
  ASSERT_TRUE(parsed);
  EXPECT_EQ(parsed->getRoot()->name, kUrdfWorldLink);
  const PoseErrors dom = maxErrors(model.chain_Tracker, poses, [&](const JointVector& q) {
    return urdfdomTipPose(*parsed, kUrdfToolLink, model.chain_Tracker.joints(), q);
  });
  std::cout << label << ": max error over " << poses.size() << " poses, stepcal loader "
            << own.max_position_m << " m / " << own.max_orientation_rad << " rad, urdfdom "
            << dom.max_position_m << " m / " << dom.max_orientation_rad << " rad\n";
  EXPECT_LE(own.max_position_m, kTolerance);
  EXPECT_LE(own.max_orientation_rad, kTolerance);
  EXPECT_LE(dom.max_position_m, kTolerance);
  EXPECT_LE(dom.max_orientation_rad, kTolerance);
}

TEST(UrdfExport, Irb4400ForwardKinematicsIsTheModelsChain) {
  const RobotDescription robot = shippedRobot("irb4400", "tmac");
  const CalibratedModel model =
      calibratedLike(nominalChain(robot), trackerPose({0.02, -0.01, 2.4}, {3.1, -1.7, 0.4}), 1);
  expectSameKinematics(model, calibratedUrdf(model, "model.stepcal", robot).urdf_xml, "irb4400");
}

TEST(UrdfExport, Ur10KeepsItsInertialsAndLimitsWithATrackerNearGimbalLock) {
  // The base tilted to 1e-8 rad short of pitch π/2 in the tracker: rpy must still be exact.
  const RobotDescription robot = shippedRobot("ur10", "tool0");
  const CalibratedModel model = calibratedLike(
      nominalChain(robot), trackerPose({0.3, kPi / 2 - 1e-8, -1.2}, {-2.0, 3.0, 0.7}), 2);
  const std::string urdf_xml = calibratedUrdf(model, "model.stepcal", robot).urdf_xml;
  expectSameKinematics(model, urdf_xml, "ur10");
  const urdf::ModelInterfaceSharedPtr original = urdf::parseURDF(robot.urdf_xml);
  const urdf::ModelInterfaceSharedPtr exported = urdf::parseURDF(urdf_xml);
  ASSERT_TRUE(exported);
  for (const auto& [name, link] : original->links_) {
    const urdf::LinkConstSharedPtr kept = exported->getLink(name);
    ASSERT_TRUE(kept) << name;
    ASSERT_EQ(!link->inertial, !kept->inertial) << name;
    if (link->inertial) {
      EXPECT_EQ(kept->inertial->mass, link->inertial->mass) << name;
    }
  }
  const urdf::JointConstSharedPtr elbow = exported->getJoint("elbow_joint");
  ASSERT_TRUE(elbow && elbow->limits);
  EXPECT_EQ(elbow->limits->lower, -3.1416);
  EXPECT_EQ(elbow->limits->effort, 150.0);
}

TEST(UrdfExport, TwistOffItsFrameAndAskewMapsOntoOriginAndAxis) {
  // Rotations about lines that miss the joint frames' origins, in no coordinate direction.
  const RobotDescription robot = shippedRobot("irb4400", "tmac");
  CalibratedModel model =
      calibratedLike(nominalChain(robot), trackerPose({0.0, 0.0, 0.5}, {1.0, 2.0, 0.0}), 3);
  std::vector<ChainJoint> joints = model.chain_Tracker.joints();
  for (size_t j = 0; j < joints.size(); ++j) {
    const Vec3 w = (joints[j].twist_Local.tail<3>() + Vec3(0.1, -0.2, 0.05)).normalized();
    const Vec3 p_AxisInJoint_m(0.01 * static_cast<double>(j), -0.02, 0.03);
    joints[j].twist_Local.head<3>() = p_AxisInJoint_m.cross(w);
    joints[j].twist_Local.tail<3>() = w;
  }
  model.chain_Tracker = KinematicChain(joints, model.chain_Tracker.initialPoses());
  const CalibratedUrdf urdf = calibratedUrdf(model, "model.stepcal", robot);
  EXPECT_NE(urdf.urdf_xml.find("link_3_on_axis"), std::string::npos);
  expectSameKinematics(model, urdf.urdf_xml, "offset twists");
}

TEST(UrdfExport, LinksAboveTheBaseGiveWayToTheTrackerWorld) {
  RobotDescription robot = shippedRobot("irb4400", "tmac");
  robot.urdf_xml.insert(robot.urdf_xml.rfind("</robot>"),
                        "<link name=\"world\"/><link name=\"pedestal\"/>"
                        "<joint name=\"world-pedestal\" type=\"fixed\"><parent link=\"world\"/>"
                        "<child link=\"pedestal\"/><origin xyz=\"0 0 0.5\"/></joint>"
                        "<joint name=\"pedestal-base\" type=\"fixed\"><parent link=\"pedestal\"/>"
                        "<child link=\"base_link\"/></joint>");
  const CalibratedModel model =
      calibratedLike(nominalChain(robot), trackerPose({0.0, 0.1, -0.3}, {2.0, 0.0, -0.5}), 4);
  const CalibratedUrdf urdf = calibratedUrdf(model, "model.stepcal", robot);
  EXPECT_EQ(urdf.dropped_links, (std::vector<std::string>{"pedestal", "world"}));
  EXPECT_EQ(urdf.urdf_xml.find("pedestal"), std::string::npos);
  expectSameKinematics(model, urdf.urdf_xml, "links above the base");
}

TEST(UrdfExport, CheckUrdfAcceptsIt) {
  if (test::run("command -v check_urdf").status != 0) {
    GTEST_SKIP() << "check_urdf is not installed (Debian package liburdfdom-tools)";
  }
  const RobotDescription robot = shippedRobot("irb4400", "tmac");
  const CalibratedModel model =
      calibratedLike(nominalChain(robot), trackerPose({0.02, -0.01, 2.4}, {3.1, -1.7, 0.4}), 5);
  test::TempDir dir;
  const fs::path file = dir.path() / "robot_calibrated.urdf";
  test::writeText(file, calibratedUrdf(model, "model.stepcal", robot).urdf_xml);
  const test::CommandResult r = test::run("check_urdf " + file.string());
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("Successfully Parsed XML"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("root Link: world has 1 child(ren)"), std::string::npos) << r.out;
}

TEST(UrdfExport, RefusesWhatAUrdfCannotHoldAndAnotherRobot) {
  const RobotDescription irb = shippedRobot("irb4400", "tmac");
  const CalibratedModel model = calibratedLike(nominalChain(irb), Pose::Identity(), 6);

  CalibratedModel pitched = model;
  std::vector<ChainJoint> joints = model.chain_Tracker.joints();
  joints[1].twist_Local.head<3>() = 1e-6 * joints[1].twist_Local.tail<3>();
  pitched.chain_Tracker = KinematicChain(joints, model.chain_Tracker.initialPoses());
  test::expectInputError([&] { calibratedUrdf(pitched, "model.stepcal", irb); }, "model.stepcal",
                         0, "", {"joint 'joint_2'", "pitch", "1e-06 m/rad", "expected 0"});

  CalibratedModel extended = model;
  extended.mechanisms.emplace_back();
  test::expectInputError([&] { calibratedUrdf(extended, "model.stepcal", irb); }, "model.stepcal",
                         0, "", {"extended model", "stepcal calibrate"});

  const RobotDescription ur10 = shippedRobot("ur10", "tool0");
  test::expectInputError([&] { calibratedUrdf(model, "model.stepcal", ur10); }, "ur10.urdf", 0, "",
                         {"joint 1 of the chain is 'shoulder_pan_joint', the model's 'joint_1'",
                          "calibrated from"});

  RobotDescription moved = irb;
  moved.urdf_xml.replace(moved.urdf_xml.find("0.200 0 0.680"), 13, "0.201 0 0.680");
  test::expectInputError([&] { calibratedUrdf(model, "model.stepcal", moved); }, "irb4400.urdf", 0,
                         "",
                         {"joint 'joint_2'", "differs from the model's nominal chain by 0.001"});

  RobotDescription taken = irb;
  taken.urdf_xml.insert(taken.urdf_xml.rfind("</robot>"),
                        "<link name=\"tool\"/><joint name=\"tmac-gripper\" type=\"fixed\">"
                        "<parent link=\"tmac\"/><child link=\"tool\"/></joint>");
  test::expectInputError([&] { calibratedUrdf(model, "model.stepcal", taken); }, "irb4400.urdf", 0,
                         "", {"already has a link 'tool'"});
}

// ---------------------------------------------------------------------------------------------
// The command

// The twin's geometry protocol simulated into dir/campaign and calibrated into dir/model.stepcal
// (the model's path).
// A geometry campaign with a self weight hidden in it, calibrated: the geometric model leaves
// a residual the GPR learns, so the model has a poe+gpr layer.
std::string calibratedSimulation(const fs::path& dir, int seed) {
  const std::string campaign = (dir / "campaign").string();
  const std::string model_path = (dir / "model.stepcal").string();
  const std::string self_weight =
      R"('{"name":"self_weight","links":[{"link":2,"mass_kg":40,"com_m":[0.3,0,0.1]},)"
      R"({"link":3,"mass_kg":30,"com_m":[0.2,0,0.05]}]}')";
  EXPECT_EQ(test::run(kStepcal + " simulate --protocol geometry --seed " + std::to_string(seed) +
                      " --out " + campaign + " --effect " + self_weight).status,
            0);
  EXPECT_EQ(test::run(kStepcal + " calibrate " + campaign + " --out " + model_path).status, 0);
  return model_path;
}

TEST(UrdfExportCli, WritesTheCalibratedUrdfAndComparesItsLayerWithTheRuntime) {
  test::TempDir dir;
  const std::string model_path = calibratedSimulation(dir.path(), 1);
  const std::string urdf_path = (dir.path() / "robot_calibrated.urdf").string();
  const test::CommandResult r =
      test::run(kStepcal + " export urdf " + model_path + " --out " + urdf_path);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("link 'world' is the tracker frame, link 'tool' the calibrated tmac"),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the runtime applies poe+gpr"), std::string::npos) << r.out;
  for (const std::string method : {"poe ", "poe+gpr "}) {
    EXPECT_NE(r.out.find("\n  " + method), std::string::npos) << method << " missing: " << r.out;
  }
  const CalibratedModel model = readModelFile(model_path);
  expectSameKinematics(model, test::readText(urdf_path), "simulated campaign, calibrated");
}

TEST(UrdfExportCli, RealUr10ModelToo) {
  // Series C of the IPA data (a copy travels with the tests), fitted on its first 2000 rows.
  test::TempDir dir;
  const std::string csv = std::string(STEPCAL_TEST_DATA_DIR) +
                          "/ipa-robot-accuracy/Series_C/measurements_random_poses.csv";
  const std::string campaign = (dir.path() / "ur10-C").string();
  const std::string model_path = (dir.path() / "ur10-C.stepcal").string();
  const std::string urdf_path = (dir.path() / "ur10_calibrated.urdf").string();
  ASSERT_EQ(test::run(kStepcal + " import ipa " + csv + " --validation-from-row 2000 --out " +
                      campaign).status, 0);
  ASSERT_EQ(test::run(kStepcal + " calibrate " + campaign + " --out " + model_path).status, 0);
  const test::CommandResult r =
      test::run(kStepcal + " export urdf " + model_path + " --out " + urdf_path);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("the calibrated tmac"), std::string::npos) << r.out;
  expectSameKinematics(readModelFile(model_path), test::readText(urdf_path), "UR10 Series C");
}

TEST(UrdfExportCli, BadInputEndsWithAnErrorNamingTheFile) {
  test::TempDir dir;
  const std::string urdf_path = (dir.path() / "out.urdf").string();
  const std::string missing = (dir.path() / "missing.stepcal").string();
  test::CommandResult r = test::run(kStepcal + " export urdf " + missing + " --out " + urdf_path);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find(missing), std::string::npos) << r.out;

  const fs::path corrupt = dir.path() / "corrupt.stepcal";
  test::writeText(corrupt, "STEPCAL not really a model");
  r = test::run(kStepcal + " export urdf " + corrupt.string() + " --out " + urdf_path);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find(corrupt.string()), std::string::npos) << r.out;

  // A model whose campaign has moved, and an out path below a regular file.
  const std::string model_path = calibratedSimulation(dir.path(), 2);
  const std::string campaign = (dir.path() / "campaign").string();
  const std::string moved = (dir.path() / "moved").string();
  fs::rename(campaign, moved);
  r = test::run(kStepcal + " export urdf " + model_path + " --out " + urdf_path);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find(model_path + ": the model's campaign '" + campaign +
                       "' (from its provenance) is not there"),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("hint: pass --campaign DIR"), std::string::npos) << r.out;
  const std::string unwritable = model_path + "/out.urdf";
  r = test::run(kStepcal + " export urdf " + model_path + " --campaign " + moved + " --out " +
                unwritable);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find(unwritable + ": cannot write the URDF"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the previous file, if any, is unchanged"), std::string::npos) << r.out;
  r = test::run(kStepcal + " export urdf " + model_path + " --campaign " + moved + " --out " +
                urdf_path);
  EXPECT_EQ(r.status, 0) << r.out;
}

}  // namespace
}  // namespace stepcal
