// Truncated-SVD least squares shared by the trainer's fits (internal to stepcal::trainer).
#pragma once

#include <algorithm>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>

namespace stepcal::trainer {

// Truncated-SVD least squares on column-normalised J (via QR when tall).
struct SvdSolution {
  Eigen::VectorXd x;
  Eigen::VectorXd column_scale;  // x = z / column_scale
  Eigen::VectorXd singular_values;
  Eigen::MatrixXd V;              // right singular vectors in scaled coordinates
  int rank = 0;
};

/// The truncated SVD solution of R z ≈ rhs (R column-normalised), x = z / s.column_scale.
inline void truncatedSvdSolve(const Eigen::MatrixXd& R, const Eigen::VectorXd& rhs, double tol,
                              SvdSolution& s) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(R, Eigen::ComputeThinU | Eigen::ComputeFullV);
  s.singular_values = svd.singularValues();
  s.V = svd.matrixV();
  const double cutoff = tol * s.singular_values(0);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(R.cols());
  for (Eigen::Index i = 0; i < s.singular_values.size(); ++i) {
    if (s.singular_values(i) <= cutoff) break;
    ++s.rank;
    z += s.V.col(i) * (svd.matrixU().col(i).dot(rhs) / s.singular_values(i));
  }
  s.x = z.cwiseQuotient(s.column_scale);
}

inline SvdSolution solveTruncated(const Eigen::MatrixXd& J, const Eigen::VectorXd& r, double tol) {
  SvdSolution s;
  const Eigen::Index p = J.cols();
  s.column_scale = J.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!(s.column_scale(c) > 0.0)) s.column_scale(c) = 1.0;
  }
  const Eigen::MatrixXd Js = J * s.column_scale.cwiseInverse().asDiagonal();
  Eigen::MatrixXd R;
  Eigen::VectorXd rhs;
  if (Js.rows() >= p) {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Js);
    R = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
    rhs = (qr.householderQ().adjoint() * r).head(p);
  } else {
    R = Js;
    rhs = r;
  }
  truncatedSvdSolve(R, rhs, tol, s);
  return s;
}

/// A tall least-squares system J x ≈ r reduced block by block of rows to R x ≈ Qᵀr (R upper
/// triangular, p × p, J = Q R): what solveReduced needs, without J held whole.
class TallQr {
 public:
  explicit TallQr(Eigen::Index p) : R_(Eigen::MatrixXd::Zero(0, p)), qtr_(0) {}
  /// Appends rows of J and their r.
  void add(const Eigen::MatrixXd& J, const Eigen::VectorXd& r) {
    Eigen::MatrixXd stacked(R_.rows() + J.rows(), R_.cols());
    stacked << R_, J;
    Eigen::VectorXd rhs(stacked.rows());
    rhs << qtr_, r;
    reduce(stacked, rhs);
  }
  /// Appends another reduction's rows (its R and Qᵀr).
  void add(const TallQr& other) { add(other.R_, other.qtr_); }
  const Eigen::MatrixXd& R() const { return R_; }
  const Eigen::VectorXd& qtr() const { return qtr_; }

 private:
  void reduce(const Eigen::MatrixXd& A, const Eigen::VectorXd& r) {
    const Eigen::Index p = A.cols();
    if (A.rows() <= p) {
      R_ = A;
      qtr_ = r;
      return;
    }
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(A);
    R_ = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
    qtr_ = (qr.householderQ().adjoint() * r).head(p);
  }
  Eigen::MatrixXd R_;
  Eigen::VectorXd qtr_;
};

/// solveTruncated on a reduced system: the same x, singular values, V and rank as on J, r (R's
/// columns have J's norms, its singular values J's).
inline SvdSolution solveReduced(const TallQr& system, double tol) {
  SvdSolution s;
  const Eigen::MatrixXd& R = system.R();
  const Eigen::Index p = R.cols();
  s.column_scale = R.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!(s.column_scale(c) > 0.0)) s.column_scale(c) = 1.0;
  }
  truncatedSvdSolve(R * s.column_scale.cwiseInverse().asDiagonal(), system.qtr(), tol, s);
  return s;
}

