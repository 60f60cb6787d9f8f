// The closed-form inverse of the nominal chains (common/closed_form_ik.hpp): every branch back
// through the forward kinematics, the branch of the answer, the singularities' status, no
// allocation; and the controllers' configuration words (common/robot_configuration.hpp) against
// hand-worked examples.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "stepcal/allocation_counter.hpp"
#include "stepcal/common/chain.hpp"
#include "stepcal/common/closed_form_ik.hpp"
#include "stepcal/common/robot_configuration.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal {
namespace {

const std::string kIrb = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";
const std::string kUr10 = std::string(STEPCAL_ROBOTS_DIR) + "/ur10.urdf";

KinematicChain irbChain() { return chainFromUrdfFile(kIrb, "base_link", "tmac", {"flange"}); }
KinematicChain ur10Chain() { return chainFromUrdfFile(kUr10, "base_link", "tool0"); }

/// The chain with every joint free within ±π (singular poses beyond the real limits).
KinematicChain withoutLimits(const KinematicChain& chain) {
  std::vector<ChainJoint> joints = chain.joints();
  for (ChainJoint& joint : joints) {
    joint.lower_rad = -M_PI;
    joint.upper_rad = M_PI;
  }
  return KinematicChain(joints, chain.initialPoses(), chain.frames());
}

Pose forward(const KinematicChain& chain, const JointVector& q) {
  ChainWorkspace ws;
  forwardKinematics(chain, q, ws);
  return tipPose(ws);
}

/// Largest difference of two poses: position (m) and rotation matrix entries.
double poseError(const Pose& a, const Pose& b) {
  return std::max((a.translation() - b.translation()).cwiseAbs().maxCoeff(),
                  (a.linear() - b.linear()).cwiseAbs().maxCoeff());
}

JointVector randomJoints(const KinematicChain& chain, std::mt19937_64& rng) {
  JointVector q(6);
  for (int j = 0; j < 6; ++j) {
    const ChainJoint& joint = chain.joints()[size_t(j)];
    std::uniform_real_distribution<double> d(std::max(joint.lower_rad, -M_PI),
                                             std::min(joint.upper_rad, M_PI));
    q(j) = d(rng);
  }
  return q;
}

/// Every solution of solveAll reaches X to 1e-12 and (away from singularities) has the branch
/// it is listed with; returns how many there were.
int checkAllBranches(const KinematicChain& chain, const ClosedFormInverse& inverse, const Pose& X,
                     bool check_branches = false) {
  std::array<JointVector, 8> q;
  std::array<ArmBranch, 8> branch;
  const int count = inverse.solveAll(X, q, branch);
  for (int k = 0; k < count; ++k) {
    EXPECT_TRUE(q[size_t(k)].allFinite());
    EXPECT_LT(poseError(forward(chain, q[size_t(k)]), X), 1e-12) << "branch " << branch[size_t(k)].index();
    if (check_branches) {
      EXPECT_EQ(inverse.branchOf(q[size_t(k)]), branch[size_t(k)]);
    }
  }
  return count;
}

void expectEightBranchesAtRandomPoses(const KinematicChain& chain, const ClosedFormInverse& inverse) {
  std::mt19937_64 rng(7);
  int full = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const JointVector q = randomJoints(chain, rng);
    const Pose X = forward(chain, q);
    const int count = checkAllBranches(chain, inverse, X, true);
    EXPECT_GE(count, 2);  // at least the branch of q itself and its wrist flip
    full += count == 8;
    // The branch of q gives q back (up to whole turns) from q as the nearest joints.
    JointVector q_back;
    const ArmBranch branch = inverse.branchOf(q);
    const ClosedFormStatus status = inverse.solve(X, branch, q, q_back);
    ASSERT_TRUE(status == ClosedFormStatus::kOk || status == ClosedFormStatus::kSingular)
        << toString(status);
    EXPECT_LT((q_back - q).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_EQ(inverse.branchOf(q_back), branch);
  }
  EXPECT_GT(full, 100);  // most poses of these arms have all eight
}

TEST(ClosedFormIk, RecognisesTheShippedArms) {
  EXPECT_EQ(ClosedFormInverse::recognise(irbChain()).layout(), ArmLayout::kSphericalWrist);
  EXPECT_EQ(ClosedFormInverse::recognise(ur10Chain()).layout(), ArmLayout::kUniversalRobots);
}

TEST(ClosedFormIk, AnotherArmHasNoClosedForm) {
  // The IRB4400 with axis 3 tilted: no two parallel axes.
  KinematicChain chain = irbChain();
  Pose T = chain.initialPose(2);
  T.linear() = T.linear() * Eigen::AngleAxisd(0.1, Vec3::UnitX()).toRotationMatrix();
  chain.setInitialPose(2, T);
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  EXPECT_EQ(inverse.layout(), ArmLayout::kOther);
  JointVector q_out;
  EXPECT_EQ(inverse.solve(Pose::Identity(), ArmBranch{}, JointVector::Zero(6), q_out),
            ClosedFormStatus::kNoClosedForm);
  // And a five-joint chain.
  EXPECT_EQ(ClosedFormInverse::recognise(chainFromUrdfFile(kIrb, "base_link", "link_5")).layout(),
            ArmLayout::kOther);
}

TEST(ClosedFormIk, Irb4400EveryBranchReachesThePose) {
  const KinematicChain chain = irbChain();
  expectEightBranchesAtRandomPoses(chain, ClosedFormInverse::recognise(chain));
}

TEST(ClosedFormIk, Ur10EveryBranchReachesThePose) {
  const KinematicChain chain = ur10Chain();
  expectEightBranchesAtRandomPoses(chain, ClosedFormInverse::recognise(chain));
}

/// At joints q near a singularity: every solution still reaches the pose, none is NaN, and the
/// branch of q reports `expected` (or OK farther out).
void expectNearSingular(const KinematicChain& chain, const JointVector& q,
                        ClosedFormStatus expected) {
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  const Pose X = forward(chain, q);
  checkAllBranches(chain, inverse, X);
  JointVector q_out;
  const ClosedFormStatus status = inverse.solve(X, inverse.branchOf(q), q, q_out);
  EXPECT_EQ(status, expected) << toString(status) << " at q = " << q.transpose();
  ASSERT_TRUE(q_out.allFinite());
  EXPECT_LT(poseError(forward(chain, q_out), X), 1e-12);
}

/// q with joint `joint` set, by bisection within [lo, hi], where the shoulder branch changes:
/// the wrist point on joint 1's axis (or, with a lateral offset, its cylinder).
JointVector shoulderSingular(const KinematicChain& chain, JointVector q, int joint, double lo,
                             double hi) {
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  const auto back = [&](double angle) {
    q(joint) = angle;
    return inverse.branchOf(q).shoulder_back;
  };
  EXPECT_NE(back(lo), back(hi));
  const bool back_lo = back(lo);
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (back(mid) == back_lo ? lo : hi) = mid;
  }
  q(joint) = 0.5 * (lo + hi);
  return q;
}

