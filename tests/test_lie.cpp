// Property tests of the SO(3)/SE(3) maps: identity, 1e-8 from identity, near π, random;
// round trips, closed forms and Jacobians against central finite differences.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::lie {
namespace {

std::vector<Vec3> rotationVectors() {
  std::vector<Vec3> out = {Vec3::Zero(),
                           Vec3(1e-8, 0, 0),
                           Vec3(1e-8, -2e-8, 3e-9),
                           Vec3(2e-5, 1e-5, -3e-5),  // inside the Taylor branch
                           Vec3(0.3, -0.2, 0.1),
                           Vec3(0, 0, kPi - 1e-9),
                           Vec3(kPi - 1e-6, 0, 0),
                           Vec3(1, 1, 1).normalized() * (kPi - 1e-7),
                           Vec3(0.2, -0.9, 0.4).normalized() * (kPi - 1e-3),
                           Vec3(0, kPi, 0)};
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Vec3 axis = Vec3(u(rng), u(rng), u(rng)).normalized();
    out.push_back(axis * (kPi * std::abs(u(rng))));
  }
  return out;
}

// log returns the principal value; at exactly π the sign of the axis is arbitrary.
void expectSameRotationVector(const Vec3& expected, const Vec3& actual, double tol) {
  if (std::abs(expected.norm() - kPi) < 1e-12) {
    EXPECT_TRUE((expected - actual).norm() < tol || (expected + actual).norm() < tol)
        << expected.transpose() << " vs " << actual.transpose();
  } else {
    EXPECT_LT((expected - actual).norm(), tol) << expected.transpose() << " vs "
                                               << actual.transpose();
  }
}

TEST(Lie, HatVeeAreInverseAndCross) {
  const Vec3 a(0.3, -1.2, 2.0), b(-0.7, 0.4, 1.1);
  EXPECT_LT((hat(a) * b - a.cross(b)).norm(), 1e-15);
  EXPECT_LT((vee(hat(a)) - a).norm(), 1e-15);
  Vec6 xi;
  xi << 1, 2, 3, 4, 5, 6;
  EXPECT_EQ(vee6(hat6(xi)), xi);
}

TEST(Lie, ExpSO3IsARotationAndMatchesEigen) {
  for (const Vec3& w : rotationVectors()) {
    const Mat3 R = expSO3(w);
    EXPECT_LT((R.transpose() * R - Mat3::Identity()).norm(), 1e-14);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
    const double theta = w.norm();
    const Mat3 R_ref = theta > 0 ? Eigen::AngleAxisd(theta, w / theta).toRotationMatrix()
                                 : Mat3::Identity();
    EXPECT_LT((R - R_ref).norm(), 1e-14) << w.transpose();
  }
}

TEST(Lie, LogInvertsExpSO3EverywhereIncludingNearPi) {
  for (const Vec3& w : rotationVectors()) {
    // Near π the axis is conditioned as 1/sqrt(1+cos θ); 1e-9 from π loses ~8 digits.
    const double tol = w.norm() > kPi - 1e-6 ? 1e-7 : 1e-13;
    expectSameRotationVector(w, logSO3(expSO3(w)), tol);
  }
}

TEST(Lie, LogSO3AtIdentityAndTinyAngles) {
  EXPECT_EQ(logSO3(Mat3::Identity()), Vec3::Zero());
  const Vec3 w(1e-8, -2e-8, 3e-9);
  EXPECT_LT((logSO3(expSO3(w)) - w).norm(), 1e-22);
}

TEST(Lie, ExpLogSE3RoundTrip) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (const Vec3& w : rotationVectors()) {
    Vec6 xi;
    xi << u(rng), u(rng), u(rng), w;
    const Vec6 back = logSE3(expSE3(xi));
    if (w.norm() > kPi - 1e-6) {
      // Only the group element is defined up to the axis sign at π: compare the poses.
      EXPECT_LT((expSE3(back).matrix() - expSE3(xi).matrix()).norm(), 1e-7);
    } else {
      EXPECT_LT((back - xi).norm(), 1e-12) << xi.transpose();
    }
  }
}

TEST(Lie, ExpSE3MatchesMatrixExponentialSeries) {
  Vec6 xi;
  xi << 0.4, -0.3, 0.8, 0.5, -0.7, 0.2;
  const Eigen::Matrix4d X = hat6(xi);
  Eigen::Matrix4d sum = Eigen::Matrix4d::Identity(), term = Eigen::Matrix4d::Identity();
  for (int k = 1; k < 40; ++k) {
    term = term * X / k;
    sum += term;
  }
  EXPECT_LT((expSE3(xi).matrix() - sum).norm(), 1e-14);
}

// expSE3 spells ŵ² out; its rotation is expSO3's and its translation V v with V from the series
// Σ ŵᵏ/(k+1)!, at identity, near it, near π and at random (translations of 1 m scale).
TEST(Lie, ExpSE3AgreesWithExpSO3AndTheSeriesOfV) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Vec3& w : rotationVectors()) {
    const Vec3 v(u(rng), u(rng), u(rng));
    Vec6 xi;
    xi.head<3>() = v;
    xi.tail<3>() = w;
    const Pose T = expSE3(xi);
    EXPECT_LT((T.linear() - expSO3(w)).norm(), 1e-14) << w.transpose();
    Mat3 V = Mat3::Identity(), term = Mat3::Identity();
    for (int k = 1; k < 60; ++k) {
      term = term * hat(w) / (k + 1);
      V += term;
    }
    EXPECT_LT((T.translation() - V * v).norm(), 1e-14) << w.transpose();
    EXPECT_EQ(T.matrix().row(3), Eigen::RowVector4d(0, 0, 0, 1));
  }
}

