// The TCP on the calibrated target: from tracker shots at it and from the four-point method
// (docs/cell.md). Both are linear least squares in the TCP (and the touched point).
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "stepcal/common/units.hpp"
#include "stepcal/trainer/cell.hpp"

namespace stepcal::trainer {
namespace {

/// The spread of the orientations R_i in their least-varied direction, from the TCP part of the
/// normal matrix S = Σ (R_i − R̄)ᵀ (R_i − R̄) = N (I − R̄ᵀR̄): two orientations θ apart about an
/// axis give S/N the eigenvalue sin²(θ/2) across it, so the spread is 2 asin √(λ_min / N).
void spreadOf(const Mat3& S, int n, ToolPointFit& fit) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(S);
  const double share = std::clamp(eigen.eigenvalues()[0] / n, 0.0, 1.0);
  fit.least_spread_rad = 2.0 * std::asin(std::sqrt(share));
  fit.least_spread_direction = eigen.eigenvectors().col(0);
}

Mat3 meanRotation(const std::vector<Pose>& X) {
  Mat3 sum = Mat3::Zero();
  for (const Pose& x : X) sum += x.linear();
  return sum / double(X.size());
}

/// Scatter of one point: the residuals' when they are redundant and larger than stated.
double pointSigma(double rss_m2, int redundancy, double stated_sigma_m) {
  if (redundancy <= 0) return stated_sigma_m;
  return std::max(std::sqrt(rss_m2 / redundancy), stated_sigma_m);
}

std::string weakSpreadNote(const ToolPointFit& fit) {
  char text[400];
  std::snprintf(text, sizeof text,
                "the orientations differ by only %.1f° in their least-varied direction (TCP axis "
                "%.2f %.2f %.2f in the target's axes; at least %.0f° wanted): the TCP along it is "
                "known to ±%.3f mm only; touch again with the tool tilted further about that axis",
                fit.least_spread_rad * kDegPerRad, fit.least_spread_direction.x(),
                fit.least_spread_direction.y(), fit.least_spread_direction.z(),
                kLeastOrientationSpread_rad * kDegPerRad,
                std::sqrt(fit.least_spread_direction.dot(fit.covariance_TcpInTip_m2 *
                                                         fit.least_spread_direction)) *
                    kMmPerM);
  return text;
}

}  // namespace

ToolPointFit fitToolFromTracker(const std::vector<Pose>& X_TrackerTip,
                                const std::vector<Vec3>& p_TcpInTracker_m, double stated_sigma_m) {
  ToolPointFit fit;
  const int n = int(X_TrackerTip.size());
  fit.points = n;
  if (n < 1 || p_TcpInTracker_m.size() != X_TrackerTip.size()) {
    fit.well_conditioned = false;
    fit.note = "no measured points: at least one tracker row at the TCP is needed";
    return fit;
  }
  // Σ R_iᵀ R_i = N I: the TCP is the mean of the shots brought into the target's frame.
  Vec3 sum = Vec3::Zero();
  for (int i = 0; i < n; ++i) {
    sum += X_TrackerTip[size_t(i)].linear().transpose() *
           (p_TcpInTracker_m[size_t(i)] - X_TrackerTip[size_t(i)].translation());
  }
  fit.p_TcpInTip_m = sum / n;
  double rss = 0.0;
  for (int i = 0; i < n; ++i) {
    const double r = (X_TrackerTip[size_t(i)] * fit.p_TcpInTip_m - p_TcpInTracker_m[size_t(i)]).norm();
    rss += r * r;
  }
  fit.redundancy = 3 * n - 3;
  fit.rms_residual_m = std::sqrt(rss / n);
  fit.point_sigma_m = pointSigma(rss, fit.redundancy, stated_sigma_m);
  fit.covariance_TcpInTip_m2 = Mat3::Identity() * (fit.point_sigma_m * fit.point_sigma_m / n);
  const Mat3 R_mean = meanRotation(X_TrackerTip);
  spreadOf(n * (Mat3::Identity() - R_mean.transpose() * R_mean), n, fit);
  return fit;
}

ToolPointFit fitToolFromFixedPoint(const std::vector<Pose>& X_TrackerTip, double stated_sigma_m) {
  ToolPointFit fit;
  const int n = int(X_TrackerTip.size());
  fit.points = n;
  if (n < 3) {
    fit.well_conditioned = false;
    fit.note = std::to_string(n) + " touches: at least 3 are needed (4 or more in orientations "
                                   "apart by 30° or more give a TCP with its σ)";
    return fit;
  }
  // p_Fixed = R̄ t + p̄ eliminated: S t = −Σ (R_i − R̄)ᵀ (p_i − p̄).
  const Mat3 R_mean = meanRotation(X_TrackerTip);
  Vec3 p_mean = Vec3::Zero();
  for (const Pose& X : X_TrackerTip) p_mean += X.translation() / n;
  Mat3 S = Mat3::Zero();
  Vec3 rhs = Vec3::Zero();
  for (const Pose& X : X_TrackerTip) {
    const Mat3 dR = X.linear() - R_mean;
    S += dR.transpose() * dR;
    rhs -= dR.transpose() * (X.translation() - p_mean);
  }
  spreadOf(S, n, fit);
  // The pseudo-inverse steps nowhere along a direction the orientations do not see; its
  // variance there is the floor's (σ² / (1e-12 n): metres for any touch scatter), not zero.
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(S);
  const double floor = 1e-12 * n;
  Vec3 inverse_values, variance_values;
  for (int k = 0; k < 3; ++k) {
    const double lambda = eigen.eigenvalues()[k];
    inverse_values[k] = lambda > floor ? 1.0 / lambda : 0.0;
    variance_values[k] = 1.0 / std::max(lambda, floor);
  }
  const Mat3& V = eigen.eigenvectors();
  const Mat3 S_inverse = V * inverse_values.asDiagonal() * V.transpose();
  fit.p_TcpInTip_m = S_inverse * rhs;
  fit.p_FixedInTracker_m = R_mean * fit.p_TcpInTip_m + p_mean;
  double rss = 0.0;
  for (const Pose& X : X_TrackerTip) {
    rss += (X * fit.p_TcpInTip_m - fit.p_FixedInTracker_m).squaredNorm();
  }
  fit.redundancy = 3 * n - 6;
  fit.rms_residual_m = std::sqrt(rss / n);
  fit.point_sigma_m = pointSigma(rss, fit.redundancy, stated_sigma_m);
  const double s2 = fit.point_sigma_m * fit.point_sigma_m;
  fit.covariance_TcpInTip_m2 = s2 * V * variance_values.asDiagonal() * V.transpose();
  if (fit.least_spread_rad < kLeastOrientationSpread_rad) {
    fit.well_conditioned = false;
    fit.note = inverse_values[0] == 0.0
                   ? "the orientations are all alike about one axis: the TCP along it is not "
                     "determined; touch again with the tool tilted about that axis"
                   : weakSpreadNote(fit);
  }
  return fit;
}

}  // namespace stepcal::trainer