/// solveReduced under lower bounds x ≥ lower (−∞: none; every lower ≤ 0, so x = 0 is feasible):
/// an active set (Lawson–Hanson's, for bounds) of truncated-SVD solves. From x = 0 it moves toward
/// the solution with the bounded variables not held, stops at the first bound that solution
/// crosses and holds that variable there; once the solution is feasible it frees the held
/// variable whose bound the residual pushes against least (a negative gradient), until none is.
/// at_bound: per variable, whether it ends held at its bound (x = lower exactly).
inline Eigen::VectorXd solveReducedBounded(const TallQr& system, double tol,
                                           const Eigen::VectorXd& lower,
                                           std::vector<bool>* at_bound = nullptr) {
  const Eigen::MatrixXd& R = system.R();
  const Eigen::Index p = R.cols();
  Eigen::VectorXd scale = R.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!(scale(c) > 0.0)) scale(c) = 1.0;
  }
  const Eigen::MatrixXd Rs = R * scale.cwiseInverse().asDiagonal();
  const Eigen::VectorXd& b = system.qtr();
  const Eigen::VectorXd lz = lower.cwiseProduct(scale);  // the bounds in scaled coordinates
  std::vector<bool> held(static_cast<size_t>(p), false);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(p);
  // Each pass holds one more variable or frees one from a feasible better point: a few passes;
  // the cap only guards against cycling on rounding.
  for (Eigen::Index pass = 0; pass < 3 * p + 3; ++pass) {
    std::vector<Eigen::Index> free;
    Eigen::VectorXd rhs = b;
    for (Eigen::Index c = 0; c < p; ++c) {
      if (held[static_cast<size_t>(c)]) {
        rhs -= Rs.col(c) * lz(c);
      } else {
        free.push_back(c);
      }
    }
    Eigen::VectorXd trial = z;
    if (!free.empty()) {
      SvdSolution s;
      s.column_scale = Eigen::VectorXd::Ones(static_cast<Eigen::Index>(free.size()));
      truncatedSvdSolve(Rs(Eigen::all, free), rhs, tol, s);
      for (size_t k = 0; k < free.size(); ++k) trial(free[k]) = s.x(static_cast<Eigen::Index>(k));
    }
    double alpha = 1.0;
    Eigen::Index blocking = -1;
    for (Eigen::Index c : free) {
      if (trial(c) >= lz(c)) continue;
      const double a = (lz(c) - z(c)) / (trial(c) - z(c));
      if (a < alpha) {
        alpha = std::max(0.0, a);
        blocking = c;
      }
    }
    if (blocking >= 0) {
      z += alpha * (trial - z);
      z(blocking) = lz(blocking);
      held[static_cast<size_t>(blocking)] = true;
      continue;
    }
    z = trial;
    // ∂(½|Rs z − b|²)/∂z_c < 0 at a held variable: the residual falls as it leaves its bound.
    const Eigen::VectorXd gradient = Rs.transpose() * (Rs * z - b);
    const double negligible = 1e-12 * (Rs.transpose() * b).cwiseAbs().maxCoeff();
    Eigen::Index release = -1;
    for (Eigen::Index c = 0; c < p; ++c) {
      if (held[static_cast<size_t>(c)] && gradient(c) < -negligible &&
          (release < 0 || gradient(c) < gradient(release))) {
        release = c;
      }
    }
    if (release < 0) break;
    held[static_cast<size_t>(release)] = false;
  }
  Eigen::VectorXd x = z.cwiseQuotient(scale);
  for (Eigen::Index c = 0; c < p; ++c) {
    if (held[static_cast<size_t>(c)]) x(c) = lower(c);
  }
  if (at_bound) *at_bound = held;
  return x;
}

