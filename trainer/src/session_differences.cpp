// Whether one value of each joint frame serves every session (geometric.hpp,
// testSessionDifferences): held-out errors of every frame shared against one frame each session's
// own, and each session's difference in the joint's terms with its 1-σ.
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <tuple>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/geometric.hpp"
#include "diagnose/cross_validation.hpp"
#include "diagnose/parallel.hpp"
#include "geometric_fit.hpp"

namespace stepcal::trainer {
namespace {

// Held-out errors of rows under a session's chain: squared over the stated noise, and the
// position error, m.
void heldOutErrors(const KinematicChain& chain, const std::vector<const Measurement*>& rows,
                   const TrackerNoise& noise, std::vector<double>& squared,
                   std::vector<double>& position_m) {
  ChainWorkspace ws;
  for (const Measurement* row : rows) {
    forwardKinematics(chain, row->q_rad, ws);
    const Pose& X = tipPose(ws);
    const double p = (row->p_TipInTracker_m - X.translation()).norm();
    double e = std::pow(p / noise.position_sigma_m, 2);
    if (row->has_orientation) {
      const Vec3 r_R = lie::logSO3(row->q_TrackerTip.toRotationMatrix() * X.linear().transpose());
      e += r_R.squaredNorm() / std::pow(noise.orientation_sigma_rad, 2);
    }
    squared.push_back(e);
    position_m.push_back(p);
  }
}

// The size of a vector and the 1-σ of that size, first order (along the vector; a zero vector:
// its largest 1-σ). covariance: the vector's.
std::pair<double, double> sizeWithSigma(const Vec3& v, const Mat3& covariance) {
  const double size = v.norm();
  if (size > 0.0) return {size, std::sqrt(std::max(0.0, (v / size).dot(covariance * v / size)))};
  return {0.0, std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Mat3>(covariance).eigenvalues()(2)))};
}

// Session s's frame k against the first session's in a fit with frame k each session's own, in
// the terms of joint k+1 (whose initial pose the frame is), with 1-σ from the fit's covariance.
FrameDifference frameDifference(const GeometricFit& fit, int k, int s) {
  const Pose& first = fit.result.sessions[0].chain_Tracker.initialPose(k);
  const KinematicChain& chain = fit.result.sessions[static_cast<size_t>(s)].chain_Tracker;
  const Pose D = first.inverse() * chain.initialPose(k);
  const Vec6 delta = lie::logSE3(D);
  // To first order, updates δ_1 and δ_s of the two frames move the difference by δ_s − Ad(D⁻¹) δ_1.
  const SvdSolution& svd = fit.last;
  const Eigen::Index p = fit.layout.count();
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(6, p);
  const Mat6 Ad = lie::adjoint(D.inverse());
  for (int c = 0; c < 6; ++c) {
    G(c, fit.layout.column(s, 6 * k + c)) += 1.0;
    G.col(fit.layout.column(0, 6 * k + c)) -= Ad.col(c);
  }
  const Eigen::MatrixXd A = G * svd.column_scale.cwiseInverse().asDiagonal();  // on scaled unknowns
  // Covariance of the retained directions (the rows are weighted by the stated noise), times the
  // reduced χ² when the rows scatter more than stated.
  const Eigen::MatrixXd W = A * svd.V.leftCols(svd.rank) *
                            svd.singular_values.head(svd.rank).cwiseInverse().asDiagonal();
  const Mat6 covariance = W * W.transpose() * std::max(1.0, fit.chi2_reduced);
  // Directions the unobserved combinations move the difference along: the rows do not determine
  // them (a trade with the session's own registration or tool).
  Eigen::MatrixXd B(6, 0);
  if (svd.rank < p) {
    const Eigen::MatrixXd moved = A * svd.V.rightCols(p - svd.rank);
    const Eigen::JacobiSVD<Eigen::MatrixXd> moves(moved, Eigen::ComputeThinU);
    // Relative to the largest move of any unknown: a trade moves the difference by 0.09–0.7 of
    // it, the null space's rounding by 1e-4 at most (measured on the twin's two stations).
    const double largest = Eigen::JacobiSVD<Eigen::MatrixXd>(A).singularValues()(0);
    Eigen::Index count = 0;
    while (count < moves.singularValues().size() && moves.singularValues()(count) > 3e-3 * largest) ++count;
    B = moves.matrixU().leftCols(count);
  }
  const Mat6 P = Mat6::Identity() - B * B.transpose();  // onto what the rows determine

  FrameDifference out;
  out.undetermined_directions = static_cast<int>(B.cols());
  const Vec6& twist = chain.joints()[static_cast<size_t>(k)].twist_Local;  // joint k+1, |ω| = 1
  Vec6 about_axis;
  about_axis << Vec3::Zero(), twist.tail<3>();
  out.zero_determined = (B.transpose() * about_axis).norm() < 0.1;
  Mat6 rest = P;  // the rest of the difference, as a map of it
  if (out.zero_determined) {
    const Vec6 zero = P.transpose() * about_axis;  // the zero offset's functional
    out.zero_offset_rad = zero.dot(delta);
    out.zero_offset_sigma_rad = std::sqrt(std::max(0.0, zero.dot(covariance * zero)));
    rest = P - (P * twist) * zero.transpose();
  }
  const Vec6 r = rest * delta;
  const Mat6 rest_covariance = rest * covariance * rest.transpose();
  std::tie(out.other_rotation_rad, out.other_rotation_sigma_rad) =
      sizeWithSigma(r.tail<3>(), rest_covariance.bottomRightCorner<3, 3>());
  std::tie(out.translation_m, out.translation_sigma_m) =
      sizeWithSigma(r.head<3>(), rest_covariance.topLeftCorner<3, 3>());
  return out;
}

}  // namespace

