// Whether one compliance of each joint serves every session (stiffness.hpp,
// testComplianceDifferences): held-out deflection errors of every compliance shared against one
// joint's each session's own, and each session's difference with its 1-σ.
#include <algorithm>
#include <cmath>
#include <map>

#include <Eigen/QR>

#include "stepcal/trainer/stiffness.hpp"
#include "deflection_system.hpp"
#include "diagnose/cross_validation.hpp"

namespace stepcal::trainer {
namespace {

// The design of a model: the shared joints' columns of B, then each own joint's once per session
// (zero on the other sessions' equations), in the order of own.
Eigen::MatrixXd design(const DeflectionSystem& system, const std::vector<int>& joints,
                       const std::vector<int>& own, Eigen::Index sessions) {
  const auto shared = static_cast<Eigen::Index>(joints.size() - own.size());
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(
      system.B.rows(), shared + sessions * static_cast<Eigen::Index>(own.size()));
  Eigen::Index c = 0;
  for (int j : joints) {
    if (std::find(own.begin(), own.end(), j) == own.end()) out.col(c++) = system.B.col(j);
  }
  for (int j : own) {
    for (size_t pair = 0; pair + 1 < system.first_equation.size(); ++pair) {
      const int first = system.first_equation[pair], count = system.first_equation[pair + 1] - first;
      out.block(first, c + system.session[pair], count, 1) = system.B.block(first, j, count, 1);
    }
    c += sessions;
  }
  return out;
}

// Equations of the pairs whose fold is (held_out) or is not (training) the given one.
std::vector<Eigen::Index> equationsOf(const DeflectionSystem& system, const std::vector<int>& fold_of,
                                      int fold, bool held_out) {
  std::vector<Eigen::Index> out;
  for (size_t pair = 0; pair < fold_of.size(); ++pair) {
    if ((fold_of[pair] == fold) != held_out) continue;
    for (int e = system.first_equation[pair]; e < system.first_equation[pair + 1]; ++e) out.push_back(e);
  }
  return out;
}

// Held-out errors of every pair under a design, fold by fold: the weighted squared deflection
// error, and the position error, m.
void heldOutErrors(const DeflectionSystem& system, const Eigen::MatrixXd& X,
                   const std::vector<int>& fold_of, int folds, std::vector<double>& squared,
                   std::vector<double>& position_m) {
  squared.assign(fold_of.size(), 0.0);
  position_m.assign(fold_of.size(), 0.0);
  for (int f = 0; f < folds; ++f) {
    const std::vector<Eigen::Index> train = equationsOf(system, fold_of, f, false);
    const Eigen::VectorXd c = X(train, Eigen::all).colPivHouseholderQr().solve(system.y(train));
    for (size_t pair = 0; pair < fold_of.size(); ++pair) {
      if (fold_of[pair] != f) continue;
      const int first = system.first_equation[pair], count = system.first_equation[pair + 1] - first;
      const Eigen::VectorXd r = system.y.segment(first, count) - X.middleRows(first, count) * c;
      squared[pair] = r.squaredNorm();
      position_m[pair] = r.head<3>().norm() / system.position_weight[pair];
    }
  }
}

double mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return sum / static_cast<double>(v.size());
}

}  // namespace

