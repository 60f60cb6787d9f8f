#include "stepcal/trainer/geometric.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/registration.hpp"
#include "least_squares.hpp"

namespace stepcal::trainer {
namespace {

// Weighted, linearised error model of all rows at the current chain: J δ ≈ r.
struct LinearSystem {
  Eigen::MatrixXd J;   // equations × active parameters, rows divided by σ
  Eigen::VectorXd r;   // weighted residuals
  IterationRecord stats;
};

LinearSystem linearise(const KinematicChain& chain, const std::vector<const Measurement*>& rows,
                       const std::vector<int>& active, const TrackerNoise& noise) {
  const int n = chain.dof();
  int equations = 0;
  for (const Measurement* row : rows) equations += row->has_orientation ? 6 : 3;
  LinearSystem sys;
  sys.J.setZero(equations, static_cast<Eigen::Index>(active.size()));
  sys.r.setZero(equations);
  const double w_p = 1.0 / noise.position_sigma_m;
  const double w_r = 1.0 / noise.orientation_sigma_rad;

  ChainWorkspace ws;
  Eigen::Matrix<double, 6, Eigen::Dynamic> A(6, 6 * (n + 1));
  double sum_p2 = 0.0, sum_r2 = 0.0;
  int oriented = 0, eq = 0;
  for (const Measurement* row : rows) {
    forwardKinematics(chain, row->q_rad, ws);
    parameterJacobian(chain, ws, A);
    const Pose& X = tipPose(ws);
    // Tip point velocity from the spatial twist: ṗ = v − p̂ ω.
    const Eigen::Matrix<double, 3, Eigen::Dynamic> A_p =
        A.topRows<3>() - lie::hat(X.translation()) * A.bottomRows<3>();
    const Vec3 r_p = row->p_TipInTracker_m - X.translation();
    sum_p2 += r_p.squaredNorm();
    for (size_t c = 0; c < active.size(); ++c) sys.J.block<3, 1>(eq, c) = w_p * A_p.col(active[c]);
    sys.r.segment<3>(eq) = w_p * r_p;
    eq += 3;
    if (row->has_orientation) {
      const Vec3 r_R = lie::logSO3(row->q_TrackerTip.toRotationMatrix() * X.linear().transpose());
      sum_r2 += r_R.squaredNorm();
      ++oriented;
      // log(exp(r̂)·exp(−ω̂)) ≈ r − Jr⁻¹(r) ω for the update exp(ω̂) on the model's rotation.
      const Mat3 Jr_inv = lie::rightJacobianInverseSO3(r_R);
      for (size_t c = 0; c < active.size(); ++c) {
        sys.J.block<3, 1>(eq, c) = w_r * Jr_inv * A.block<3, 1>(3, active[c]);
      }
      sys.r.segment<3>(eq) = w_r * r_R;
      eq += 3;
    }
  }
  sys.stats.rms_position_m = std::sqrt(sum_p2 / static_cast<double>(rows.size()));
  sys.stats.rms_orientation_rad = oriented > 0 ? std::sqrt(sum_r2 / oriented) : 0.0;
  sys.stats.weighted_cost = sys.r.squaredNorm();
  return sys;
}

const char* kComponent[6] = {"tx", "ty", "tz", "rx", "ry", "rz"};

std::string blockName(const KinematicChain& chain, int k) {
  const int n = chain.dof();
  const std::string from = k == 0 ? "root" : chain.joints()[static_cast<size_t>(k - 1)].name;
  const std::string to = k == n ? "tip" : chain.joints()[static_cast<size_t>(k)].name;
  return "T(" + from + "->" + to + ")";
}

std::string formatCombination(const Eigen::VectorXd& v, const std::vector<std::string>& names) {
  std::vector<Eigen::Index> order(static_cast<size_t>(v.size()));
  for (Eigen::Index i = 0; i < v.size(); ++i) order[static_cast<size_t>(i)] = i;
  std::sort(order.begin(), order.end(),
            [&](Eigen::Index a, Eigen::Index b) { return std::abs(v(a)) > std::abs(v(b)); });
  const double biggest = std::abs(v(order[0]));
  std::ostringstream out;
  out.precision(2);
  int terms = 0;
  for (Eigen::Index i : order) {
    if (std::abs(v(i)) < 0.05 * biggest || terms == 5) break;
    out << (v(i) < 0 ? (terms ? " - " : "-") : (terms ? " + " : "")) << std::fixed
        << std::abs(v(i) / biggest) << "*" << names[static_cast<size_t>(i)];
    ++terms;
  }
  return out.str();
}

// Names the null space: first the model's structural redundancies (a rotation about and a
// translation along each joint axis trade between the two initial poses beside the joint),
// then whatever else the data leave unobserved, in reduced row-echelon form.
Observability analyseObservability(const KinematicChain& chain, const std::vector<int>& active,
                                   const SvdSolution& s) {
  Observability obs;
  const Eigen::Index p = static_cast<Eigen::Index>(active.size());
  obs.parameter_count = static_cast<int>(p);
  obs.rank = s.rank;
  obs.condition_number = s.singular_values(0) / s.singular_values(std::max(s.rank - 1, 0));
  const Eigen::Index nullity = p - s.rank;
  if (nullity == 0) return obs;
  const Eigen::MatrixXd N = s.V.rightCols(nullity);  // scaled coordinates

  std::vector<int> position_of(static_cast<size_t>(6 * (chain.dof() + 1)), -1);
  for (size_t c = 0; c < active.size(); ++c) position_of[static_cast<size_t>(active[c])] = c;

  Eigen::MatrixXd accepted(p, 0);
  const int n = chain.dof();
  for (int i = 1; i <= n; ++i) {
    const ChainJoint& joint = chain.joints()[static_cast<size_t>(i - 1)];
    const Mat6 Ad_next_inv = lie::adjoint(chain.initialPose(i).inverse());
    Vec6 translation_along;
    translation_along << joint.twist_Local.tail<3>(), Vec3::Zero();
    const std::pair<Vec6, std::string> candidates[2] = {
        {joint.twist_Local, "rotation about " + joint.name + "'s axis (joint zero offset)"},
        {translation_along, "translation along " + joint.name + "'s axis"}};
    for (const auto& [twist, what] : candidates) {
      Eigen::VectorXd d = Eigen::VectorXd::Zero(p);
      const Vec6 after = -Ad_next_inv * twist;
      bool representable = true;
      for (int c = 0; c < 6; ++c) {
        const int a = position_of[static_cast<size_t>(6 * (i - 1) + c)];
        const int b = position_of[static_cast<size_t>(6 * i + c)];
        if ((a < 0 && std::abs(twist(c)) > 0) || (b < 0 && std::abs(after(c)) > 0)) {
          representable = false;
        }
        if (a >= 0) d(a) += twist(c);
        if (b >= 0) d(b) += after(c);
      }
      if (!representable) continue;
      d = d.cwiseProduct(s.column_scale);
      d.normalize();
      if ((N.transpose() * d).norm() < 0.999) continue;
      accepted.conservativeResize(p, accepted.cols() + 1);
      accepted.col(accepted.cols() - 1) = d;
      obs.unobservable.push_back(
          {what + ": trades between " + blockName(chain, i - 1) + " and " + blockName(chain, i),
           true});
    }
  }

  // What remains of the null space beyond the structural part.
  const Eigen::Index rest = nullity - accepted.cols();
  if (rest <= 0) return obs;
  Eigen::MatrixXd N_rest = N;
  if (accepted.cols() > 0) {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(accepted);
    const Eigen::MatrixXd Q =
        qr.householderQ() * Eigen::MatrixXd::Identity(p, accepted.cols());
    N_rest -= Q * (Q.transpose() * N);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(N_rest, Eigen::ComputeThinU);
  Eigen::MatrixXd M = svd.matrixU().leftCols(rest).transpose();  // rest × p
  // Back to physical parameter units so the printed ratios are in m and rad.
  M = M * s.column_scale.asDiagonal();
  std::vector<std::string> names_all = parameterNames(chain), names;
  for (int a : active) names.push_back(names_all[static_cast<size_t>(a)]);
  // Gauss–Jordan with the largest available pivot per row.
  std::vector<bool> used(static_cast<size_t>(p), false);
  for (Eigen::Index row = 0; row < M.rows(); ++row) {
    Eigen::Index pivot = 0;
    double best = -1.0;
    for (Eigen::Index c = 0; c < p; ++c) {
      if (!used[static_cast<size_t>(c)] && std::abs(M(row, c)) > best) {
        best = std::abs(M(row, c));
        pivot = c;
      }
    }
    used[static_cast<size_t>(pivot)] = true;
    M.row(row) /= M(row, pivot);
    for (Eigen::Index other = 0; other < M.rows(); ++other) {
      if (other != row) M.row(other) -= M(other, pivot) * M.row(row);
    }
  }
  for (Eigen::Index row = 0; row < M.rows(); ++row) {
    obs.unobservable.push_back(
        {"not excited by these rows: " + formatCombination(M.row(row).transpose(), names), false});
  }
  return obs;
}

}  // namespace

std::vector<std::string> parameterNames(const KinematicChain& chain) {
  std::vector<std::string> names;
  for (int k = 0; k <= chain.dof(); ++k) {
    for (const char* c : kComponent) names.push_back(blockName(chain, k) + "." + c);
  }
  return names;
}

GeometricResult calibrateGeometry(const KinematicChain& nominal_Base,
                                  const std::vector<const Measurement*>& rows,
                                  const TrackerNoise& noise, const GeometricOptions& options) {
  const int n = nominal_Base.dof();
  for (const Measurement* row : rows) {
    if (row->q_rad.size() != n) {
      throw InputError("row has " + std::to_string(row->q_rad.size()) +
                           " joint angles but the robot chain has " + std::to_string(n),
                       "measurements.csv", row->source_line);
    }
  }
  if (rows.size() < 3) {
    throw InputError("geometric calibration needs at least 3 fit rows (set=geometry), got " +
                     std::to_string(rows.size()));
  }
  GeometricResult result;
  result.fit_rows = static_cast<int>(rows.size());
  result.X_TrackerBase = registerTracker(nominal_Base, rows);
  KinematicChain chain = nominal_Base.rerooted(result.X_TrackerBase);
  Pose X_ToolCorrection = Pose::Identity();
  X_ToolCorrection.linear() = registerToolRotation(chain, rows);
  chain.setInitialPose(n, chain.initialPose(n) * X_ToolCorrection);

  std::vector<int> active;
  for (int k = 0; k <= n; ++k) {
    if (options.scope == GeometricScope::kFullPoe || k == 0 || k == n) {
      for (int c = 0; c < 6; ++c) active.push_back(6 * k + c);
    }
  }

  double previous_cost = 0.0;
  SvdSolution last;
  for (int it = 0;; ++it) {
    LinearSystem sys = linearise(chain, rows, active, noise);
    sys.stats.iteration = it;
    result.history.push_back(sys.stats);
    last = solveTruncated(sys.J, sys.r, options.rank_tolerance);
    // Converged when the last update no longer lowers the cost, or the next one is below
    // a picometre / picoradian (noiseless data approach zero cost, so only the step tells).
    const bool stalled = previous_cost - sys.stats.weighted_cost <=
                         options.relative_cost_tolerance * previous_cost;
    if (it > 0 && (stalled || last.x.cwiseAbs().maxCoeff() < 1e-12)) {
      result.converged = true;
      break;
    }
    if (it == options.max_iterations) break;
    Eigen::VectorXd delta = Eigen::VectorXd::Zero(6 * (n + 1));
    for (size_t c = 0; c < active.size(); ++c) delta(active[c]) = last.x(static_cast<Eigen::Index>(c));
    chain = chain.corrected(delta);
    result.iterations = it + 1;
    previous_cost = sys.stats.weighted_cost;
  }
  result.chain_Tracker = chain;
  result.observability = analyseObservability(chain, active, last);
  return result;
}

}  // namespace stepcal::trainer
