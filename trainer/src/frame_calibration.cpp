// A work object's frame from measured points: the three-point method and the least-squares fit
// to fiducials of known nominal coordinates (Kabsch/Horn by SVD), each with its 1-σ carried from
// the points' scatter and the TCP's own σ (docs/cell.md).
#include <Eigen/SVD>
#include <cmath>
#include <algorithm>
#include <functional>

#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/cell.hpp"

namespace stepcal::trainer {
namespace {

using FrameOfPoints = std::function<Pose(const std::vector<Vec3>&)>;

/// The frame's deviation from X̂ in its own axes: (R̂ᵀ (o − ô), log(R̂ᵀ R)).
Vec6 deviation(const Pose& X_hat, const Pose& X) {
  Vec6 d;
  d.head<3>() = X_hat.linear().transpose() * (X.translation() - X_hat.translation());
  d.tail<3>() = lie::logSO3(X_hat.linear().transpose() * X.linear());
  return d;
}

/// Covariance of the frame from the points': each point's isotropic σ² and the TCP's
/// covariance, shared by every touched point through dp_i/dt. The frame's Jacobian in the
/// points by central differences (the fits are smooth; steps of 1 µm).
Mat6 frameCovariance(const FrameOfPoints& frameOf, const std::vector<FramePoint>& points,
                     double point_sigma_m, const Mat3& covariance_TcpInTip_m2) {
  std::vector<Vec3> p;
  for (const FramePoint& point : points) p.push_back(point.p_InTracker_m);
  const Pose X_hat = frameOf(p);
  const int columns = 3 * int(points.size());
  Eigen::MatrixXd J(6, columns), D(columns, 3);
  constexpr double kStep_m = 1e-6;
  for (int c = 0; c < columns; ++c) {
    std::vector<Vec3> plus = p, minus = p;
    plus[size_t(c / 3)][c % 3] += kStep_m;
    minus[size_t(c / 3)][c % 3] -= kStep_m;
    J.col(c) = (deviation(X_hat, frameOf(plus)) - deviation(X_hat, frameOf(minus))) / (2 * kStep_m);
  }
  for (size_t i = 0; i < points.size(); ++i) D.middleRows(3 * Eigen::Index(i), 3) = points[i].dPointdTcp;
  const Eigen::MatrixXd covariance_points =
      point_sigma_m * point_sigma_m * Eigen::MatrixXd::Identity(columns, columns) +
      D * covariance_TcpInTip_m2 * D.transpose();
  return J * covariance_points * J.transpose();
}

Pose threePointFrame(const std::vector<Vec3>& p) {
  const Vec3 x = (p[1] - p[0]).normalized();
  const Vec3 z = x.cross(p[2] - p[0]).normalized();
  Pose X = Pose::Identity();
  X.linear().col(0) = x;
  X.linear().col(1) = z.cross(x);
  X.linear().col(2) = z;
  X.translation() = p[0];
  return X;
}

/// Kabsch/Horn: the rotation and translation taking the nominal points onto the measured ones.
Pose rigidFit(const std::vector<Vec3>& measured, const std::vector<Vec3>& nominal) {
  const double n = double(measured.size());
  Vec3 m_mean = Vec3::Zero(), n_mean = Vec3::Zero();
  for (size_t i = 0; i < measured.size(); ++i) {
    m_mean += measured[i] / n;
    n_mean += nominal[i] / n;
  }
  Mat3 H = Mat3::Zero();
  for (size_t i = 0; i < measured.size(); ++i) {
    H += (nominal[i] - n_mean) * (measured[i] - m_mean).transpose();
  }
  const Eigen::JacobiSVD<Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 sign = Mat3::Identity();
  sign(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  Pose X = Pose::Identity();
  X.linear() = svd.matrixV() * sign * svd.matrixU().transpose();
  X.translation() = m_mean - X.linear() * n_mean;
  return X;
}

/// Second singular value of the centred points over their spread: near zero, they lie on a line.
double planarity(const std::vector<Vec3>& points) {
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : points) mean += p / double(points.size());
  Eigen::Matrix3Xd centred(3, Eigen::Index(points.size()));
  for (size_t i = 0; i < points.size(); ++i) centred.col(Eigen::Index(i)) = points[i] - mean;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred);
  const auto& values = svd.singularValues();
  return values[0] > 0 ? values[1] / values[0] : 0.0;
}

constexpr double kLeastPlanarity = 1e-3;

}  // namespace

FrameFit fitFrameFromThreePoints(const FramePoint& origin, const FramePoint& on_x,
                                 const FramePoint& in_xy, double stated_sigma_m,
                                 const Mat3& covariance_TcpInTip_m2) {
  FrameFit fit;
  fit.points = 3;
  const std::vector<FramePoint> points = {origin, on_x, in_xy};
  const std::vector<Vec3> p = {origin.p_InTracker_m, on_x.p_InTracker_m, in_xy.p_InTracker_m};
  if (planarity(p) < kLeastPlanarity || (p[1] - p[0]).norm() < 1e-9) {
    fit.note = "the three points lie on a line (or two coincide): they fix no plane; touch the "
               "origin, a point on +x and a point on the +y side, each well apart";
    return fit;
  }
  fit.X_TrackerFrame = threePointFrame(p);
  fit.point_sigma_m = stated_sigma_m;
  fit.covariance = frameCovariance(threePointFrame, points, stated_sigma_m, covariance_TcpInTip_m2);
  return fit;
}

FrameFit fitFrameToFiducials(const std::vector<FramePoint>& measured,
                             const std::vector<Vec3>& p_NominalInFrame_m, double stated_sigma_m,
                             const Mat3& covariance_TcpInTip_m2) {
  FrameFit fit;
  fit.points = int(measured.size());
  if (measured.size() < 3 || measured.size() != p_NominalInFrame_m.size() ||
      planarity(p_NominalInFrame_m) < kLeastPlanarity) {
    fit.note = "a frame needs at least 3 fiducials not on one line; got " +
               std::to_string(measured.size());
    return fit;
  }
  const FrameOfPoints frameOf = [&](const std::vector<Vec3>& p) {
    return rigidFit(p, p_NominalInFrame_m);
  };
  std::vector<Vec3> p;
  for (const FramePoint& point : measured) p.push_back(point.p_InTracker_m);
  fit.X_TrackerFrame = frameOf(p);
  double rss = 0.0;
  for (size_t i = 0; i < p.size(); ++i) {
    rss += (fit.X_TrackerFrame * p_NominalInFrame_m[i] - p[i]).squaredNorm();
  }
  fit.redundancy = 3 * fit.points - 6;
  fit.rms_residual_m = std::sqrt(rss / fit.points);
  fit.point_sigma_m = std::max(std::sqrt(rss / fit.redundancy), stated_sigma_m);
  fit.covariance = frameCovariance(frameOf, measured, fit.point_sigma_m, covariance_TcpInTip_m2);
  return fit;
}

}  // namespace stepcal::trainer
