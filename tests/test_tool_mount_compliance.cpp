// tool_mount_compliance (common/mechanisms/tool_mount_compliance.hpp): the tool shifting on its
// mount by the load's force. Its registry entry and checks; its shift against the closed form
// and against the twin's own effect (tools/twin ToolMountCompliance, written apart from it); and
// the arm: the physical model's tip moves by R_RootMount C F_Mount, its orientation and every
// joint frame untouched, with a measured wrench (sensor axes) and with a payload (the sensor's
// axes, or the flange's without a sensor); a model without it, or unloaded, is untouched.
#include <gtest/gtest.h>

#include <cmath>

#include "stepcal/common/compliance.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/mechanisms/tool_mount_compliance.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/twin/effects.hpp"

namespace stepcal {
namespace {

Mechanism mount(double c_x, double c_y, double c_z) {
  Mechanism m;
  m.kind = MechanismKind::kToolMountCompliance;
  m.parameters = {c_x, c_y, c_z};
  m.sigma = {0.0, 0.0, 0.0};
  return m;
}

TEST(ToolMountCompliance, TheRegistryNamesChecksAndDescribesIt) {
  EXPECT_EQ(mechanismKindFromString("tool_mount_compliance"), MechanismKind::kToolMountCompliance);
  EXPECT_EQ(static_cast<int>(MechanismKind::kToolMountCompliance), 15) << "stored in model files";
  EXPECT_EQ(mechanismParameterNames(MechanismKind::kToolMountCompliance, 6),
            (std::vector<std::string>{"x_compliance_m_per_n", "y_compliance_m_per_n",
                                      "z_compliance_m_per_n"}));
  EXPECT_EQ(describe(mount(0.0, 0.0, 2e-7)), "tool_mount_compliance");
  EXPECT_EQ(mechanismProblem(mount(0.0, 1e-7, 2e-7), 6), "");
  EXPECT_NE(mechanismProblem(mount(0.0, -1e-9, 2e-7), 6)
                .find("compliances 0, -1e-09, 2e-07 m/N (x, y, z); expected ≥ 0"),
            std::string::npos)
      << "a mount that moves against its force: " << mechanismProblem(mount(0.0, -1e-9, 2e-7), 6);
  Mechanism on_a_joint = mount(0.0, 0.0, 2e-7);
  on_a_joint.joint = 2;
  EXPECT_NE(mechanismProblem(on_a_joint, 6), "") << "the mount is no joint's";
  EXPECT_FALSE(isTorqueDeflection(MechanismKind::kToolMountCompliance));
  EXPECT_FALSE(isMeasurementOnly(MechanismKind::kToolMountCompliance));
}

TEST(ToolMountCompliance, TheShiftIsItsClosedFormAndTheTwinsAlongZ) {
  const Vec3 force(30.0, -120.0, 410.0);
  EXPECT_NEAR(
      (mechanism::toolShift_m(mount(1e-7, 3e-7, 2e-7), force) - Vec3(3e-6, -3.6e-5, 8.2e-5)).norm(),
      0.0, 1e-18);
  // The twin's mount gives along the sensor's z only: δ = c (z·F) z in any axes; the kind's
  // (0, 0, c) in the sensor's axes, turned into the base's, is the same shift.
  const twin::ToolMountCompliance twin_mount(2e-7);
  const Eigen::Matrix3d R_BaseSensor =
      (Eigen::AngleAxisd(0.7, Vec3(0.2, -0.5, 0.84).normalized())).toRotationMatrix();
  const Vec3 force_Base(-40.0, 25.0, -539.0);
  const Vec3 twin_shift = twin_mount.shift(force_Base, R_BaseSensor.col(2));
  const Vec3 kind_shift =
      R_BaseSensor *
      mechanism::toolShift_m(mount(0.0, 0.0, 2e-7), R_BaseSensor.transpose() * force_Base);
  ASSERT_GT(twin_shift.norm(), 5e-5);
  EXPECT_NEAR((kind_shift - twin_shift).norm(), 0.0, 1e-17);
}

PhysicalModel irb4400(bool with_sensor) {
  PhysicalModel model;
  model.chain_Tracker = chainFromUrdfFile(std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf",
                                          "base_link", "tmac", {"ft_sensor"});
  model.sensor_frame = with_sensor ? model.chain_Tracker.findFrame("ft_sensor") : -1;
  model.compliance_rad_per_nm = JointVector::Constant(6, 5e-6);
  model.gravity_Tracker = Vec3(0.0, 0.0, -9.81);
  return model;
}

JointVector pose() {
  JointVector q(6);
  q << 0.1, 0.4, -0.2, 0.3, 0.5, -0.1;
  return q;
}

// The tip of model and of model with the mount, from the same commanded angles and load: the
// mount moves the tip by its shift and nothing else (no joint's frame, no orientation).
struct Tips {
  ChainWorkspace plain, mounted;
};

Tips tips(const PhysicalModel& model, const Mechanism& m, const Vec6& wrench,
          const PointPayload* payload) {
  PhysicalModel with = model;
  with.mechanisms.push_back(m);
  Tips t;
  JointVector theta(6), tau(6), theta_with(6), tau_with(6);
  EXPECT_TRUE(physicalLinkAngles(model, pose(), wrench, std::nan(""), {t.plain, theta, tau},
                                 {nullptr, nullptr, payload}));
  EXPECT_TRUE(physicalLinkAngles(with, pose(), wrench, std::nan(""),
                                 {t.mounted, theta_with, tau_with}, {nullptr, nullptr, payload}));
  EXPECT_EQ(theta, theta_with) << "the mount moves no joint";
  for (int k = 0; k <= 6; ++k) {
    EXPECT_EQ(t.plain.X_RootFrame[static_cast<size_t>(k)].matrix(),
              t.mounted.X_RootFrame[static_cast<size_t>(k)].matrix())
        << "frame " << k;
  }
  EXPECT_EQ(tipPose(t.plain).linear(), tipPose(t.mounted).linear()) << "a shift, not a turn";
  return t;
}

TEST(ToolMountCompliance, AMeasuredForceShiftsTheTipAlongTheSensorsAxes) {
  const PhysicalModel model = irb4400(true);
  Vec6 wrench;
  wrench << 35.0, -80.0, 420.0, 12.0, -30.0, 4.0;
  const Mechanism m = mount(1e-7, 3e-7, 2e-7);
  const Tips t = tips(model, m, wrench, nullptr);
  const Eigen::Matrix3d R_RootSensor =
      framePose(model.chain_Tracker, t.plain, model.sensor_frame).linear();
  const Vec3 expected = R_RootSensor * Vec3(1e-7 * 35.0, 3e-7 * -80.0, 2e-7 * 420.0);
  const Vec3 move = tipPose(t.mounted).translation() - tipPose(t.plain).translation();
  EXPECT_NEAR((move - expected).norm(), 0.0, 1e-15) << move.transpose();
}

TEST(ToolMountCompliance, APayloadsWeightShiftsTheTipInTheMountsAxes) {
  const PointPayload payload{55.0, Vec3(0.05, 0.0, 0.15)};
  const Mechanism m = mount(1e-7, 3e-7, 2e-7);
  const Vec3 weight_Root = payload.mass_kg * Vec3(0.0, 0.0, -9.81);
  // With a sensor frame its axes; without one the flange's (the last joint's frame).
  for (const bool with_sensor : {true, false}) {
    SCOPED_TRACE(with_sensor ? "sensor frame" : "flange");
    const PhysicalModel model = irb4400(with_sensor);
    const Tips t = tips(model, m, Vec6::Zero(), &payload);
    const Eigen::Matrix3d R_RootMount =
        with_sensor
            ? Eigen::Matrix3d(framePose(model.chain_Tracker, t.plain, model.sensor_frame).linear())
            : Eigen::Matrix3d(t.plain.X_RootFrame[6].linear());
    const Vec3 expected =
        R_RootMount * mechanism::toolShift_m(m, R_RootMount.transpose() * weight_Root);
    ASSERT_GT(expected.norm(), 5e-5);
    const Vec3 move = tipPose(t.mounted).translation() - tipPose(t.plain).translation();
    EXPECT_NEAR((move - expected).norm(), 0.0, 1e-15) << move.transpose();
  }
}

TEST(ToolMountCompliance, AZeroComplianceOrNoLoadMovesNothing) {
  const PhysicalModel model = irb4400(true);
  Vec6 wrench;
  wrench << 10.0, -200.0, 350.0, 12.0, -30.0, 4.0;
  const Tips zero = tips(model, mount(0.0, 0.0, 0.0), wrench, nullptr);
  EXPECT_EQ(tipPose(zero.plain).matrix(), tipPose(zero.mounted).matrix());
  const Tips unloaded = tips(model, mount(1e-7, 3e-7, 2e-7), Vec6::Zero(), nullptr);
  EXPECT_EQ(tipPose(unloaded.plain).matrix(), tipPose(unloaded.mounted).matrix());
}

}  // namespace
}  // namespace stepcal
