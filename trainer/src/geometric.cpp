#include "stepcal/trainer/geometric.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/trainer/registration.hpp"
#include "geometric_fit.hpp"

namespace stepcal::trainer {
namespace {

// Fit statistics of one session's rows.
struct SessionStats {
  double sum_p2 = 0.0, sum_r2 = 0.0;
  int rows = 0, oriented = 0;
};

// Weighted, linearised error model of all sessions' rows at their current chains: J δ ≈ r.
struct LinearSystem {
  Eigen::MatrixXd J;   // equations × fitted parameters, rows divided by σ
  Eigen::VectorXd r;   // weighted residuals
  IterationRecord stats;
  std::vector<SessionStats> sessions;
};

LinearSystem linearise(const std::vector<KinematicChain>& chains,
                       const std::vector<GeometricSession>& sessions, const ParameterLayout& layout) {
  const int n = chains[0].dof();
  int equations = 0;
  for (const GeometricSession& session : sessions) {
    for (const Measurement* row : session.rows) equations += row->has_orientation ? 6 : 3;
  }
  LinearSystem sys;
  sys.J.setZero(equations, layout.count());
  sys.r.setZero(equations);
  sys.sessions.resize(sessions.size());

  ChainWorkspace ws;
  Eigen::Matrix<double, 6, Eigen::Dynamic> A(6, 6 * (n + 1));
  std::vector<std::pair<int, int>> fitted;  // (chain parameter, column) of the session
  int eq = 0;
  for (size_t s = 0; s < sessions.size(); ++s) {
    const KinematicChain& chain = chains[s];
    const double w_p = 1.0 / sessions[s].noise.position_sigma_m;
    const double w_r = 1.0 / sessions[s].noise.orientation_sigma_rad;
    fitted.clear();
    for (int i = 0; i < 6 * (n + 1); ++i) {
      if (const int c = layout.column(static_cast<int>(s), i); c >= 0) fitted.emplace_back(i, c);
    }
    SessionStats& stats = sys.sessions[s];
    for (const Measurement* row : sessions[s].rows) {
      forwardKinematics(chain, row->q_rad, ws);
      parameterJacobian(chain, ws, A);
      const Pose& X = tipPose(ws);
      // Tip point velocity from the spatial twist: ṗ = v − p̂ ω.
      const Eigen::Matrix<double, 3, Eigen::Dynamic> A_p =
          A.topRows<3>() - lie::hat(X.translation()) * A.bottomRows<3>();
      const Vec3 r_p = row->p_TipInTracker_m - X.translation();
      stats.sum_p2 += r_p.squaredNorm();
      ++stats.rows;
      for (const auto& [i, c] : fitted) sys.J.block<3, 1>(eq, c) = w_p * A_p.col(i);
      sys.r.segment<3>(eq) = w_p * r_p;
      eq += 3;
      if (row->has_orientation) {
        const Vec3 r_R = lie::logSO3(row->q_TrackerTip.toRotationMatrix() * X.linear().transpose());
        stats.sum_r2 += r_R.squaredNorm();
        ++stats.oriented;
        // log(exp(r̂)·exp(−ω̂)) ≈ r − Jr⁻¹(r) ω for the update exp(ω̂) on the model's rotation.
        const Mat3 Jr_inv = lie::rightJacobianInverseSO3(r_R);
        for (const auto& [i, c] : fitted) sys.J.block<3, 1>(eq, c) = w_r * Jr_inv * A.block<3, 1>(3, i);
        sys.r.segment<3>(eq) = w_r * r_R;
        eq += 3;
      }
    }
  }
  SessionStats all;
  for (const SessionStats& s : sys.sessions) {
    all.sum_p2 += s.sum_p2;
    all.sum_r2 += s.sum_r2;
    all.rows += s.rows;
    all.oriented += s.oriented;
  }
  sys.stats.rms_position_m = std::sqrt(all.sum_p2 / static_cast<double>(all.rows));
  sys.stats.rms_orientation_rad = all.oriented > 0 ? std::sqrt(all.sum_r2 / all.oriented) : 0.0;
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

// Names of the fit's unknowns: the chain's parameter names, a session's own frames prefixed
// with its number when there are several.
std::vector<std::string> unknownNames(const KinematicChain& chain, const ParameterLayout& layout) {
  const std::vector<std::string> chain_names = parameterNames(chain);
  std::vector<std::string> names(static_cast<size_t>(layout.count()));
  for (int session = 0; session < layout.sessions(); ++session) {
    for (size_t i = 0; i < chain_names.size(); ++i) {
      const int c = layout.column(session, static_cast<int>(i));
      if (c < 0) continue;
      const bool own = layout.columns(static_cast<int>(i)).size() > 1;
      names[static_cast<size_t>(c)] =
          own ? "session " + std::to_string(session + 1) + " " + chain_names[i] : chain_names[i];
    }
  }
  return names;
}

// Names the null space: first the model's structural redundancies (a rotation about and a
// translation along each joint axis trade between the two initial poses beside the joint),
// then whatever else the data leave unobserved, in reduced row-echelon form.
Observability analyseObservability(const KinematicChain& chain, const ParameterLayout& layout,
                                   const SvdSolution& s) {
  Observability obs;
  const Eigen::Index p = layout.count();
  obs.parameter_count = static_cast<int>(p);
  obs.rank = s.rank;
  obs.condition_number = s.singular_values(0) / s.singular_values(std::max(s.rank - 1, 0));
  const Eigen::Index nullity = p - s.rank;
  if (nullity == 0) return obs;
  const Eigen::MatrixXd N = s.V.rightCols(nullity);  // scaled coordinates

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
      // A session's own frame beside the joint moves alike in every session.
      for (int c = 0; c < 6; ++c) {
        const std::vector<int> a = layout.columns(6 * (i - 1) + c);
        const std::vector<int> b = layout.columns(6 * i + c);
        if ((a.empty() && std::abs(twist(c)) > 0) || (b.empty() && std::abs(after(c)) > 0)) {
          representable = false;
        }
        for (int column : a) d(column) += twist(c);
        for (int column : b) d(column) += after(c);
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
  const std::vector<std::string> names = unknownNames(chain, layout);
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

// The first session's chain parameters' covariance factor F (Σ = F Fᵀ, 6(n+1) × rank): the
// truncated SVD's V S⁻¹ on its retained directions, back in physical units, times √χ²_red when
// the rows scatter more than stated. Parameters the fit does not take get zero rows.
Eigen::MatrixXd chainCovarianceFactor(const ParameterLayout& layout, const SvdSolution& svd, int n,
                                      double chi2_reduced) {
  const Eigen::MatrixXd W = svd.V.leftCols(svd.rank) *
                            svd.singular_values.head(svd.rank).cwiseInverse().asDiagonal() *
                            std::sqrt(std::max(1.0, chi2_reduced));
  Eigen::MatrixXd F = Eigen::MatrixXd::Zero(6 * (n + 1), svd.rank);
  for (int i = 0; i < 6 * (n + 1); ++i) {
    if (const int c = layout.column(0, i); c >= 0) F.row(i) = W.row(c) / svd.column_scale(c);
  }
  if (F.cols() <= F.rows()) return F;
  // Several campaigns: their own frames add columns beyond the chain's 6(n + 1) parameters. The
  // chain's marginal covariance F Fᵀ, factored again as V √Λ over its positive eigenvalues, has
  // at most as many columns as rows (the model file's layout).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(F * F.transpose());
  const Eigen::VectorXd& lambda = eigen.eigenvalues();  // ascending
  const double floor = lambda.maxCoeff() * 1e-14;
  Eigen::Index kept = 0;
  while (kept < lambda.size() && lambda(lambda.size() - 1 - kept) > floor) ++kept;
  return eigen.eigenvectors().rightCols(kept) * lambda.tail(kept).cwiseSqrt().asDiagonal();
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
  return calibrateGeometry(nominal_Base, std::vector<GeometricSession>{{rows, noise}}, options);
}

GeometricResult calibrateGeometry(const KinematicChain& nominal_Base,
                                  const std::vector<GeometricSession>& sessions,
                                  const GeometricOptions& options) {
  return fitGeometry(nominal_Base, sessions, options).result;
}

GeometricFit fitGeometry(const KinematicChain& nominal_Base, const std::vector<GeometricSession>& sessions,
                         const GeometricOptions& options) {
  const int n = nominal_Base.dof();
  if (sessions.empty()) throw InputError("geometric calibration needs at least one session");
  for (size_t s = 0; s < sessions.size(); ++s) {
    const std::string which = "session " + std::to_string(s + 1) + ": ";
    for (const Measurement* row : sessions[s].rows) {
      if (row->q_rad.size() != n) {
        throw InputError(which + "row has " + std::to_string(row->q_rad.size()) +
                             " joint angles but the robot chain has " + std::to_string(n),
                         "measurements.csv", row->source_line);
      }
    }
    if (sessions[s].rows.size() < 3) {
      throw InputError(which + "geometric calibration needs at least 3 fit rows (set=geometry) "
                       "to register its tracker, got " + std::to_string(sessions[s].rows.size()));
    }
  }
  GeometricResult result;
  std::vector<KinematicChain> chains;
  for (const GeometricSession& session : sessions) {
    SessionFrames frames;
    frames.fit_rows = static_cast<int>(session.rows.size());
    frames.X_TrackerBase = registerTracker(nominal_Base, session.rows);
    KinematicChain chain = nominal_Base.rerooted(frames.X_TrackerBase);
    Pose X_ToolCorrection = Pose::Identity();
    X_ToolCorrection.linear() = registerToolRotation(chain, session.rows);
    chain.setInitialPose(n, chain.initialPose(n) * X_ToolCorrection);
    chains.push_back(std::move(chain));
    result.fit_rows += frames.fit_rows;
    result.sessions.push_back(std::move(frames));
  }
  result.X_TrackerBase = result.sessions[0].X_TrackerBase;
  const ParameterLayout layout(n, static_cast<int>(sessions.size()), options);

  double previous_cost = 0.0;
  SvdSolution last;
  LinearSystem sys;
  for (int it = 0;; ++it) {
    sys = linearise(chains, sessions, layout);
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
    for (size_t s = 0; s < chains.size(); ++s) {
      chains[s] = chains[s].corrected(layout.chainDelta(static_cast<int>(s), last.x));
    }
    result.iterations = it + 1;
    previous_cost = sys.stats.weighted_cost;
  }
  for (size_t s = 0; s < chains.size(); ++s) {
    SessionFrames& frames = result.sessions[s];
    const SessionStats& stats = sys.sessions[s];
    frames.rms_position_m = std::sqrt(stats.sum_p2 / static_cast<double>(stats.rows));
    frames.rms_orientation_rad = stats.oriented > 0 ? std::sqrt(stats.sum_r2 / stats.oriented) : 0.0;
    frames.chain_Tracker = chains[s];
  }
  result.chain_Tracker = chains[0];
  result.observability = analyseObservability(chains[0], layout, last);
  if (sessions.size() > 1) result.own_frames = options.own_frames;
  const double dof_residual = std::max<double>(1.0, static_cast<double>(sys.r.size() - last.rank));
  const double chi2_reduced = sys.stats.weighted_cost / dof_residual;
  result.covariance_factor = chainCovarianceFactor(layout, last, n, chi2_reduced);
  return {std::move(result), layout, std::move(last), chi2_reduced};
}

}  // namespace stepcal::trainer