/// The active set of a least-squares problem under linear inequalities A z ≥ d (every d ≤ 0, so
/// z = 0 is feasible): the bounds' method of solveReducedBounded for general rows (primal, as in
/// Gill, Murray and Wright). The rows held are kept as equalities: the trial point is z_W + N y,
/// z_W the least-norm point with A_W z = d_W, N an orthonormal basis of A_W's null space, y the
/// objective's truncated minimiser on that affine set, minimise(N, z_W). From z = 0 it moves toward
/// the trial point, stops at the first row that point violates and holds it; once the trial point
/// is feasible it frees the held row whose multiplier (A_Wᵀ λ = gradient(z)) is most negative,
/// below −negligible, until none is. active: per row, whether it ends held (A_i z = d_i).
template <class Minimise, class Gradient>
Eigen::VectorXd activeSetSolve(Eigen::Index p, const Eigen::MatrixXd& A, const Eigen::VectorXd& d,
                               const Minimise& minimise, const Gradient& gradient,
                               double negligible, std::vector<bool>* active) {
  const Eigen::Index rows = A.rows();
  std::vector<bool> held(static_cast<size_t>(rows), false);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(p);
  // Each pass holds one more row or frees one from a feasible better point: a few passes; the
  // cap only guards against cycling on rounding.
  for (Eigen::Index pass = 0; pass < 3 * (rows + p) + 3; ++pass) {
    std::vector<Eigen::Index> w;
    for (Eigen::Index i = 0; i < rows; ++i) {
      if (held[static_cast<size_t>(i)]) w.push_back(i);
    }
    Eigen::VectorXd z_w = Eigen::VectorXd::Zero(p);
    Eigen::MatrixXd N = Eigen::MatrixXd::Identity(p, p);
    if (!w.empty()) {
      const Eigen::MatrixXd A_w = A(w, Eigen::all);
      z_w = A_w.completeOrthogonalDecomposition().solve(d(w));
      const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A_w.transpose());
      const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(p, p);
      N = Q.rightCols(p - qr.rank());
    }
    const Eigen::VectorXd trial = N.cols() > 0 ? Eigen::VectorXd(z_w + minimise(N, z_w)) : z_w;
    // The first row not held that the way to the trial point crosses. A row the held ones span
    // (at a vertex where more rows meet than there are variables, as at a lumped link's zero
    // mass) is not held too, and one the way runs along only by rounding blocks nothing: the held
    // rows stay independent, so their multipliers are unique and a stalled vertex is left.
    double alpha = 1.0;
    Eigen::Index blocking = -1;
    const Eigen::VectorXd at = A * z, towards = A * trial;
    const double way = (trial - z).norm();
    for (Eigen::Index i = 0; i < rows; ++i) {
      if (held[static_cast<size_t>(i)] || towards(i) >= d(i) || towards(i) >= at(i)) continue;
      const double size = A.row(i).norm();
      if (towards(i) - at(i) > -1e-12 * size * way) continue;
      if ((N.transpose() * A.row(i).transpose()).norm() <= 1e-10 * size) continue;
      const double a = (d(i) - at(i)) / (towards(i) - at(i));
      if (a < alpha) {
        alpha = std::max(0.0, a);
        blocking = i;
      }
    }
    if (blocking >= 0) {
      z += alpha * (trial - z);
      held[static_cast<size_t>(blocking)] = true;
      continue;
    }
    z = trial;
    if (w.empty()) break;
    // KKT: the gradient is A_Wᵀ λ; λ_i < 0 at a held row: the objective falls as z leaves it.
    const Eigen::VectorXd lambda =
        A(w, Eigen::all).transpose().completeOrthogonalDecomposition().solve(gradient(z));
    Eigen::Index release = -1;
    for (Eigen::Index k = 0; k < lambda.size(); ++k) {
      if (lambda(k) < -negligible && (release < 0 || lambda(k) < lambda(release))) release = k;
    }
    if (release < 0) break;
    held[static_cast<size_t>(w[static_cast<size_t>(release)])] = false;
  }
  if (active) *active = held;
  return z;
}