ComplianceDifferences testComplianceDifferences(const std::vector<StiffnessSession>& sessions,
                                                int sensor_frame, const StiffnessResult& shared,
                                                int folds) {
  ComplianceDifferences out;
  // The sessions with enough loaded poses to leave a fold out, and the rest.
  std::vector<StiffnessSession> tested;
  for (size_t s = 0; s < sessions.size(); ++s) {
    std::map<std::string, int> poses;
    for (const DeflectionPair& p : sessions[s].pairs) poses.emplace(p.unloaded->pose_id, 0);
    if (static_cast<int>(poses.size()) >= 2 * folds) {
      out.sessions.push_back(static_cast<int>(s));
      tested.push_back(sessions[s]);
    } else {
      out.untested_sessions.push_back(static_cast<int>(s));
    }
  }
  if (out.sessions.size() < 2 || sensor_frame < 0) {
    out.not_tested = "fewer than two campaigns have loaded pairs at " + std::to_string(2 * folds) +
                     " poses or more (2 per fold)";
    return out;
  }
  const DeflectionSystem system = deflectionSystem(tested, sensor_frame);
  // A pair's fold: its session's loaded poses in the order first measured, dealt round.
  std::vector<int> fold_of;
  for (const StiffnessSession& session : tested) {
    std::map<std::string, int> pose_fold;
    for (const DeflectionPair& p : session.pairs) {
      const auto [it, added] =
          pose_fold.emplace(p.unloaded->pose_id, static_cast<int>(pose_fold.size()) % folds);
      fold_of.push_back(it->second);
    }
  }
  std::vector<int> joints;  // identified in the shared fit; the others are taken as rigid
  for (size_t j = 0; j < shared.joints.size(); ++j) {
    if (shared.joints[j].excited) joints.push_back(static_cast<int>(j));
  }
  const auto session_count = static_cast<Eigen::Index>(tested.size());
  // Forward, as the diagnosis adds its families: the joint whose own compliances lower the held-out
  // error most is named when significant and kept its own while the others are tested again (a
  // joint beside it would otherwise take part of its difference and be named too).
  std::vector<int> own;
  std::vector<double> base_squared, base_position;
  heldOutErrors(system, design(system, joints, own, session_count), fold_of, folds, base_squared,
                base_position);
  std::vector<ComplianceDifference> tests(joints.size());
  while (true) {
    std::vector<std::vector<double>> squared(joints.size()), position(joints.size());
    int best = -1;
    for (size_t i = 0; i < joints.size(); ++i) {
      if (tests[i].significant) continue;
      std::vector<int> with = own;
      with.push_back(joints[i]);
      heldOutErrors(system, design(system, joints, with, session_count), fold_of, folds,
                    squared[i], position[i]);
      tests[i].held_out_gain_m = mean(base_position) - mean(position[i]);
      tests[i].z_statistic = diagnosis::signedRankZ(base_squared, squared[i]);
      if (best < 0 || tests[i].z_statistic > tests[static_cast<size_t>(best)].z_statistic) {
        best = static_cast<int>(i);
      }
    }
    if (best < 0 || tests[static_cast<size_t>(best)].z_statistic <= kComplianceDifferenceZ) break;
    tests[static_cast<size_t>(best)].significant = true;
    own.push_back(joints[static_cast<size_t>(best)]);
    base_squared = std::move(squared[static_cast<size_t>(best)]);
    base_position = std::move(position[static_cast<size_t>(best)]);
  }
  out.tested = true;
  for (size_t i = 0; i < joints.size(); ++i) {
    ComplianceDifference& d = tests[i];
    d.index = joints[i];
    d.joint = shared.joints[static_cast<size_t>(d.index)].joint;
    d.shared_rad_per_nm = shared.compliance_rad_per_nm(d.index);
    // Every pair, the named joints and this one each session's own: the sessions' values of this
    // one, their covariance and so their differences' 1-σ.
    std::vector<int> with = own;
    if (!d.significant) with.push_back(d.index);
    const Eigen::MatrixXd X = design(system, joints, with, session_count);
    const Eigen::VectorXd c = X.colPivHouseholderQr().solve(system.y);
    const double dof_residual = std::max<double>(1.0, static_cast<double>(X.rows() - X.cols()));
    const double chi2_reduced = std::max(1.0, (system.y - X * c).squaredNorm() / dof_residual);
    const Eigen::MatrixXd covariance =
        (X.transpose() * X).completeOrthogonalDecomposition().pseudoInverse() * chi2_reduced;
    const auto at = std::find(with.begin(), with.end(), d.index) - with.begin();
    const Eigen::Index first = X.cols() - session_count * static_cast<Eigen::Index>(with.size() - at);
    for (Eigen::Index s = 0; s < session_count; ++s) {
      const Eigen::Index a = first + s, b = first;
      d.difference_rad_per_nm.push_back(c(a) - c(b));
      d.difference_sigma_rad_per_nm.push_back(std::sqrt(
          std::max(0.0, covariance(a, a) + covariance(b, b) - 2.0 * covariance(a, b))));
    }
  }
  out.joints = std::move(tests);
  return out;
}

}  // namespace stepcal::trainer