TEST(Lie, AdjointTransformsTwists) {
  // Ad_T ξ̂ = T ξ̂ T⁻¹ (closed form, any T).
  Vec6 xi, t;
  xi << 0.1, 0.2, -0.3, 0.7, -0.1, 0.4;
  t << 1.0, -2.0, 0.5, 0.3, 2.0, -1.0;
  const Pose T = expSE3(t);
  const Eigen::Matrix4d lhs = hat6(adjoint(T) * xi);
  const Eigen::Matrix4d rhs = T.matrix() * hat6(xi) * T.inverse().matrix();
  EXPECT_LT((lhs - rhs).norm(), 1e-14);
  EXPECT_LT((adjoint(T) * adjoint(T.inverse()) - Mat6::Identity()).norm(), 1e-13);
}

TEST(Lie, SO3JacobiansMatchFiniteDifferences) {
  const double h = 1e-6;
  for (const Vec3& w : {Vec3(0, 0, 0), Vec3(1e-8, 0, 2e-8), Vec3(0.3, -0.5, 0.8),
                        Vec3(Vec3(0.1, 0.2, -0.3).normalized() * 3.0)}) {
    Mat3 Jl_fd, Jr_fd;
    for (int i = 0; i < 3; ++i) {
      const Vec3 e = Vec3::Unit(i) * h;
      Jl_fd.col(i) =
          (logSO3(expSO3(w + e) * expSO3(w).transpose()) -
           logSO3(expSO3(w - e) * expSO3(w).transpose())) / (2 * h);
      Jr_fd.col(i) =
          (logSO3(expSO3(w).transpose() * expSO3(w + e)) -
           logSO3(expSO3(w).transpose() * expSO3(w - e))) / (2 * h);
    }
    EXPECT_LT((leftJacobianSO3(w) - Jl_fd).norm(), 1e-8) << w.transpose();
    EXPECT_LT((rightJacobianSO3(w) - Jr_fd).norm(), 1e-8) << w.transpose();
    EXPECT_LT((leftJacobianInverseSO3(w) * leftJacobianSO3(w) - Mat3::Identity()).norm(), 1e-12);
    EXPECT_LT((rightJacobianInverseSO3(w) * rightJacobianSO3(w) - Mat3::Identity()).norm(),
              1e-12);
  }
}

TEST(Lie, AngleBetweenAndProjection) {
  const Mat3 R = expSO3(Vec3(0.1, 0.2, 0.3));
  EXPECT_NEAR(angleBetween(R, R * expSO3(Vec3(0, 0.01, 0))), 0.01, 1e-15);
  Mat3 noisy = R;
  noisy(0, 1) += 1e-3;
  const Mat3 P = projectToSO3(noisy);
  EXPECT_LT((P.transpose() * P - Mat3::Identity()).norm(), 1e-14);
  EXPECT_NEAR(P.determinant(), 1.0, 1e-14);
  EXPECT_LT((projectToSO3(R) - R).norm(), 1e-14);
}

TEST(Lie, RpyRoundTripAndConvention) {
  // URDF: R = Rz(yaw) Ry(pitch) Rx(roll).
  const Mat3 R = rotationFromRpy(0.1, -0.4, 2.5);
  const Mat3 R_ref = expSO3(Vec3(0, 0, 2.5)) * expSO3(Vec3(0, -0.4, 0)) * expSO3(Vec3(0.1, 0, 0));
  EXPECT_LT((R - R_ref).norm(), 1e-15);
  const Vec3 rpy = rpyFromRotation(R);
  EXPECT_LT((rpy - Vec3(0.1, -0.4, 2.5)).norm(), 1e-14);
  for (double pitch : {kPi / 2, -kPi / 2}) {
    const Mat3 G = rotationFromRpy(0.3, pitch, 0.0);
    const Vec3 back = rpyFromRotation(G);
    EXPECT_LT((rotationFromRpy(back.x(), back.y(), back.z()) - G).norm(), 1e-12);
  }
}

TEST(Lie, RpyGivesTheRotationBackToRoundingNearGimbalLock) {
  // Where cos(pitch) is tiny, yaw and roll each come from small entries; the rotation they give
  // back must not lose what rounding there costs (1e-16 / cos(pitch) rad).
  for (const double from_lock : {1e-4, 1e-7, 1e-9, 1e-11, 0.0}) {
    for (const double pitch : {kPi / 2 - from_lock, -kPi / 2 + from_lock}) {
      const Mat3 R = rotationFromRpy(0.3, pitch, -1.2);
      const Vec3 back = rpyFromRotation(R);
      EXPECT_LT((rotationFromRpy(back.x(), back.y(), back.z()) - R).norm(), 1e-15)
          << "pitch " << pitch;
    }
  }
}

}  // namespace
}  // namespace stepcal::lie
