// Local-POE chain: FK against hand-computed closed forms, Jacobians against finite
// differences, URDF import and its errors, and no allocation on the evaluation path.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "stepcal/common/chain.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/allocation_counter.hpp"

namespace stepcal {
namespace {

const std::string kIrb = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";
const std::string kUr10 = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";

KinematicChain irb() {
  return chainFromUrdfFile(kIrb, "base_link", "tmac", {"flange", "ft_sensor"});
}

JointVector randomQ(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  JointVector q(n);
  for (int i = 0; i < n; ++i) q(i) = u(rng);
  return q;
}

Pose tipAt(const KinematicChain& chain, const JointVector& q) {
  ChainWorkspace ws;
  EXPECT_TRUE(forwardKinematics(chain, q, ws));
  return tipPose(ws);
}

// Spatial twist (v, ω) that takes X_a to X_b: log(X_b X_a⁻¹)^∨.
Vec6 spatialDifference(const Pose& X_a, const Pose& X_b) {
  return lie::logSE3(X_b * X_a.inverse());
}

TEST(Chain, Irb4400HomePoseMatchesPublishedGeometry) {
  const KinematicChain chain = irb();
  ASSERT_EQ(chain.dof(), 6);
  ChainWorkspace ws;
  ASSERT_TRUE(forwardKinematics(chain, JointVector::Zero(6), ws));
  // Wrist centre: a1 + d4 forward, 680 + 890 + 150 mm up; flange 140 mm beyond it.
  const Pose X_BaseFlange = framePose(chain, ws, chain.findFrame("flange"));
  EXPECT_LT((X_BaseFlange.translation() - Vec3(0.200 + 0.880 + 0.140, 0, 0.680 + 0.890 + 0.150))
                .norm(),
            1e-12);
  // Flange z along base x.
  EXPECT_LT((X_BaseFlange.linear().col(2) - Vec3::UnitX()).norm(), 1e-12);
  // Tip: sensor 45 mm + T-Mac (40, −30, 215) mm in flange axes.
  const Vec3 p_expected = X_BaseFlange * Vec3(0.040, -0.030, 0.045 + 0.215);
  EXPECT_LT((tipPose(ws).translation() - p_expected).norm(), 1e-12);
}

TEST(Chain, Irb4400JointTwoClosedForm) {
  // Rotating joint 2 by a swings everything above it about the axis (0.2, ·, 0.68) along y.
  const KinematicChain chain = irb();
  const double a = 0.3;
  JointVector q = JointVector::Zero(6);
  q(1) = a;
  const Pose X0 = tipAt(chain, JointVector::Zero(6));
  const Pose X1 = tipAt(chain, q);
  Pose X_rot = Pose::Identity();
  X_rot.linear() = lie::expSO3(Vec3(0, a, 0));
  const Vec3 pivot(0.2, 0, 0.68);
  X_rot.translation() = pivot - X_rot.linear() * pivot;
  EXPECT_LT((X1.matrix() - (X_rot * X0).matrix()).norm(), 1e-12);
}

TEST(Chain, Ur10HomeMatchesDhClosedForm) {
  // All zero: the arm is stretched along −x of DH frame 0 (a2 + a3 < 0), tool z along −y.
  const KinematicChain chain = chainFromUrdfFile(kUr10, "base_link", "tool0");
  ASSERT_EQ(chain.dof(), 6);
  const Pose X = tipAt(chain, JointVector::Zero(6));
  const double d1 = 0.1273, a2 = -0.612, a3 = -0.5723, d4 = 0.163941, d5 = 0.1157, d6 = 0.0922;
  EXPECT_LT((X.translation() - Vec3(a2 + a3, -d4 - d6, d1 - d5)).norm(), 1e-12)
      << X.translation().transpose();
}

TEST(Chain, SpatialJacobianMatchesFiniteDifferences) {
  const KinematicChain chain = irb();
  std::mt19937_64 rng(3);
  const double h = 1e-6;
  for (int trial = 0; trial < 20; ++trial) {
    const JointVector q = randomQ(rng, 6);
    ChainWorkspace ws;
    forwardKinematics(chain, q, ws);
    Jacobian J_s, J_b, J_p;
    spatialJacobian(chain, ws, J_s);
    bodyJacobian(chain, ws, J_b);
    tipPointJacobian(chain, ws, J_p);
    const Pose X = tipPose(ws);
    for (int i = 0; i < 6; ++i) {
      JointVector qp = q, qm = q;
      qp(i) += h;
      qm(i) -= h;
      const Pose Xp = tipAt(chain, qp), Xm = tipAt(chain, qm);
      const Vec6 fd_s = (spatialDifference(X, Xp) - spatialDifference(X, Xm)) / (2 * h);
      EXPECT_LT((J_s.col(i) - fd_s).norm(), 1e-8);
      const Vec6 fd_b = (lie::logSE3(X.inverse() * Xp) - lie::logSE3(X.inverse() * Xm)) / (2 * h);
      EXPECT_LT((J_b.col(i) - fd_b).norm(), 1e-8);
      const Vec3 fd_p = (Xp.translation() - Xm.translation()) / (2 * h);
      EXPECT_LT((J_p.col(i).head<3>() - fd_p).norm(), 1e-8);
      EXPECT_LT((J_p.col(i).tail<3>() - J_s.col(i).tail<3>()).norm(), 1e-15);
    }
  }
}

TEST(Chain, ParameterJacobianMatchesFiniteDifferences) {
  const KinematicChain chain = irb();
  std::mt19937_64 rng(5);
  const JointVector q = randomQ(rng, 6);
  ChainWorkspace ws;
  forwardKinematics(chain, q, ws);
  Eigen::Matrix<double, 6, Eigen::Dynamic> A(6, 42);
  parameterJacobian(chain, ws, A);
  const Pose X = tipPose(ws);
  const double h = 1e-6;
  for (int c = 0; c < 42; ++c) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(42);
    d(c) = h;
    const Pose Xp = tipAt(chain.corrected(d), q);
    const Pose Xm = tipAt(chain.corrected(-d), q);
    const Vec6 fd = (spatialDifference(X, Xp) - spatialDifference(X, Xm)) / (2 * h);
    EXPECT_LT((A.col(c) - fd).norm(), 1e-8) << "parameter " << c;
  }
}

TEST(Chain, RerootedPrependsTransform) {
  const KinematicChain chain = irb();
  const Pose X_NewOld = lie::expSE3((Vec6() << 3, -1, 0.5, 0.1, 0.2, 2.0).finished());
  const KinematicChain moved = chain.rerooted(X_NewOld);
  std::mt19937_64 rng(9);
  const JointVector q = randomQ(rng, 6);
  EXPECT_LT(((X_NewOld * tipAt(chain, q)).matrix() - tipAt(moved, q).matrix()).norm(), 1e-12);
}

TEST(Chain, EvaluationDoesNotAllocate) {
  const KinematicChain chain = irb();
  ChainWorkspace ws;
  Jacobian J;
  Eigen::Matrix<double, 6, Eigen::Dynamic> A(6, 42);
  JointVector q = JointVector::Constant(6, 0.3);
  long allocations = -1;
  {
    test::AllocationCounter counter;
    for (int i = 0; i < 100; ++i) {
      q(0) += 0.01;
      forwardKinematics(chain, q, ws);
      spatialJacobian(chain, ws, J);
      bodyJacobian(chain, ws, J);
      tipPointJacobian(chain, ws, J);
      parameterJacobian(chain, ws, A);
    }
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  // The counter must see allocations when there are some.
  {
    test::AllocationCounter counter;
    Eigen::VectorXd heap(1000);
    heap.setZero();
    EXPECT_GT(counter.count(), 0);
  }
}

// sin and cos of q + δ by the angle sum: within 1e-15 of the library's at every shift size the
// series serves (|δ| ≤ 0.01), on both sides of it and far from it; δ = 0 (a rigid joint the
// deflection leaves alone) gives the unshifted values themselves.
TEST(Chain, ShiftedJointTrigMatchesTheLibraryAtEveryShift) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> angle(-2.0 * kPi, 2.0 * kPi);
  const double shifts[] = {0.0, 1e-12, -1e-9, 1e-6, -1e-4, 3e-3, -0.0099, 0.0101, -0.5, 2.0};
  for (int trial = 0; trial < 200; ++trial) {
    JointVector q(6), delta(6);
    for (int i = 0; i < 6; ++i) {
      q(i) = angle(rng);
      delta(i) = shifts[(trial + i) % std::size(shifts)];
    }
    JointTrig trig, shifted;
    jointTrig(q, trig);
    shiftedJointTrig(trig, q, delta, shifted);
    for (int i = 0; i < 6; ++i) {
      if (delta(i) == 0.0) {
        EXPECT_EQ(shifted.sin(i), trig.sin(i));
        EXPECT_EQ(shifted.cos(i), trig.cos(i));
      }
      EXPECT_NEAR(shifted.sin(i), std::sin(q(i) + delta(i)), 1e-15) << q(i) << " " << delta(i);
      EXPECT_NEAR(shifted.cos(i), std::cos(q(i) + delta(i)), 1e-15) << q(i) << " " << delta(i);
    }
  }
}

TEST(Chain, ForwardKinematicsRejectsWrongSize) {
  ChainWorkspace ws;
  EXPECT_FALSE(forwardKinematics(irb(), JointVector::Zero(5), ws));
}

TEST(Chain, AttachedFramesHangFromTheRightJoint) {
  const KinematicChain chain = irb();
  const int sensor = chain.findFrame("ft_sensor");
  ASSERT_GE(sensor, 0);
  EXPECT_EQ(chain.frames()[static_cast<size_t>(sensor)].parent, 6);
  EXPECT_EQ(chain.findFrame("nope"), -1);
}

void expectUrdfError(const std::string& xml, const std::string& base, const std::string& tip,
                     const std::string& needle, const std::vector<std::string>& attached = {}) {
  try {
    chainFromUrdf(xml, base, tip, attached, "bad.urdf");
    ADD_FAILURE() << "expected InputError containing '" << needle << "'";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    EXPECT_EQ(e.file(), "bad.urdf");
  }
}

const char* kTwoJoint = R"(<robot name="r">
  <link name="a"/><link name="b"/><link name="c"/><link name="side"/>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 1"/><axis xyz="0 0 AXIS"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
  <joint name="j2" type="JTYPE"><parent link="b"/><child link="c"/>
    <origin xyz="1 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="a"/><child link="side"/>
    <origin xyz="0 0 0"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
</robot>)";

