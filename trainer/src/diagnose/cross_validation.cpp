#include "cross_validation.hpp"

#include "parallel.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>

namespace stepcal::trainer::diagnosis {
namespace {

// Eigenvalues of a column-normalised Gram below this fraction of the largest are unobservable.
constexpr double kGramRankTolerance = 1e-15;

std::vector<Eigen::Index> joined(const std::vector<Eigen::Index>& a,
                                 const std::vector<Eigen::Index>& b) {
  std::vector<Eigen::Index> out = a;
  out.insert(out.end(), b.begin(), b.end());
  return out;
}

// One-sided p-value of a t statistic, normal approximation (hundreds of poses).
double upperTailP(double t) { return 0.5 * std::erfc(t / std::sqrt(2.0)); }

}  // namespace

FoldGrams::FoldGrams(Eigen::MatrixXd A, const Eigen::VectorXd& r0, const FitRows& fit) {
  const Eigen::Index p = A.cols();
  const int folds = fit.folds;
  std::vector<std::vector<int>> rows_of_fold(static_cast<size_t>(folds));
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    rows_of_fold[static_cast<size_t>(fit.fold[i])].push_back(static_cast<int>(i));
  }
  G.assign(static_cast<size_t>(folds) + 1, Eigen::MatrixXd::Zero(p, p));
  b.assign(static_cast<size_t>(folds) + 1, Eigen::VectorXd::Zero(p));
  e0.assign(static_cast<size_t>(folds), 0.0);
  parallelFor(static_cast<size_t>(folds), [&](size_t fold) {
    const int f = static_cast<int>(fold);
    Eigen::Index count = 0;
    for (int i : rows_of_fold[static_cast<size_t>(f)]) count += fit.equations(static_cast<size_t>(i));
    Eigen::MatrixXd Af(count, p);
    Eigen::VectorXd rf(count);
    Eigen::Index e = 0;
    for (int i : rows_of_fold[static_cast<size_t>(f)]) {
      const int k = fit.equations(static_cast<size_t>(i));
      Af.middleRows(e, k) = A.middleRows(fit.start[static_cast<size_t>(i)], k);
      rf.segment(e, k) = r0.segment(fit.start[static_cast<size_t>(i)], k);
      e += k;
    }
    Eigen::MatrixXd& Gf = G[static_cast<size_t>(f)];
    Gf.selfadjointView<Eigen::Lower>().rankUpdate(Af.transpose());
    Gf.triangularView<Eigen::StrictlyUpper>() = Gf.transpose();
    b[static_cast<size_t>(f)] = Af.transpose() * rf;
    e0[static_cast<size_t>(f)] = rf.squaredNorm();
  });
  for (int f = 0; f < folds; ++f) {
    G[static_cast<size_t>(folds)] += G[static_cast<size_t>(f)];
    b[static_cast<size_t>(folds)] += b[static_cast<size_t>(f)];
  }
  scale = G[static_cast<size_t>(folds)].diagonal().cwiseSqrt();
  for (Eigen::Index c = 0; c < p; ++c) {
    if (!(scale(c) > 0.0)) scale(c) = 1.0;
  }
  A_rows = A;
}

CrossValidation::CrossValidation(const FoldGrams& grams, const Eigen::VectorXd& r0,
                                 const FitRows& fit, std::vector<Eigen::Index> stage1,
                                 std::vector<Eigen::Index> stage2, Eigen::VectorXd ridge)
    : grams_(grams), r0_(r0), fit_(fit), stage1_(std::move(stage1)), stage2_(std::move(stage2)),
      ridge_(std::move(ridge)) {
  const int folds = fit.folds;
  // The current model on each fold's training rows and on every row.
  u_.resize(static_cast<size_t>(folds) + 1);
  p_.resize(u_.size());
  rhs2_.resize(u_.size());
  H_.resize(u_.size());
  base_.columns = joined(stage1_, stage2_);
  base_.x.resize(u_.size());
  for (int f = 0; f <= folds; ++f) {
    const size_t k = static_cast<size_t>(f);
    u_[k] = solveStage1(f, stage1_);
    if (!stage2_.empty()) {
      Eigen::MatrixXd H = trainingGram(f, stage2_, stage2_);
      for (size_t c = 0; c < stage2_.size(); ++c) {
        H(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(c)) += ridge_(stage2_[c]);
      }
      H_[k].compute(H);
      rhs2_[k] = trainingRhs(f, stage2_) - trainingGram(f, stage2_, stage1_) * u_[k];
      p_[k] = H_[k].solve(rhs2_[k]);
    } else {
      p_[k].resize(0);
    }
    base_.x[k].resize(static_cast<Eigen::Index>(base_.columns.size()));
    base_.x[k] << u_[k], p_[k];
    if (f < folds) base_.sse += heldOutSse(f, base_.columns, base_.x[k]);
  }
}

