// off_axis_compliance (common/mechanisms/off_axis_compliance.hpp): a joint's frame tilting across
// its axis by the moment it carries. Its registry entry and checks; its directions and tilt
// against their closed forms; and the arm: the physical model's fixed point turns everything
// beyond the joint about the joint's origin by the tilt the load's moment gives, with a payload
// and with a measured wrench, to first order in the tilt; a model without it is untouched.
#include <gtest/gtest.h>

#include <cmath>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/mechanisms/off_axis_compliance.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal {
namespace {

Mechanism offAxis(int joint, double c_u, double c_v) {
  Mechanism m;
  m.kind = MechanismKind::kOffAxisCompliance;
  m.joint = joint;
  m.parameters = {c_u, c_v};
  m.sigma = {0.0, 0.0};
  return m;
}

TEST(OffAxisCompliance, TheRegistryNamesChecksAndDescribesIt) {
  EXPECT_EQ(mechanismKindFromString("off_axis_compliance"), MechanismKind::kOffAxisCompliance);
  EXPECT_EQ(static_cast<int>(MechanismKind::kOffAxisCompliance), 14) << "stored in model files";
  EXPECT_EQ(mechanismParameterNames(MechanismKind::kOffAxisCompliance, 6),
            (std::vector<std::string>{"tilt_u_compliance_rad_per_nm",
                                      "tilt_v_compliance_rad_per_nm"}));
  EXPECT_EQ(describe(offAxis(1, 2e-7, 1e-7)), "off_axis_compliance (joint 2)");
  EXPECT_EQ(mechanismProblem(offAxis(1, 2e-7, 0.0), 6), "");
  EXPECT_NE(mechanismProblem(offAxis(6, 2e-7, 1e-7), 6), "") << "joint 7 of a 6-joint chain";
  EXPECT_NE(mechanismProblem(offAxis(1, 2e-7, -1e-9), 6).find("expected ≥ 0"), std::string::npos)
      << "a frame that turns against its moment";
  EXPECT_FALSE(isTorqueDeflection(MechanismKind::kOffAxisCompliance));
  EXPECT_FALSE(isMeasurementOnly(MechanismKind::kOffAxisCompliance));
}

TEST(OffAxisCompliance, DirectionsAreAcrossTheAxisAndTheTiltItsClosedForm) {
  Vec3 u, v;
  mechanism::tiltDirections(Vec3::UnitZ(), u, v);
  EXPECT_EQ(u, Vec3::UnitX());
  EXPECT_EQ(v, Vec3::UnitY());
  mechanism::tiltDirections(-Vec3::UnitY(), u, v);
  EXPECT_EQ(u, Vec3::UnitX());
  EXPECT_NEAR((v - Vec3::UnitZ()).norm(), 0.0, 1e-15) << "−y × x = z";
  const Vec3 skew = Vec3(0.3, -0.5, 0.8).normalized();
  mechanism::tiltDirections(skew, u, v);
  EXPECT_NEAR(u.norm(), 1.0, 1e-15);
  EXPECT_NEAR(v.norm(), 1.0, 1e-15);
  EXPECT_NEAR(u.dot(skew), 0.0, 1e-15);
  EXPECT_NEAR(v.dot(skew), 0.0, 1e-15);
  EXPECT_NEAR(u.cross(v).dot(skew), 1.0, 1e-15) << "(u, v, axis) right-handed";

  // Isotropic: c times the moment less its component along the axis; the axis's own: nothing.
  const Vec3 moment(300.0, -120.0, 45.0);
  const Vec3 tilt = mechanism::frameTilt_rad(offAxis(0, 2e-7, 2e-7), skew, moment);
  const Vec3 across = moment - moment.dot(skew) * skew;
  EXPECT_NEAR((tilt - 2e-7 * across).norm(), 0.0, 1e-15);
  EXPECT_EQ(mechanism::frameTilt_rad(offAxis(0, 2e-7, 2e-7), skew, 10.0 * skew).norm() < 1e-20,
            true);
  // Anisotropic, axis z: c_u on x, c_v on y.
  EXPECT_NEAR((mechanism::frameTilt_rad(offAxis(0, 3e-7, 1e-7), Vec3::UnitZ(), moment) -
               Vec3(3e-7 * 300.0, -1e-7 * 120.0, 0.0))
                  .norm(),
              0.0, 1e-18);
}

PhysicalModel irb4400(bool compliant) {
  PhysicalModel model;
  model.chain_Tracker = chainFromUrdfFile(std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf",
                                          "base_link", "tmac", {"ft_sensor"});
  model.sensor_frame = model.chain_Tracker.findFrame("ft_sensor");
  model.compliance_rad_per_nm = JointVector::Constant(6, compliant ? 5e-6 : 0.0);
  model.gravity_Tracker = Vec3(0.0, 0.0, -9.81);
  return model;
}

// The tip's move to first order in the tilt t (joint frame axes) at the joint's origin: t turned
// into root axes, crossed with the arm beyond.
Vec3 firstOrderTipMove(const PhysicalModel& model, const JointVector& theta, int joint,
                       const Vec6& W_Root, const Mechanism& m) {
  ChainWorkspace ws;
  forwardKinematics(model.chain_Tracker, theta, ws);
  const Pose& X_RootJoint = ws.X_RootFrame[static_cast<size_t>(joint + 1)];
  const Vec3 moment_Joint =
      X_RootJoint.linear().transpose() *
      (W_Root.tail<3>() - X_RootJoint.translation().cross(W_Root.head<3>()));
  const Vec3 axis = model.chain_Tracker.joints()[static_cast<size_t>(joint)].twist_Local.tail<3>();
  const Vec3 tilt_Root = X_RootJoint.linear() * mechanism::frameTilt_rad(m, axis, moment_Joint);
  return tilt_Root.cross(tipPose(ws).translation() - X_RootJoint.translation());
}

TEST(OffAxisCompliance, APayloadTiltsEverythingBeyondTheJointAboutItsOrigin) {
  const PhysicalModel rigid = irb4400(false);
  const PointPayload payload{55.0, Vec3(0.05, 0.0, 0.15)};
  JointVector q(6);
  q << 0.1, 0.4, -0.2, 0.3, 0.5, -0.1;
  ChainWorkspace ws_rigid, ws_tilted;
  JointVector theta_rigid(6), tau_rigid(6), theta(6), tau(6);
  ASSERT_TRUE(physicalLinkAngles(rigid, q, Vec6::Zero(), std::nan(""),
                                 {ws_rigid, theta_rigid, tau_rigid}, {nullptr, nullptr, &payload}));
  Vec6 W_Root;
  W_Root.head<3>() = payload.mass_kg * rigid.gravity_Tracker;
  W_Root.tail<3>() = (ws_rigid.X_RootFrame[6] * payload.p_CoGInLast_m).cross(W_Root.head<3>());
  for (const int joint : {0, 1, 2, 4}) {
    SCOPED_TRACE("joint " + std::to_string(joint + 1));
    PhysicalModel tilted = rigid;
    // A heavy robot's base bearing; the joints beyond carry only the payload's moment out of
    // the arm's plane (and the wrist's), so ten times softer ones there.
    const double scale = joint == 0 ? 1.0 : 10.0;
    const Mechanism m = offAxis(joint, 3e-7 * scale, 1.5e-7 * scale);
    tilted.mechanisms.push_back(m);
    ASSERT_TRUE(physicalLinkAngles(tilted, q, Vec6::Zero(), std::nan(""), {ws_tilted, theta, tau},
                                   {nullptr, nullptr, &payload}));
    const Vec3 move = tipPose(ws_tilted).translation() - tipPose(ws_rigid).translation();
    const Vec3 expected = firstOrderTipMove(rigid, theta_rigid, joint, W_Root, m);
    ASSERT_GT(expected.norm(), 2e-6) << "the payload tilts the joint";
    // Second order: the tilt (~1e-4 rad) squared times the arm, and the moment across the axis
    // changing as the arm turns: by the tilt times the moment along the axis, which beyond joint
    // 1 is a hundred times larger (0.4 % on joint 2).
    EXPECT_NEAR((move - expected).norm(), 0.0, 1e-2 * expected.norm())
        << "move " << move.transpose() << " expected " << expected.transpose();
    // The frames up to the joint's own origin do not move.
    EXPECT_NEAR((ws_tilted.X_RootFrame[static_cast<size_t>(joint + 1)].translation() -
                 ws_rigid.X_RootFrame[static_cast<size_t>(joint + 1)].translation())
                    .norm(),
                0.0, 1e-15);
  }
}

TEST(OffAxisCompliance, AMeasuredWrenchTiltsAsTheSamePayloadDoesInsideTheFixedPoint) {
  // The sensor reads the payload's weight at the deflected pose; fed back, the model's tip must
  // be the payload's: the tilt turns the sensor too, so the reading is taken at the tilted pose.
  PhysicalModel model = irb4400(true);
  model.mechanisms.push_back(offAxis(1, 3e-7, 3e-7));
  const PointPayload payload{40.0, Vec3(0.0, 0.02, 0.12)};
  JointVector q(6);
  q << -0.3, 0.2, 0.1, -0.6, 0.7, 0.4;
  ChainWorkspace ws;
  JointVector theta(6), tau(6);
  ASSERT_TRUE(physicalLinkAngles(model, q, Vec6::Zero(), std::nan(""), {ws, theta, tau},
                                 {nullptr, nullptr, &payload}));
  const Pose X_payload = tipPose(ws);
  // The payload's reading at that pose (sensor axes, about its origin).
  const Pose X_RootSensor = framePose(model.chain_Tracker, ws, model.sensor_frame);
  const Vec3 f_Sensor = X_RootSensor.linear().transpose() * (payload.mass_kg * model.gravity_Tracker);
  const Vec3 p_CoGRoot = ws.X_RootFrame[6] * payload.p_CoGInLast_m;
  Vec6 reading;
  reading.head<3>() = f_Sensor;
  reading.tail<3>() = (X_RootSensor.inverse() * p_CoGRoot).cross(f_Sensor);
  ASSERT_TRUE(physicalLinkAngles(model, q, reading, std::nan(""), {ws, theta, tau}));
  // Three passes contract the error by ~1e-3 each: far below a micrometre.
  EXPECT_NEAR((tipPose(ws).translation() - X_payload.translation()).norm(), 0.0, 1e-9);
}

TEST(OffAxisCompliance, AZeroCompliancesOrNoLoadMoveNothing) {
  const PhysicalModel plain = irb4400(true);
  PhysicalModel zero = plain;
  zero.mechanisms.push_back(offAxis(2, 0.0, 0.0));
  JointVector q(6);
  q << 0.2, -0.3, 0.4, 0.1, -0.5, 0.6;
  Vec6 wrench;
  wrench << 10.0, -200.0, 350.0, 12.0, -30.0, 4.0;
  ChainWorkspace ws_plain, ws_zero;
  JointVector theta(6), tau(6);
  ASSERT_TRUE(physicalLinkAngles(plain, q, wrench, 25.0, {ws_plain, theta, tau}));
  ASSERT_TRUE(physicalLinkAngles(zero, q, wrench, 25.0, {ws_zero, theta, tau}));
  EXPECT_EQ(tipPose(ws_plain).matrix(), tipPose(ws_zero).matrix());
  PhysicalModel soft = plain;
  soft.mechanisms.push_back(offAxis(2, 5e-7, 5e-7));
  ASSERT_TRUE(physicalLinkAngles(plain, q, Vec6::Zero(), 25.0, {ws_plain, theta, tau}));
  ASSERT_TRUE(physicalLinkAngles(soft, q, Vec6::Zero(), 25.0, {ws_zero, theta, tau}));
  EXPECT_EQ(tipPose(ws_plain).matrix(), tipPose(ws_zero).matrix()) << "unloaded";
}

}  // namespace
}  // namespace stepcal