/// min ½|Rs z − b|² under A z ≥ d (activeSetSolve), Rs already column-normalised: on each affine
/// set the truncated-SVD solution of Rs N y ≈ b − Rs z_W (with no row held, exactly
/// truncatedSvdSolve's).
inline Eigen::VectorXd solveConstrainedScaled(const Eigen::MatrixXd& Rs, const Eigen::VectorXd& b,
                                              double tol, const Eigen::MatrixXd& A,
                                              const Eigen::VectorXd& d,
                                              std::vector<bool>* active = nullptr) {
  const auto minimise = [&](const Eigen::MatrixXd& N, const Eigen::VectorXd& z_w) {
    SvdSolution s;
    s.column_scale = Eigen::VectorXd::Ones(N.cols());
    truncatedSvdSolve(Rs * N, b - Rs * z_w, tol, s);
    return Eigen::VectorXd(N * s.x);
  };
  const auto gradient = [&](const Eigen::VectorXd& z) {
    return Eigen::VectorXd(Rs.transpose() * (Rs * z - b));
  };
  const double negligible = 1e-12 * (Rs.transpose() * b).cwiseAbs().maxCoeff();
  return activeSetSolve(Rs.cols(), A, d, minimise, gradient, negligible, active);
}

/// min ½ zᵀ G z − bᵀ z under A z ≥ d (activeSetSolve), G symmetric, ≥ 0 and normalised: on each
/// affine set the eigenvalues of NᵀGN above tol times the largest (a truncated solve of the normal
/// equations; with no row held, G's own truncated solve).
inline Eigen::VectorXd solveConstrainedGram(const Eigen::MatrixXd& G, const Eigen::VectorXd& b,
                                            double tol, const Eigen::MatrixXd& A,
                                            const Eigen::VectorXd& d) {
  const auto minimise = [&](const Eigen::MatrixXd& N, const Eigen::VectorXd& z_w) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(N.transpose() * G * N);
    const Eigen::VectorXd& lambda = eig.eigenvalues();
    const Eigen::VectorXd rhs = N.transpose() * (b - G * z_w);
    const double cutoff = tol * lambda.maxCoeff();
    Eigen::VectorXd y = Eigen::VectorXd::Zero(N.cols());
    for (Eigen::Index i = 0; i < lambda.size(); ++i) {
      if (lambda(i) > cutoff) y += eig.eigenvectors().col(i) * (eig.eigenvectors().col(i).dot(rhs) / lambda(i));
    }
    return Eigen::VectorXd(N * y);
  };
  const auto gradient = [&](const Eigen::VectorXd& z) { return Eigen::VectorXd(G * z - b); };
  const double negligible = 1e-12 * b.cwiseAbs().maxCoeff();
  return activeSetSolve(G.cols(), A, d, minimise, gradient, negligible, nullptr);
}

/// solveReduced under linear inequalities C x ≥ d (every d ≤ 0: x = 0 is feasible), the exact
/// constrained least-squares step (solveConstrainedScaled on the column-normalised system).
/// active: per row of C, whether it ends held.
inline Eigen::VectorXd solveReducedConstrained(const TallQr& system, double tol,
                                               const Eigen::MatrixXd& C, const Eigen::VectorXd& d,
                                               std::vector<bool>* active = nullptr) {
  const Eigen::MatrixXd& R = system.R();
  const Eigen::Index p = R.cols();
  Eigen::VectorXd scale = R.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!(scale(c) > 0.0)) scale(c) = 1.0;
  }
  const Eigen::MatrixXd Rs = R * scale.cwiseInverse().asDiagonal();
  const Eigen::MatrixXd A = C * scale.cwiseInverse().asDiagonal();
  return solveConstrainedScaled(Rs, system.qtr(), tol, A, d, active).cwiseQuotient(scale);
}

}  // namespace stepcal::trainer