Eigen::MatrixXd CrossValidation::trainingGram(int f, const std::vector<Eigen::Index>& a,
                                              const std::vector<Eigen::Index>& b) const {
  const Eigen::MatrixXd& total = grams_.G[static_cast<size_t>(fit_.folds)];
  if (f == fit_.folds) return total(a, b);
  return total(a, b) - grams_.G[static_cast<size_t>(f)](a, b);
}

Eigen::VectorXd CrossValidation::trainingRhs(int f, const std::vector<Eigen::Index>& a) const {
  const Eigen::VectorXd& total = grams_.b[static_cast<size_t>(fit_.folds)];
  if (f == fit_.folds) return total(a);
  return total(a) - grams_.b[static_cast<size_t>(f)](a);
}

// Stage 1: least squares on column-normalised normal equations, truncated eigen-decomposition
// (the geometry is rank deficient by construction: METHOD.md, rank 30 of 42).
Eigen::VectorXd CrossValidation::solveStage1(int f, const std::vector<Eigen::Index>& columns) const {
  const Eigen::Index m = static_cast<Eigen::Index>(columns.size());
  Eigen::MatrixXd G = trainingGram(f, columns, columns);
  const Eigen::VectorXd b = trainingRhs(f, columns);
  Eigen::VectorXd s(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    G(a, a) += ridge_(columns[static_cast<size_t>(a)]);
    s(a) = grams_.scale(columns[static_cast<size_t>(a)]);
  }
  const Eigen::MatrixXd Gs = s.cwiseInverse().asDiagonal() * G * s.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Gs);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double cutoff = kGramRankTolerance * lambda.maxCoeff();
  const Eigen::VectorXd bs = b.cwiseQuotient(s);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    if (lambda(i) > cutoff) {
      z += eig.eigenvectors().col(i) * (eig.eigenvectors().col(i).dot(bs) / lambda(i));
    }
  }
  return z.cwiseQuotient(s);
}

double CrossValidation::heldOutSse(int f, const std::vector<Eigen::Index>& columns,
                                   const Eigen::VectorXd& x) const {
  const Eigen::MatrixXd& G = grams_.G[static_cast<size_t>(f)];
  const Eigen::VectorXd& b = grams_.b[static_cast<size_t>(f)];
  return grams_.e0[static_cast<size_t>(f)] - 2.0 * x.dot(b(columns)) +
         x.dot(G(columns, columns) * x);
}

CrossValidation::Correction CrossValidation::withGlobal(
    const std::vector<Eigen::Index>& columns) const {
  Correction out;
  const std::vector<Eigen::Index> stage1 = joined(stage1_, columns);
  out.columns = joined(stage1, stage2_);
  out.x.resize(static_cast<size_t>(fit_.folds) + 1);
  for (int f = 0; f <= fit_.folds; ++f) {
    const size_t k = static_cast<size_t>(f);
    const Eigen::VectorXd u = solveStage1(f, stage1);
    Eigen::VectorXd p(static_cast<Eigen::Index>(stage2_.size()));
    if (!stage2_.empty()) {
      p = H_[k].solve(trainingRhs(f, stage2_) - trainingGram(f, stage2_, stage1) * u);
    }
    out.x[k].resize(static_cast<Eigen::Index>(out.columns.size()));
    out.x[k] << u, p;
    if (f < fit_.folds) out.sse += heldOutSse(f, out.columns, out.x[k]);
  }
  return out;
}

CrossValidation::ProfileCandidate CrossValidation::prepareProfile(
    const std::vector<Eigen::Index>& columns) const {
  ProfileCandidate c;
  c.columns = columns;
  const size_t folds = static_cast<size_t>(fit_.folds) + 1;
  c.X.resize(folds);
  c.schur.resize(folds);
  c.rhs.resize(folds);
  for (int f = 0; f <= fit_.folds; ++f) {
    const size_t k = static_cast<size_t>(f);
    c.schur[k] = trainingGram(f, columns, columns);
    c.rhs[k] = trainingRhs(f, columns) - trainingGram(f, columns, stage1_) * u_[k];
    if (!stage2_.empty()) {
      c.X[k] = H_[k].solve(trainingGram(f, stage2_, columns));
      c.schur[k] -= trainingGram(f, columns, stage2_) * c.X[k];
      c.rhs[k] -= c.X[k].transpose() * rhs2_[k];
    }
  }
  return c;
}