TEST(ClosedFormIk, Irb4400AtItsSingularities) {
  const KinematicChain chain = withoutLimits(irbChain());
  JointVector q(6);
  q << 0.3, 0.2, -0.4, 0.7, 0.0, -0.5;  // wrist: q5 = 0
  expectNearSingular(chain, q, ClosedFormStatus::kSingular);
  q(4) = 1e-13;
  expectNearSingular(chain, q, ClosedFormStatus::kSingular);
  q(4) = 1e-4;
  expectNearSingular(chain, q, ClosedFormStatus::kOk);
  // Shoulder: the wrist point on axis 1 (a1 = 0.2 m forward, so the arm leaning back).
  JointVector q_over(6);
  q_over << 0.4, -0.6, 0.0, 0.3, 0.5, 0.2;
  expectNearSingular(chain, shoulderSingular(chain, q_over, 2, -1.0, 1.1),
                     ClosedFormStatus::kSingular);
  // Elbow stretched: the wrist point on the line through axes 2 and 3.
  JointVector q_stretched(6);
  // The forearm (0.88, 0, 0.15) m turned about y onto the upper arm's z: q3 = atan2(−0.88, 0.15).
  q_stretched << -0.2, 0.3, std::atan2(-0.88, 0.15), 0.4, 0.6, 0.1;
  expectNearSingular(chain, q_stretched, ClosedFormStatus::kSingular);
}

