#include "stepcal/common/lie.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/SVD>

namespace stepcal::lie {
namespace {

// Below this angle (rad) the trigonometric coefficients use their Taylor series; the series
// are truncated where the next term is below double precision for θ < kSmallAngle.
constexpr double kSmallAngle = 1e-4;

// sin(θ)/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³ — the coefficients of Rodrigues' formula and V.
struct Coefficients {
  double a, b, c;
};

Coefficients rodrigues(double theta) noexcept {
  const double t2 = theta * theta;
  if (theta < kSmallAngle) {
    return {1.0 - t2 / 6.0 * (1.0 - t2 / 20.0), 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0),
            1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0)};
  }
  const double s = std::sin(theta), c = std::cos(theta);
  return {s / theta, (1.0 - c) / t2, (theta - s) / (t2 * theta)};
}

// (1 − a/(2b))/θ², the ŵ² coefficient of V⁻¹ and of Jl⁻¹.
double inverseCoefficient(double theta, const Coefficients& k) noexcept {
  const double t2 = theta * theta;
  if (theta < kSmallAngle) return 1.0 / 12.0 + t2 / 720.0;
  return (1.0 - k.a / (2.0 * k.b)) / t2;
}

}  // namespace

Mat3 hat(const Vec3& w) noexcept {
  Mat3 W;
  W << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return W;
}

Vec3 vee(const Mat3& W) noexcept {
  return 0.5 * Vec3(W(2, 1) - W(1, 2), W(0, 2) - W(2, 0), W(1, 0) - W(0, 1));
}

Eigen::Matrix4d hat6(const Vec6& xi) noexcept {
  Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
  X.topLeftCorner<3, 3>() = hat(xi.tail<3>());
  X.topRightCorner<3, 1>() = xi.head<3>();
  return X;
}

Vec6 vee6(const Eigen::Matrix4d& X) noexcept {
  Vec6 xi;
  xi << X.topRightCorner<3, 1>(), vee(X.topLeftCorner<3, 3>());
  return xi;
}

Mat3 expSO3(const Vec3& w) noexcept {
  const Coefficients k = rodrigues(w.norm());
  const Mat3 W = hat(w);
  return Mat3::Identity() + k.a * W + k.b * W * W;
}

Vec3 logSO3(const Mat3& R) noexcept {
  // s = sin θ · n and c = cos θ from the antisymmetric part and the trace; atan2 keeps θ
  // accurate over the whole range.
  const Vec3 s_axis = vee(R);
  const double s = s_axis.norm();
  const double c = std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0);
  const double theta = std::atan2(s, c);
  if (c > -0.7) {
    if (s < 1e-300) return Vec3::Zero();
    const double theta_over_s =
        theta < kSmallAngle ? 1.0 + theta * theta / 6.0 : theta / s;
    return theta_over_s * s_axis;
  }
  // Near π the antisymmetric part vanishes: take the axis from the symmetric part,
  // n nᵀ = (sym(R) − c I)/(1 − c), and its sign from s_axis.
  const Mat3 nnT = (0.5 * (R + R.transpose()) - c * Mat3::Identity()) / (1.0 - c);
  int col = 0;
  nnT.diagonal().maxCoeff(&col);
  Vec3 n = nnT.col(col) / std::sqrt(std::max(nnT(col, col), 1e-300));
  n.normalize();
  if (n.dot(s_axis) < 0.0) n = -n;
  return theta * n;
}

Pose expSE3(const Vec6& xi) noexcept {
  // R = I + a ŵ + b ŵ² and V v = v + b w × v + c w × (w × v), with ŵ² = w wᵀ − θ² I spelled
  // out rather than as 3 × 3 products.
  const Vec3 w = xi.tail<3>(), v = xi.head<3>();
  const double t2 = w.squaredNorm();
  const Coefficients k = rodrigues(std::sqrt(t2));
  Pose T;
  auto R = T.linear();
  const double diagonal = 1.0 - k.b * t2;
  const Vec3 aw = k.a * w, bw = k.b * w;
  R(0, 0) = diagonal + bw.x() * w.x();
  R(1, 1) = diagonal + bw.y() * w.y();
  R(2, 2) = diagonal + bw.z() * w.z();
  R(0, 1) = bw.x() * w.y() - aw.z();
  R(1, 0) = bw.x() * w.y() + aw.z();
  R(0, 2) = bw.x() * w.z() + aw.y();
  R(2, 0) = bw.x() * w.z() - aw.y();
  R(1, 2) = bw.y() * w.z() - aw.x();
  R(2, 1) = bw.y() * w.z() + aw.x();
  const Vec3 wxv = w.cross(v);
  T.translation() = v + k.b * wxv + k.c * w.cross(wxv);
  T.makeAffine();
  return T;
}

Vec6 logSE3(const Pose& T) noexcept {
  const Vec3 w = logSO3(T.linear());
  const double theta = w.norm();
  const Coefficients k = rodrigues(theta);
  const Mat3 W = hat(w);
  const Mat3 V_inv = Mat3::Identity() - 0.5 * W + inverseCoefficient(theta, k) * W * W;
  Vec6 xi;
  xi.head<3>() = V_inv * T.translation();
  xi.tail<3>() = w;
  return xi;
}

Mat6 adjoint(const Pose& T) noexcept {
  Mat6 Ad = Mat6::Zero();
  const Mat3& R = T.linear();
  Ad.topLeftCorner<3, 3>() = R;
  Ad.topRightCorner<3, 3>() = hat(T.translation()) * R;
  Ad.bottomRightCorner<3, 3>() = R;
  return Ad;
}

Mat3 leftJacobianSO3(const Vec3& w) noexcept {
  const Coefficients k = rodrigues(w.norm());
  const Mat3 W = hat(w);
  return Mat3::Identity() + k.b * W + k.c * W * W;
}

Mat3 leftJacobianInverseSO3(const Vec3& w) noexcept {
  const double theta = w.norm();
  const Coefficients k = rodrigues(theta);
  const Mat3 W = hat(w);
  return Mat3::Identity() - 0.5 * W + inverseCoefficient(theta, k) * W * W;
}

Mat3 rightJacobianSO3(const Vec3& w) noexcept { return leftJacobianSO3(-w); }

Mat3 rightJacobianInverseSO3(const Vec3& w) noexcept { return leftJacobianInverseSO3(-w); }

double angleBetween(const Mat3& R_a, const Mat3& R_b) noexcept {
  return logSO3(R_a.transpose() * R_b).norm();
}

Mat3 projectToSO3(const Mat3& M) noexcept {
  const Eigen::JacobiSVD<Mat3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 D = Mat3::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

Mat3 rotationFromRpy(double roll, double pitch, double yaw) noexcept {
  return (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
          Eigen::AngleAxisd(roll, Vec3::UnitX()))
      .toRotationMatrix();
}

Vec3 rpyFromRotation(const Mat3& R) noexcept {
  const double pitch = std::atan2(-R(2, 0), std::hypot(R(0, 0), R(1, 0)));
  // Near gimbal lock the yaw is ill-conditioned; the roll taken from Rz(yaw)ᵀ R = Ry(pitch)
  // Rx(roll), whose middle row is (0, cos roll, −sin roll), absorbs its error, so the angles
  // give R back to rounding at every pitch.
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double roll = std::atan2(-(c * R(1, 2) - s * R(0, 2)), c * R(1, 1) - s * R(0, 1));
  return {roll, pitch, yaw};
}

}  // namespace stepcal::lie
