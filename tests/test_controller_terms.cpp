// Each controller's frame terms (common/.../controller_terms.hpp) against hand-worked examples:
// KUKA {A 30, B 45, C 60} and FANUC (W 60, P 45, R 30) are the same matrix Rz(30°)·Ry(45°)·Rx(60°),
// whose elements are worked below; ABB's quaternion of 45° about y is its manual's
// [0.92388, 0, 0.382683, 0]; UR's rotation vector of the cyclic permutation x→y→z→x is 120°
// about (1, 1, 1)/√3.
#include <gtest/gtest.h>

#include <cmath>

#include "stepcal/common/controller_terms.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal {
namespace {

Pose at(const Vec3& p_m, const Mat3& R) {
  Pose X = Pose::Identity();
  X.linear() = R;
  X.translation() = p_m;
  return X;
}

// R = Rz(30°) Ry(45°) Rx(60°), by hand: with cA = √3/2, sA = 1/2, cB = sB = √2/2, cC = 1/2,
// sC = √3/2: R00 = cA cB, R10 = sA cB, R20 = −sB, R21 = cB sC, R22 = cB cC,
// R01 = cA sB sC − sA cC, R12 = sA sB cC − cA sC.
Mat3 handWorked() {
  const double cA = std::sqrt(3.0) / 2, sA = 0.5, cB = std::sqrt(0.5), sB = std::sqrt(0.5);
  const double cC = 0.5, sC = std::sqrt(3.0) / 2;
  Mat3 R;
  R << cA * cB, cA * sB * sC - sA * cC, cA * sB * cC + sA * sC,  //
      sA * cB, sA * sB * sC + cA * cC, sA * sB * cC - cA * sC,   //
      -sB, cB * sC, cB * cC;
  return R;
}

TEST(ControllerTerms, KukaAbcIsZyxEuler) {
  const Pose X = at(Vec3(0.1, -0.2, 0.35), handWorked());
  const KukaFrame k = toKuka(X);
  EXPECT_NEAR(k.x_mm, 100.0, 1e-9);
  EXPECT_NEAR(k.y_mm, -200.0, 1e-9);
  EXPECT_NEAR(k.z_mm, 350.0, 1e-9);
  EXPECT_NEAR(k.a_deg, 30.0, 1e-9);
  EXPECT_NEAR(k.b_deg, 45.0, 1e-9);
  EXPECT_NEAR(k.c_deg, 60.0, 1e-9);
  EXPECT_LT((fromKuka(k).matrix() - X.matrix()).norm(), 1e-12);
  EXPECT_EQ(kukaText(k), "{X 100.000, Y -200.000, Z 350.000, A 30.0000, B 45.0000, C 60.0000}");
  // A value that prints as zero prints unsigned, as a pendant takes it.
  EXPECT_EQ(kukaText({1e-12, -1e-12, 0, -1e-9, 0, -0.0}),
            "{X 0.000, Y 0.000, Z 0.000, A 0.0000, B 0.0000, C 0.0000}");
  // A alone turns about z: x goes to y.
  const Pose Z90 = fromKuka({0, 0, 0, 90, 0, 0});
  EXPECT_LT((Z90.linear() * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-12);
}

TEST(ControllerTerms, FanucWprIsFixedXyz) {
  const Pose X = at(Vec3(0.1, -0.2, 0.35), handWorked());
  const FanucFrame f = toFanuc(X);
  EXPECT_NEAR(f.w_deg, 60.0, 1e-9);
  EXPECT_NEAR(f.p_deg, 45.0, 1e-9);
  EXPECT_NEAR(f.r_deg, 30.0, 1e-9);
  EXPECT_NEAR(f.x_mm, 100.0, 1e-9);
  EXPECT_LT((fromFanuc(f).matrix() - X.matrix()).norm(), 1e-12);
  EXPECT_EQ(fanucText(f), "X 100.000 Y -200.000 Z 350.000 W 60.0000 P 45.0000 R 30.0000");
  // W alone turns about the fixed x: y goes to z.
  const Pose X90 = fromFanuc({0, 0, 0, 90, 0, 0});
  EXPECT_LT((X90.linear() * Vec3::UnitY() - Vec3::UnitZ()).norm(), 1e-12);
}

TEST(ControllerTerms, AbbQuaternionScalarFirst) {
  // 45° about y: [cos 22.5°, 0, sin 22.5°, 0] = [0.92388, 0, 0.382683, 0].
  const Pose X = at(Vec3(0, 0, 0.35), Eigen::AngleAxisd(kPi / 4, Vec3::UnitY()).toRotationMatrix());
  const AbbFrame a = toAbb(X);
  EXPECT_NEAR(a.rot_q1234[0], 0.9238795325, 1e-9);
  EXPECT_NEAR(a.rot_q1234[1], 0.0, 1e-12);
  EXPECT_NEAR(a.rot_q1234[2], 0.3826834324, 1e-9);
  EXPECT_NEAR(a.rot_q1234[3], 0.0, 1e-12);
  EXPECT_NEAR(a.trans_mm[2], 350.0, 1e-9);
  EXPECT_EQ(abbText(a), "[[0.000,0.000,350.000],[0.923879533,0.000000000,0.382683432,0.000000000]]");
  // −q is the same rotation; ABB's form keeps q1 ≥ 0.
  const Pose Y270 = at(Vec3::Zero(), Eigen::AngleAxisd(1.5 * kPi, Vec3::UnitY()).toRotationMatrix());
  EXPECT_GE(toAbb(Y270).rot_q1234[0], 0.0);
  EXPECT_LT((fromAbb(toAbb(Y270)).matrix() - Y270.matrix()).norm(), 1e-12);
}

TEST(ControllerTerms, UrRotationVectorInMetres) {
  Mat3 cyclic;  // x→y, y→z, z→x: 120° about (1, 1, 1)/√3
  cyclic << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const UrFrame u = toUr(at(Vec3(0.1, 0.2, 0.3), cyclic));
  const double each = (2 * kPi / 3) / std::sqrt(3.0);  // 1.2092
  EXPECT_NEAR(u.pose_m_rad[0], 0.1, 1e-15);
  for (int k = 3; k < 6; ++k) EXPECT_NEAR(u.pose_m_rad[size_t(k)], each, 1e-12);
  EXPECT_EQ(urText(u), "p[0.100000, 0.200000, 0.300000, 1.209200, 1.209200, 1.209200]");
  EXPECT_LT((fromUr(u).linear() - cyclic).norm(), 1e-12);
}

}  // namespace
}  // namespace stepcal