TEST(ClosedFormIk, Ur10AtItsSingularities) {
  const KinematicChain chain = ur10Chain();
  JointVector q(6);
  q << 0.3, -1.2, 1.4, 0.7, 0.0, -0.5;  // wrist: axis 6 ∥ axes 2–4
  expectNearSingular(chain, q, ClosedFormStatus::kSingular);
  q(4) = 1e-4;
  expectNearSingular(chain, q, ClosedFormStatus::kOk);
  q << 0.3, -1.2, 0.0, 0.7, 1.1, -0.5;  // elbow stretched
  expectNearSingular(chain, q, ClosedFormStatus::kSingular);
  // Shoulder: the point where axes 5 and 6 meet on the cylinder of radius d4 about axis 1.
  q << 0.3, -1.2, 1.4, 0.7, 1.1, -0.5;
  expectNearSingular(chain, shoulderSingular(chain, q, 1, -2.5, -0.5), ClosedFormStatus::kSingular);
}

TEST(ClosedFormIk, BeyondReachIsUnreachableNeverNaN) {
  const KinematicChain chain = irbChain();
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  Pose X = Pose::Identity();
  X.translation() = Vec3(5.0, 0.0, 1.0);
  std::array<JointVector, 8> q;
  std::array<ArmBranch, 8> branch;
  EXPECT_EQ(inverse.solveAll(X, q, branch), 0);
  JointVector q_out = JointVector::Constant(6, 0.25);
  EXPECT_EQ(inverse.solve(X, ArmBranch{}, JointVector::Zero(6), q_out),
            ClosedFormStatus::kUnreachable);
  EXPECT_EQ(q_out, JointVector::Constant(6, 0.25));
  X.translation() = Vec3(NAN, 0.0, 1.0);
  EXPECT_EQ(inverse.solve(X, ArmBranch{}, JointVector::Zero(6), q_out),
            ClosedFormStatus::kBadRequest);
  EXPECT_EQ(inverse.solve(Pose::Identity(), ArmBranch{}, JointVector::Zero(5), q_out),
            ClosedFormStatus::kBadRequest);
}