CrossValidation::Correction CrossValidation::withProfile(const ProfileCandidate& candidate,
                                                         int width, double lambda) const {
  Correction out;
  const std::vector<Eigen::Index> columns(candidate.columns.begin(),
                                          candidate.columns.begin() + width);
  out.columns = joined(base_.columns, columns);
  out.x.resize(static_cast<size_t>(fit_.folds) + 1);
  for (int f = 0; f <= fit_.folds; ++f) {
    const size_t k = static_cast<size_t>(f);
    // Block elimination: the leading block of the candidate's Schur complement against the
    // current profiles is the Schur complement of its first `width` columns.
    Eigen::MatrixXd S = candidate.schur[k].topLeftCorner(width, width);
    S.diagonal().array() += lambda;
    const Eigen::VectorXd xc = S.llt().solve(candidate.rhs[k].head(width));
    Eigen::VectorXd p = p_[k];
    if (!stage2_.empty()) p -= candidate.X[k].leftCols(width) * xc;
    out.x[k].resize(static_cast<Eigen::Index>(out.columns.size()));
    out.x[k] << u_[k], p, xc;
    if (f < fit_.folds) out.sse += heldOutSse(f, out.columns, out.x[k]);
  }
  return out;
}

CrossValidation::Stage2 CrossValidation::stage2OnAllRows() const {
  Stage2 out;
  const size_t all = static_cast<size_t>(fit_.folds);
  out.x = p_[all];
  const Eigen::Index width = static_cast<Eigen::Index>(stage2_.size());
  if (width == 0) return out;
  double e0 = 0.0;
  for (double e : grams_.e0) e0 += e;
  const Eigen::VectorXd& x = base_.x[all];
  const double sse = e0 - 2.0 * x.dot(grams_.b[all](base_.columns)) +
                     x.dot(grams_.G[all](base_.columns, base_.columns) * x);
  const double variance = std::max(0.0, sse) / std::max<double>(1.0, double(fit_.count - width));
  out.sigma = (variance * H_[all].solve(Eigen::MatrixXd::Identity(width, width)).diagonal())
                  .cwiseMax(0.0)
                  .cwiseSqrt();
  return out;
}

CrossValidation::Outcome CrossValidation::heldOut(const Correction& correction) const {
  Outcome out;
  out.pose_sse.assign(static_cast<size_t>(fit_.poses), 0.0);
  out.position_m.assign(fit_.rows.size(), 0.0);
  // Each fold's coefficients scattered over every column: a row's prediction is then one
  // contiguous dot product.
  const Eigen::Index p = grams_.A_rows.cols();
  std::vector<Eigen::VectorXd> dense(static_cast<size_t>(fit_.folds), Eigen::VectorXd::Zero(p));
  for (int f = 0; f < fit_.folds; ++f) {
    const Eigen::VectorXd& x = correction.x[static_cast<size_t>(f)];
    for (size_t a = 0; a < correction.columns.size(); ++a) {
      dense[static_cast<size_t>(f)](correction.columns[a]) += x(static_cast<Eigen::Index>(a));
    }
  }
  for (size_t i = 0; i < fit_.rows.size(); ++i) {
    const int k = fit_.equations(i), e0 = fit_.start[i];
    const Eigen::VectorXd& x = dense[static_cast<size_t>(fit_.fold[i])];
    Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Zero();
    for (int c = 0; c < k; ++c) e(c) = r0_(e0 + c) - grams_.A_rows.row(e0 + c).dot(x);
    out.pose_sse[static_cast<size_t>(fit_.pose[i])] += e.squaredNorm();
    out.position_m[i] = e.head<3>().norm() / fit_.w_p;
  }
  return out;
}

Comparison compare(const CrossValidation::Outcome& base, const CrossValidation::Outcome& with) {
  Comparison c;
  const size_t n = base.pose_sse.size();
  double sum = 0.0, sum2 = 0.0, total = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double d = base.pose_sse[i] - with.pose_sse[i];
    sum += d;
    sum2 += d * d;
    total += base.pose_sse[i];
  }
  const double mean = sum / static_cast<double>(n);
  c.relative_reduction = total > 0.0 ? sum / total : 0.0;
  const double var = (sum2 - sum * mean) / static_cast<double>(n - 1);
  c.t = var > 0.0 ? mean / std::sqrt(var / static_cast<double>(n)) : 0.0;
  c.p = upperTailP(c.t);
  double gain = 0.0;
  for (size_t i = 0; i < base.position_m.size(); ++i) gain += base.position_m[i] - with.position_m[i];
  c.gain_mm = 1e3 * gain / static_cast<double>(base.position_m.size());
  return c;
}

double pairedT(const std::vector<double>& a, const std::vector<double>& b) {
  double sum = 0.0, sum2 = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    sum += a[i] - b[i];
    sum2 += (a[i] - b[i]) * (a[i] - b[i]);
  }
  const double n = static_cast<double>(a.size()), mean = sum / n;
  const double var = (sum2 - sum * mean) / (n - 1.0);
  return var > 0.0 ? mean / std::sqrt(var / n) : 0.0;
}

}  // namespace stepcal::trainer::diagnosis