double heldOutShare(const SessionDifference& difference) {
  return difference.shared_held_out_m > 0.0 ? difference.held_out_gain_m / difference.shared_held_out_m
                                            : 0.0;
}

bool keepsOwnFrame(const SessionDifference& difference) {
  return difference.significant && heldOutShare(difference) >= kSessionDifferenceLeastShare;
}

std::vector<SessionDifference> testSessionDifferences(const KinematicChain& nominal_Base,
                                                      const std::vector<GeometricSession>& sessions,
                                                      const GeometricOptions& options, int folds) {
  std::vector<SessionDifference> out;
  const int n = nominal_Base.dof();
  if (sessions.size() < 2 || options.scope != GeometricScope::kFullPoe) return out;
  // A fold of each session: its poses in the order first measured, dealt round. A session of
  // fewer than 2 poses per fold leaves folds too small to fit on: no test then (a result).
  std::vector<std::vector<int>> fold_of(sessions.size());
  for (size_t s = 0; s < sessions.size(); ++s) {
    std::map<std::string, int> pose_fold;
    for (const Measurement* row : sessions[s].rows) {
      const auto [it, added] = pose_fold.emplace(row->pose_id, static_cast<int>(pose_fold.size()) % folds);
      fold_of[s].push_back(it->second);
    }
    if (static_cast<int>(pose_fold.size()) < 2 * folds) return out;
  }
  // Every fit the test needs, fold by fold, with frame k each session's own (k = 0: every frame
  // shared), then frame k's own on every row (fold = folds): independent, so on the cores.
  struct Fit {
    int own_frame = 0, fold = 0;
    std::optional<GeometricFit> fit;
  };
  std::vector<Fit> fits;
  for (int k = 0; k < n; ++k) {
    for (int f = 0; f <= folds; ++f) {
      if (k > 0 || f < folds) fits.push_back({k, f, {}});
    }
  }
  const auto rowsOf = [&](int fold, bool held_out) {
    std::vector<GeometricSession> part = sessions;
    for (size_t s = 0; s < sessions.size(); ++s) {
      part[s].rows.clear();
      for (size_t i = 0; i < sessions[s].rows.size(); ++i) {
        if ((fold_of[s][i] == fold) == held_out) part[s].rows.push_back(sessions[s].rows[i]);
      }
    }
    return part;
  };
  diagnosis::parallelFor(fits.size(), [&](size_t i) {
    GeometricOptions fit_options = options;
    fit_options.own_frames.clear();
    if (fits[i].own_frame > 0) fit_options.own_frames.push_back(fits[i].own_frame);
    fits[i].fit = fitGeometry(nominal_Base, rowsOf(fits[i].fold, false), fit_options);
  });
  // Held-out errors of every row under the fits with frame k own, fold by fold.
  const auto heldOut = [&](int own_frame, std::vector<double>& squared, std::vector<double>& position_m) {
    for (const Fit& fit : fits) {
      if (fit.own_frame != own_frame || fit.fold == folds) continue;
      const std::vector<GeometricSession> test = rowsOf(fit.fold, true);
      for (size_t s = 0; s < sessions.size(); ++s) {
        heldOutErrors(fit.fit->result.sessions[s].chain_Tracker, test[s].rows, sessions[s].noise,
                      squared, position_m);
      }
    }
  };
  std::vector<double> shared_squared, shared_position;
  heldOut(0, shared_squared, shared_position);
  const auto mean = [](const std::vector<double>& v) {
    double sum = 0.0;
    for (double x : v) sum += x;
    return sum / static_cast<double>(v.size());
  };
  const std::vector<std::string> names = parameterNames(nominal_Base);
  for (int k = 1; k < n; ++k) {
    SessionDifference d;
    d.frame = k;
    d.name = names[static_cast<size_t>(6 * k)].substr(0, names[static_cast<size_t>(6 * k)].rfind('.'));
    d.joint = nominal_Base.joints()[static_cast<size_t>(k)].name;
    std::vector<double> squared, position;
    heldOut(k, squared, position);
    d.shared_held_out_m = mean(shared_position);
    d.held_out_gain_m = d.shared_held_out_m - mean(position);
    d.z_statistic = diagnosis::signedRankZ(shared_squared, squared);
    d.significant = d.z_statistic > kSessionDifferenceZ;
    d.kept_per_session = keepsOwnFrame(d);
    const GeometricFit& all =
        *std::find_if(fits.begin(), fits.end(), [&](const Fit& fit) {
          return fit.own_frame == k && fit.fold == folds;
        })->fit;
    const Pose& first = all.result.sessions[0].chain_Tracker.initialPose(k);
    for (size_t s = 0; s < all.result.sessions.size(); ++s) {
      d.differences.push_back(
          lie::logSE3(first.inverse() * all.result.sessions[s].chain_Tracker.initialPose(k)));
      d.against_first.push_back(s == 0 ? FrameDifference{} : frameDifference(all, k, static_cast<int>(s)));
    }
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace stepcal::trainer