std::string twoJoint(const std::string& axis_z, const std::string& type) {
  std::string xml = kTwoJoint;
  xml.replace(xml.find("AXIS"), 4, axis_z);
  xml.replace(xml.find("JTYPE"), 5, type);
  return xml;
}

TEST(Urdf, ParsesAnyAxisAndFixedOffsets) {
  const KinematicChain chain = chainFromUrdf(twoJoint("2", "revolute"), "a", "c");
  ASSERT_EQ(chain.dof(), 2);
  EXPECT_LT((chain.joints()[0].twist_Local.tail<3>() - Vec3::UnitZ()).norm(), 1e-15);
  EXPECT_LT((chain.joints()[1].twist_Local.tail<3>() - Vec3::UnitY()).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(chain.joints()[0].upper_rad, 1.0);
}

TEST(Urdf, RefusesBadDescriptions) {
  expectUrdfError("<robot", "a", "c", "not a valid URDF");
  expectUrdfError(twoJoint("1", "revolute"), "a", "zz", "tip_link 'zz' is not a link");
  expectUrdfError(twoJoint("1", "revolute"), "zz", "c", "base_link 'zz'");
  expectUrdfError(twoJoint("1", "revolute"), "c", "a", "not below base_link");
  expectUrdfError(twoJoint("1", "prismatic"), "a", "c", "neither revolute");
  expectUrdfError(twoJoint("1", "revolute"), "a", "c", "not on the chain", {"side"});
  expectUrdfError(twoJoint("1", "revolute"), "b", "b", "no revolute joint");
}

// Found by tests/fuzz/fuzz_urdf.cpp: the UR10 with wrist_3_joint's parent turned into its child
// (wrist_3_link → wrist_3_link). urdfdom accepts it; walking up from tool0 never ended.
TEST(Urdf, RefusesAJointWhoseChildIsItsParent) {
  const std::string input = readTextFile(std::string(STEPCAL_TEST_DATA_DIR) +
                                         "/fuzz/urdf/self-loop-timeout-44d68b63");
  const size_t newline = input.find('\n');
  ASSERT_EQ(input.substr(0, newline), "base_link tool0");
  expectUrdfError(input.substr(newline + 1), "base_link", "tool0",
                  "the joints above link 'tool0' form a loop");
}

// Found by tests/fuzz/fuzz_urdf.cpp: a description cut off inside a UTF-8 character (…
// link="base_lin" then 0xD3 0xD3 0xD3). TinyXML skipped the character's announced bytes past the
// text's end (AddressSanitizer: heap-buffer-overflow in TiXmlBase::ReadName).
TEST(Urdf, RefusesTextThatIsNotUtf8) {
  const std::string input = readTextFile(std::string(STEPCAL_TEST_DATA_DIR) +
                                         "/fuzz/urdf/truncated-utf8-overflow-f193ce71");
  const std::string urdf_xml = input.substr(input.find('\n') + 1);
  expectUrdfError(urdf_xml, "base_link", "tool0",
                  "byte 0xD3, which starts no complete UTF-8 character, at column 27");
  try {
    chainFromUrdf(urdf_xml, "base_link", "tool0", {}, "bad.urdf");
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 1 + static_cast<int>(std::count(urdf_xml.begin(), urdf_xml.end(), '\n')));
  }
  std::string with_nul = twoJoint("1", "revolute");
  with_nul[with_nul.find("<link")] = '\0';
  expectUrdfError(with_nul, "a", "c", "a NUL byte at column");
  std::string bad_continuation = twoJoint("1", "revolute");
  bad_continuation.insert(bad_continuation.find("<robot"), "<!-- \xC3( -->\n");
  expectUrdfError(bad_continuation, "a", "c", "byte 0xC3");
  // Characters beyond ASCII, whole, are welcome (in a comment here).
  std::string accented = twoJoint("1", "revolute");
  accented.insert(accented.find("<link"), "<!-- Bahnführung, 軌道 -->\n");
  EXPECT_EQ(chainFromUrdf(accented, "a", "c").dof(), 2);
}

// Loops urdfdom accepts beside that one: a link taken as child by a second joint (the later
// joint becomes its parent) and a ring of links away from the root.
TEST(Urdf, RefusesLoopsOfJoints) {
  std::string second_parent = twoJoint("1", "revolute");
  second_parent.insert(second_parent.find("</robot>"),
                       "<joint name=\"back\" type=\"fixed\"><parent link=\"c\"/>"
                       "<child link=\"b\"/></joint>\n");
  expectUrdfError(second_parent, "a", "c", "link 'b' is the child of joints");
  std::string ring = twoJoint("1", "revolute");
  ring.insert(ring.find("</robot>"),
              "<link name=\"x\"/><link name=\"y\"/>\n"
              "<joint name=\"xy\" type=\"fixed\"><parent link=\"x\"/>"
              "<child link=\"y\"/></joint>\n"
              "<joint name=\"yx\" type=\"fixed\"><parent link=\"y\"/>"
              "<child link=\"x\"/></joint>\n");
  expectUrdfError(ring, "a", "c", "the joints above link 'x' form a loop");
}

}  // namespace
}  // namespace stepcal