TEST(ClosedFormIk, TurnsNearestTheGivenJointsWithinTheLimits) {
  const KinematicChain chain = ur10Chain();  // joints ±2π: two turns of most joints
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  JointVector q(6);
  q << 0.3, -1.2, 1.4, 0.7, 1.0, -0.5;
  const Pose X = forward(chain, q);
  JointVector q_near = q;
  q_near(5) += 2 * M_PI;  // the other turn of joints 6 and 1, within their ±2π
  q_near(0) -= 2 * M_PI;
  JointVector q_out;
  ASSERT_EQ(inverse.solve(X, inverse.branchOf(q), q_near, q_out), ClosedFormStatus::kOk);
  EXPECT_NEAR(q_out(5), q(5) + 2 * M_PI, 1e-9);
  EXPECT_NEAR(q_out(0), q(0) - 2 * M_PI, 1e-9);
  // IRB4400 joint 1 is within ±165°: a turn beyond it is not taken.
  const KinematicChain irb = irbChain();
  const ClosedFormInverse irb_inverse = ClosedFormInverse::recognise(irb);
  JointVector qi(6);
  qi << 0.3, 0.2, -0.4, 0.7, 0.5, -0.5;
  JointVector qi_near = qi;
  qi_near(0) += 2 * M_PI;
  ASSERT_EQ(irb_inverse.solve(forward(irb, qi), irb_inverse.branchOf(qi), qi_near, q_out),
            ClosedFormStatus::kOk);
  EXPECT_NEAR(q_out(0), qi(0), 1e-9);
  // solveNearest keeps the nearest turn and says it is beyond the limits.
  ASSERT_EQ(irb_inverse.solveNearest(forward(irb, qi), irb_inverse.branchOf(qi), qi_near, q_out),
            ClosedFormStatus::kBeyondLimits);
  EXPECT_NEAR(q_out(0), qi(0) + 2 * M_PI, 1e-9);
  ASSERT_EQ(irb_inverse.solveNearest(forward(irb, qi), irb_inverse.branchOf(qi), qi, q_out),
            ClosedFormStatus::kOk);
  EXPECT_LT((q_out - qi).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(ClosedFormIk, TheIrb4400sZeroPoseIsShoulderFrontElbowUpWristNotFlipped) {
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(irbChain());
  JointVector q = JointVector::Zero(6);
  q(4) = 0.5;
  EXPECT_EQ(inverse.branchOf(q).index(), 0);
  q(4) = -0.5;  // wrist flipped
  EXPECT_EQ(inverse.branchOf(q).index(), 1);
  // Forearm raised past the line through axes 2 and 3 (at q3 = atan2(−0.88, 0.15) = −80.3°).
  q(2) = -1.5;
  EXPECT_TRUE(inverse.branchOf(q).elbow_down);
  q(2) = 0.0;
  // Upper arm leaning back 1.2 rad: the wrist point's x = 0.2 − 0.89 sin 1.2 + 0.88 cos 1.2 −
  // 0.15 sin 1.2 = −0.45 m, behind axis 1.
  q(1) = -1.2;
  EXPECT_TRUE(inverse.branchOf(q).shoulder_back);
  q(1) = -0.5;  // x = 0.2 − 0.43 + 0.77 − 0.07 = 0.47 m
  EXPECT_FALSE(inverse.branchOf(q).shoulder_back);
}

TEST(ClosedFormIk, SolvingAllocatesNothing) {
  const KinematicChain chain = irbChain();
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  const KinematicChain ur = ur10Chain();
  const ClosedFormInverse ur_inverse = ClosedFormInverse::recognise(ur);
  JointVector q(6);
  q << 0.3, 0.2, -0.4, 0.7, 0.5, -0.5;
  const Pose X = forward(chain, q);
  const Pose X_ur = forward(ur, q);
  std::array<JointVector, 8> all;
  std::array<ArmBranch, 8> branches;
  JointVector q_out(6);
  int solved = 0;
  const test::AllocationCounter counter;
  for (int i = 0; i < 100; ++i) {
    solved += inverse.solveAll(X, all, branches);
    solved += ur_inverse.solveAll(X_ur, all, branches);
    solved += inverse.solve(X, inverse.branchOf(q), q, q_out) == ClosedFormStatus::kOk;
    solved += ur_inverse.solve(X_ur, ur_inverse.branchOf(q), q, q_out) == ClosedFormStatus::kOk;
  }
  EXPECT_EQ(counter.count(), 0);
  EXPECT_GT(solved, 0);
}

// The configuration words, against examples worked by hand from the vendors' definitions.

JointVector degrees(double a1, double a2, double a3, double a4, double a5, double a6) {
  JointVector q(6);
  q << a1, a2, a3, a4, a5, a6;
  return q * kRadPerDeg;
}

TEST(RobotConfiguration, KukaStatusAndTurn) {
  // KUKA's home pose {A1 0, A2 -90, A3 90, A4 0, A5 45, A6 0}: basic area, A3 ≥ 0, A5 > 0:
  // S 'B010' = 2; only A2 negative: T 'B000010' = 2.
  const KukaStatusTurn home = kukaStatusTurn(ArmBranch{false, false, false}, degrees(0, -90, 90, 0, 45, 0));
  EXPECT_EQ(home.status, 2);
  EXPECT_EQ(home.turn, 2);
  // Overhead, elbow down, A5 < 0: S = 1 + 4 = 5; A1, A2, A4, A5 negative: T = 1+2+8+16 = 27.
  const KukaStatusTurn over = kukaStatusTurn(ArmBranch{true, true, true}, degrees(-30, -100, 20, -10, -20, 100));
  EXPECT_EQ(over.status, 5);
  EXPECT_EQ(over.turn, 27);
  // Turn applied: A6 at −90° asked positive (bit 5 clear) goes to 270°; A4 at 30° asked negative
  // (bit 3) to −330°; A1 keeps its sign.
  JointVector q_turned = degrees(-30, -90, 90, 30, 45, -90);
  applyKukaTurn(1 | 2 | 8, q_turned);
  EXPECT_NEAR(q_turned(5), 270.0 * kRadPerDeg, 1e-12);
  EXPECT_NEAR(q_turned(3), -330.0 * kRadPerDeg, 1e-12);
  EXPECT_NEAR(q_turned(0), -30.0 * kRadPerDeg, 1e-12);
  EXPECT_EQ(kukaStatusTurn(ArmBranch{}, q_turned).turn, 1 | 2 | 8);
  // Back from S: every branch, with joint 5 counted as the chain counts it (and reversed).
  ControllerJoints same, reversed;
  reversed.direction[4] = -1.0;
  for (int index = 0; index < 8; ++index) {
    const ArmBranch branch = ArmBranch::fromIndex(index);
    const JointVector q = degrees(10, -80, 70, 0, joint5Negative(branch, same) ? -30 : 30, 0);
    EXPECT_EQ(branchOfKukaStatus(kukaStatusTurn(branch, q).status, same), branch);
    const JointVector q_reversed = degrees(10, -80, 70, 0, joint5Negative(branch, reversed) ? -30 : 30, 0);
    EXPECT_EQ(branchOfKukaStatus(kukaStatusTurn(branch, q_reversed).status, reversed), branch);
  }
}

TEST(RobotConfiguration, AbbConfData) {
  EXPECT_EQ(abbQuadrant(0.0), 0);
  EXPECT_EQ(abbQuadrant(89.9 * kRadPerDeg), 0);
  EXPECT_EQ(abbQuadrant(90.1 * kRadPerDeg), 1);
  EXPECT_EQ(abbQuadrant(-0.1 * kRadPerDeg), -1);
  EXPECT_EQ(abbQuadrant(-90.1 * kRadPerDeg), -2);
  EXPECT_EQ(abbQuadrant(270.5 * kRadPerDeg), 3);
  EXPECT_EQ(abbQuadrant(-181.0 * kRadPerDeg), -3);
  // Axis 1 at 100° (quadrant 1), axis 4 at −45° (−1), axis 6 at 200° (2); in front of axis 1
  // and of the lower arm, axis 5 negative: cfx 1.
  const AbbConfData conf = abbConfData(ArmBranch{false, false, true}, degrees(100, 10, 20, -45, -30, 200));
  EXPECT_EQ(conf.cf1, 1);
  EXPECT_EQ(conf.cf4, -1);
  EXPECT_EQ(conf.cf6, 2);
  EXPECT_EQ(conf.cfx, 1);
  // Behind axis 1, behind the lower arm, axis 5 positive: cfx 6 (the manual's table row 6).
  EXPECT_EQ(abbConfData(ArmBranch{true, true, false}, degrees(0, 0, 0, 0, 30, 0)).cfx, 6);
  const ControllerJoints same;
  for (int cfx = 0; cfx < 8; ++cfx) {
    const ArmBranch branch = branchOfAbbCfx(cfx, same);
    EXPECT_EQ(abbConfData(branch, degrees(0, 0, 0, 0, joint5Negative(branch, same) ? -30 : 30, 0)).cfx, cfx);
  }
  // Quadrants applied by whole turns: axis 6 at −160° (−2) asked for quadrant 2 goes to 200°.
  JointVector q = degrees(10, 0, 0, 0, 30, -160);
  applyAbbQuadrants(AbbConfData{0, 0, 2, 0}, q);
  EXPECT_NEAR(q(5), 200.0 * kRadPerDeg, 1e-12);
  EXPECT_NEAR(q(0), 10.0 * kRadPerDeg, 1e-12);
}

TEST(RobotConfiguration, FanucConfig) {
  EXPECT_EQ(fanucTurn(0.0), 0);
  EXPECT_EQ(fanucTurn(M_PI), 0);
  EXPECT_EQ(fanucTurn(180.5 * kRadPerDeg), 1);
  EXPECT_EQ(fanucTurn(-M_PI), -1);
  EXPECT_EQ(fanucTurn(-179.0 * kRadPerDeg), 0);
  EXPECT_EQ(fanucTurn(541.0 * kRadPerDeg), 2);
  // The tool-down pose J4 = 0, J5 = −90°: 'N U T, 0, 0, 0'.
  const FanucConfig down = fanucConfig(ArmBranch{false, false, false}, degrees(0, 0, 0, 0, -90, 0));
  EXPECT_FALSE(down.flip);
  EXPECT_TRUE(down.up);
  EXPECT_TRUE(down.front);
  EXPECT_EQ(down.turn1 + down.turn4 + down.turn6, 0);
  // J4 = 180°, J5 = +90°, J6 = −270°, back, elbow down: 'F D B, 0, 0, -1'.
  const FanucConfig flipped = fanucConfig(ArmBranch{true, true, true}, degrees(170, 0, 0, 180, 90, -270));
  EXPECT_TRUE(flipped.flip);
  EXPECT_FALSE(flipped.up);
  EXPECT_FALSE(flipped.front);
  EXPECT_EQ(flipped.turn1, 0);
  EXPECT_EQ(flipped.turn4, 0);
  EXPECT_EQ(flipped.turn6, -1);
  // A Fanuc URDF counted as Fanuc counts (J5 = the chain's q5): non-flip is q5 ≤ 0, the chain's
  // wrist_flipped side.
  ControllerJoints fanuc;
  EXPECT_TRUE(branchOfFanucConfig(down, fanuc).wrist_flipped);
  fanuc.direction[4] = -1.0;  // an ABB-like URDF: J5 = −q5
  EXPECT_FALSE(branchOfFanucConfig(down, fanuc).wrist_flipped);
  JointVector q = degrees(0, 0, 0, 0, -90, -270);
  applyFanucTurn(5, 0, q);
  EXPECT_NEAR(q(5), 90.0 * kRadPerDeg, 1e-12);
}

TEST(RobotConfiguration, TheIrb4400sBranchIsAbbsCfx) {
  // The IRB4400's URDF is in ABB's convention: cfx's axis-5 bit is the chain's wrist flip.
  const KinematicChain chain = irbChain();
  const ClosedFormInverse inverse = ClosedFormInverse::recognise(chain);
  ControllerJoints abb;
  ASSERT_TRUE(shippedControllerJoints("irb4400", abb));
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const JointVector q = randomJoints(chain, rng);
    const ArmBranch branch = inverse.branchOf(q);
    const AbbConfData conf = abbConfData(branch, controllerFromChain(abb, q));
    EXPECT_EQ(branchOfAbbCfx(conf.cfx, abb), branch);
  }
  EXPECT_FALSE(shippedControllerJoints("kr210", abb));
}

}  // namespace
}  // namespace stepcal
