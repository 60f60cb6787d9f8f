#include "cross_validation.hpp"

#include "chunked_gram.hpp"
#include "parallel.hpp"
#include "profiles.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Eigenvalues>

#include "stepcal/common/error.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Eigenvalues of a column-normalised Gram below this fraction of the largest are unobservable.
constexpr double kGramRankTolerance = 1e-12;

std::vector<Eigen::Index> joined(const std::vector<Eigen::Index>& a,
                                 const std::vector<Eigen::Index>& b) {
  std::vector<Eigen::Index> out = a;
  out.insert(out.end(), b.begin(), b.end());
  return out;
}

}  // namespace

double upperTailP(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

namespace {

ScreeningColumns allStored(const Eigen::MatrixXd& A) {
  ScreeningColumns columns;
  for (Eigen::Index c = 0; c < A.cols(); ++c) {
    columns.stored.emplace_back(A.col(c));
    columns.source.push_back({ColumnSource::Kind::kStored, c});
  }
  return columns;
}

}  // namespace

FoldGrams::FoldGrams(const Eigen::MatrixXd& A, const Eigen::VectorXd& r0, const FitRows& fit)
    : FoldGrams(allStored(A), r0, fit) {}

FoldGrams::FoldGrams(ScreeningColumns columns, const Eigen::VectorXd& r0, const FitRows& fit) {
  const Eigen::Index p = columns.size();
  const size_t folds = static_cast<size_t>(fit.folds);
  const Eigen::Index n = columns.link_angle.cols();
  const Eigen::Index stored = static_cast<Eigen::Index>(columns.stored.size());
  const Eigen::Index features = static_cast<Eigen::Index>(columns.features.size());
  rows_of_fold.assign(folds, {});
  for (size_t i = 0; i < fit.rows.size(); ++i) {
    rows_of_fold[static_cast<size_t>(fit.fold[i])].push_back(static_cast<int>(i));
  }
  auto by_fold = std::make_shared<Columns>();
  Columns& c = *by_fold;
  c.source = std::move(columns.source);
  c.blocks = std::move(columns.blocks);
  for (const FeatureColumn& feature : columns.features) c.feature_joint.push_back(feature.joint);
  for (const ColumnSource& s : c.source) {
    const Eigen::Index count = s.kind == ColumnSource::Kind::kStored    ? stored
                               : s.kind == ColumnSource::Kind::kFeature ? features
                                                                        : static_cast<Eigen::Index>(c.blocks.size());
    STEPCAL_INVARIANT(s.index >= 0 && s.index < count, "every screening column has its source");
  }
  const bool made = features > 0 || !c.blocks.empty();
  c.stored_by_fold.resize(folds);
  c.link_angle_by_fold.resize(folds);
  c.q_by_fold.resize(folds);
  c.feature_by_fold.resize(folds);
  c.start_by_fold.resize(folds);
  r0_fold.resize(folds);
  for (size_t f = 0; f < folds; ++f) {
    const Eigen::Index rows = static_cast<Eigen::Index>(rows_of_fold[f].size());
    Eigen::Index count = 0;
    c.start_by_fold[f].push_back(0);
    for (int i : rows_of_fold[f]) {
      count += fit.equations(static_cast<size_t>(i));
      c.start_by_fold[f].push_back(count);
    }
    c.stored_by_fold[f].resize(count, stored);
    r0_fold[f].resize(count);
    c.link_angle_by_fold[f].resize(made ? count : 0, n);
    c.q_by_fold[f].resize(c.blocks.empty() ? 0 : rows, n);
    c.feature_by_fold[f].resize(rows, features);
    for (Eigen::Index r = 0; r < rows; ++r) {
      const size_t i = static_cast<size_t>(rows_of_fold[f][static_cast<size_t>(r)]);
      for (Eigen::Index j = 0; j < c.q_by_fold[f].cols() && !c.blocks.empty(); ++j) {
        c.q_by_fold[f](r, j) = fit.rows[i]->q_rad(j);
      }
      for (Eigen::Index k = 0; k < features; ++k) {
        c.feature_by_fold[f](r, k) = columns.features[static_cast<size_t>(k)].feature(static_cast<Eigen::Index>(i));
      }
    }
  }
  columns.features.clear();
  // Column by column into the folds, each column released once sorted: it is held once.
  const auto sortInto = [&](const auto& from, size_t fold, auto&& to) {
    Eigen::Index e = 0;
    for (int i : rows_of_fold[fold]) {
      const int k = fit.equations(static_cast<size_t>(i));
      to.middleRows(e, k) = from.middleRows(fit.start[static_cast<size_t>(i)], k);
      e += k;
    }
  };
  for (Eigen::Index s = 0; s < stored; ++s) {
    Eigen::VectorXd& column = columns.stored[static_cast<size_t>(s)];
    STEPCAL_INVARIANT(column.size() == fit.count,
                      "every screening column has an entry per fit equation");
    for (size_t f = 0; f < folds; ++f) sortInto(column, f, c.stored_by_fold[f].col(s));
    column = Eigen::VectorXd();
  }
  for (size_t f = 0; f < folds; ++f) {
    sortInto(r0, f, r0_fold[f]);
    if (made) sortInto(columns.link_angle, f, c.link_angle_by_fold[f]);
  }
  columns_ = std::move(by_fold);

  G.assign(folds + 1, Eigen::MatrixXd::Zero(p, p));
  b.assign(folds + 1, Eigen::VectorXd::Zero(p));
  e0.assign(folds, 0.0);
  // Per fold, chunk by chunk of its rows: A is never made whole.
  parallelFor(folds, [&](size_t f) {
    const Eigen::VectorXd& rf = r0_fold[f];
    Eigen::MatrixXd& Gf = G[f];
    const size_t rows = rows_of_fold[f].size();
    for (size_t begin = 0; begin < rows; begin += kGramChunkRows) {
      const size_t end = std::min(rows, begin + kGramChunkRows);
      const Eigen::MatrixXd A = foldRows(f, begin, end);
      const Eigen::Index e = c.start_by_fold[f][begin];
      Gf.selfadjointView<Eigen::Lower>().rankUpdate(A.transpose());
      b[f].noalias() += A.transpose() * rf.segment(e, A.rows());
    }
    Gf.triangularView<Eigen::StrictlyUpper>() = Gf.transpose();
    e0[f] = rf.squaredNorm();
  });
  for (size_t f = 0; f < folds; ++f) {
    G[folds] += G[f];
    b[folds] += b[f];
  }
  scale = G[folds].diagonal().cwiseSqrt();
  for (Eigen::Index col = 0; col < p; ++col) {
    if (!(scale(col) > 0.0)) scale(col) = 1.0;
  }
}

Eigen::MatrixXd FoldGrams::blockColumns(size_t f, Eigen::Index b, int width, size_t begin,
                                        size_t end) const {
  const Columns& c = *columns_;
  const ProfileBlock& block = c.blocks[static_cast<size_t>(b)];
  const Eigen::MatrixXd& L = c.link_angle_by_fold[f];
  const std::vector<Eigen::Index>& start = c.start_by_fold[f];
  Eigen::MatrixXd B(start[end] - start[begin], width);
  Eigen::VectorXd features(2 * block.order);
  for (size_t r = begin; r < end; ++r) {
    profileFeatures(block.coverage, block.order,
                    c.q_by_fold[f](static_cast<Eigen::Index>(r), block.joint), features.data());
    const Eigen::Index e = start[r], k = start[r + 1] - e;
    B.middleRows(e - start[begin], k) =
        L.block(e, block.joint, k, 1) * features.head(width).transpose();
  }
  return B;
}

Eigen::MatrixXd FoldGrams::blockColumns(size_t f, Eigen::Index b, int width) const {
  return blockColumns(f, b, width, 0, rows_of_fold[f].size());
}

void FoldGrams::subtractFeatureColumn(size_t f, Eigen::Index k, double x, Eigen::VectorXd& e) const {
  const Columns& c = *columns_;
  const Eigen::MatrixXd& L = c.link_angle_by_fold[f];
  const std::vector<Eigen::Index>& start = c.start_by_fold[f];
  const int joint = c.feature_joint[static_cast<size_t>(k)];
  for (size_t r = 0; r + 1 < start.size(); ++r) {
    const double feature = c.feature_by_fold[f](static_cast<Eigen::Index>(r), k);
    for (Eigen::Index i = start[r]; i < start[r + 1]; ++i) e(i) -= x * (L(i, joint) * feature);
  }
}

Eigen::MatrixXd FoldGrams::foldRows(size_t f, size_t begin, size_t end) const {
  const Columns& c = *columns_;
  const Eigen::Index p = static_cast<Eigen::Index>(c.source.size());
  const std::vector<Eigen::Index>& start = c.start_by_fold[f];
  const Eigen::Index first = start[begin], count = start[end] - first;
  Eigen::MatrixXd A(count, p);
  for (Eigen::Index col = 0; col < p; ++col) {
    const ColumnSource& s = c.source[static_cast<size_t>(col)];
    if (s.kind == ColumnSource::Kind::kStored) {
      A.col(col) = c.stored_by_fold[f].col(s.index).segment(first, count);
    } else if (s.kind == ColumnSource::Kind::kFeature) {
      const int joint = c.feature_joint[static_cast<size_t>(s.index)];
      for (size_t r = begin; r < end; ++r) {
        const Eigen::Index e = start[r], k = start[r + 1] - e;
        A.col(col).segment(e - first, k) =
            c.link_angle_by_fold[f].block(e, joint, k, 1) *
            c.feature_by_fold[f](static_cast<Eigen::Index>(r), s.index);
      }
    }
  }
  for (size_t b = 0; b < c.blocks.size(); ++b) {
    A.middleCols(c.blocks[b].first, 2 * c.blocks[b].order) =
        blockColumns(f, static_cast<Eigen::Index>(b), 2 * c.blocks[b].order, begin, end);
  }
  return A;
}

void FoldGrams::takeOut(const Eigen::VectorXd& v) {
  const size_t folds = r0_fold.size();
  b[folds].setZero();
  for (size_t f = 0; f < folds; ++f) {
    const std::vector<Eigen::Index>& start = columns_->start_by_fold[f];
    const size_t rows = rows_of_fold[f].size();
    for (size_t begin = 0; begin < rows; begin += kGramChunkRows) {
      const size_t end = std::min(rows, begin + kGramChunkRows);
      r0_fold[f].segment(start[begin], start[end] - start[begin]).noalias() +=
          foldRows(f, begin, end) * v;
    }
    b[f] += G[f] * v;
    b[folds] += b[f];
    e0[f] = r0_fold[f].squaredNorm();
  }
}

FoldGrams FoldGrams::without(const Eigen::VectorXd& v) const {
  FoldGrams out = *this;
  out.takeOut(v);
  return out;
}

CrossValidation::CrossValidation(const FoldGrams& grams, const FitRows& fit,
                                 std::vector<Eigen::Index> stage1,
                                 std::vector<Eigen::Index> stage2, Eigen::VectorXd ridge,
                                 Eigen::VectorXd current)
    : grams_(grams), fit_(fit), stage1_(std::move(stage1)), stage2_(std::move(stage2)),
      ridge_(std::move(ridge)), current_(std::move(current)) {
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
    u_[k] = solveRidged(f, stage1_);
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

// Aᵀr0 of the training rows less the ridges' pull on the current values: the normal equations
// of the change δ when the ridge holds the value current + δ near zero.
Eigen::VectorXd CrossValidation::trainingRhs(int f, const std::vector<Eigen::Index>& a) const {
  const Eigen::VectorXd& total = grams_.b[static_cast<size_t>(fit_.folds)];
  Eigen::VectorXd rhs = total(a) - ridge_(a).cwiseProduct(current_(a));
  if (f < fit_.folds) rhs -= grams_.b[static_cast<size_t>(f)](a);
  return rhs;
}

// Least squares on column-normalised normal equations with the ridges, truncated
// eigen-decomposition (the geometry is rank deficient by construction: METHOD.md, rank 30 of 42).
Eigen::VectorXd CrossValidation::solveRidged(int f, const std::vector<Eigen::Index>& columns,
                                             Eigen::VectorXd* unit_variance) const {
  const Eigen::Index m = static_cast<Eigen::Index>(columns.size());
  Eigen::MatrixXd G = trainingGram(f, columns, columns);
  const Eigen::VectorXd b = trainingRhs(f, columns);
  // Normalised with the ridge in: a prior on a column the rows barely see (a lumped mass that
  // loads no compliant joint) would otherwise dwarf the largest eigenvalue, and the cutoff
  // relative to it would drop directions the rows determine well (thermal expansion with self
  // weight came out exactly zero).
  Eigen::VectorXd s(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    G(a, a) += ridge_(columns[static_cast<size_t>(a)]);
    s(a) = G(a, a) > 0.0 ? std::sqrt(G(a, a)) : 1.0;
  }
  const Eigen::MatrixXd Gs = s.cwiseInverse().asDiagonal() * G * s.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Gs);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double cutoff = kGramRankTolerance * lambda.maxCoeff();
  const Eigen::VectorXd bs = b.cwiseQuotient(s);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(m);
  if (unit_variance) unit_variance->setZero(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    if (lambda(i) > cutoff) {
      z += eig.eigenvectors().col(i) * (eig.eigenvectors().col(i).dot(bs) / lambda(i));
      if (unit_variance) *unit_variance += eig.eigenvectors().col(i).cwiseAbs2() / lambda(i);
    }
  }
  if (unit_variance) *unit_variance = unit_variance->cwiseQuotient(s.cwiseAbs2());
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
    const Eigen::VectorXd u = solveRidged(f, stage1);
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

CrossValidation::JointFit CrossValidation::jointFit(const std::vector<Eigen::Index>& columns) const {
  JointFit out;
  out.change = solveRidged(fit_.folds, columns, &out.unit_variance);
  const size_t all = static_cast<size_t>(fit_.folds);
  double e0 = 0.0;
  for (double e : grams_.e0) e0 += e;
  const double sse = e0 - 2.0 * out.change.dot(grams_.b[all](columns)) +
                     out.change.dot(grams_.G[all](columns, columns) * out.change);
  out.variance = std::max(0.0, sse) / std::max<double>(1.0, double(fit_.count - columns.size()));
  return out;
}

CrossValidation::Outcome CrossValidation::heldOut(const Correction& correction) const {
  Outcome out;
  out.pose_sse.assign(static_cast<size_t>(fit_.poses), 0.0);
  out.position_m.assign(fit_.rows.size(), 0.0);
  for (int f = 0; f < fit_.folds; ++f) {
    const size_t k = static_cast<size_t>(f);
    // The fold's residual over just the correction's columns (column by column: A streams once).
    Eigen::VectorXd e = grams_.r0_fold[k];
    const Eigen::VectorXd& x = correction.x[k];
    // A profile block's columns are made once per run of them, as many as the correction uses.
    Eigen::MatrixXd block;
    Eigen::Index made = -1;
    for (size_t a = 0; a < correction.columns.size(); ++a) {
      const ColumnSource& source = grams_.source(correction.columns[a]);
      if (source.kind == ColumnSource::Kind::kStored) {
        e.noalias() -= x(static_cast<Eigen::Index>(a)) * grams_.storedColumn(k, source.index);
        continue;
      }
      if (source.kind == ColumnSource::Kind::kFeature) {
        grams_.subtractFeatureColumn(k, source.index, x(static_cast<Eigen::Index>(a)), e);
        continue;
      }
      const Eigen::Index first = grams_.block(source.index).first;
      const Eigen::Index offset = correction.columns[a] - first;
      if (source.index != made || offset >= block.cols()) {
        Eigen::Index width = offset + 1;
        for (size_t later = a + 1; later < correction.columns.size(); ++later) {
          const ColumnSource& other = grams_.source(correction.columns[later]);
          if (other.kind == ColumnSource::Kind::kProfile && other.index == source.index) {
            width = std::max(width, correction.columns[later] - first + 1);
          }
        }
        block = grams_.blockColumns(k, source.index, static_cast<int>(width));
        made = source.index;
      }
      e.noalias() -= x(static_cast<Eigen::Index>(a)) * block.col(offset);
    }
    Eigen::Index at = 0;
    for (int i : grams_.rows_of_fold[k]) {
      const int equations = fit_.equations(static_cast<size_t>(i));
      out.pose_sse[static_cast<size_t>(fit_.pose[static_cast<size_t>(i)])] +=
          e.segment(at, equations).squaredNorm();
      out.position_m[static_cast<size_t>(i)] = e.segment<3>(at).norm() / fit_.w_p;
      at += equations;
    }
  }
  return out;
}

Comparison compare(const CrossValidation::Outcome& base, const CrossValidation::Outcome& with) {
  Comparison c;
  double reduction = 0.0, total = 0.0;
  for (size_t i = 0; i < base.pose_sse.size(); ++i) {
    reduction += base.pose_sse[i] - with.pose_sse[i];
    total += base.pose_sse[i];
  }
  c.relative_reduction = total > 0.0 ? reduction / total : 0.0;
  c.z = signedRankZ(base.pose_sse, with.pose_sse);
  c.p = upperTailP(c.z);
  double gain = 0.0;
  for (size_t i = 0; i < base.position_m.size(); ++i) gain += base.position_m[i] - with.position_m[i];
  c.gain_mm = 1e3 * gain / static_cast<double>(base.position_m.size());
  return c;
}

double signedRankZ(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> d;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i] != b[i]) d.push_back(a[i] - b[i]);
  }
  const size_t n = d.size();
  if (n == 0) return 0.0;
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](size_t x, size_t y) { return std::abs(d[x]) < std::abs(d[y]); });
  // Ranks of |d|, ties sharing their mean rank; W⁺ the sum over positive differences.
  double w_plus = 0.0, tie_term = 0.0;
  for (size_t i = 0; i < n;) {
    size_t j = i;
    while (j + 1 < n && std::abs(d[order[j + 1]]) == std::abs(d[order[i]])) ++j;
    const double rank = 0.5 * static_cast<double>(i + j) + 1.0, t = static_cast<double>(j - i + 1);
    tie_term += t * t * t - t;
    for (size_t k = i; k <= j; ++k) {
      if (d[order[k]] > 0.0) w_plus += rank;
    }
    i = j + 1;
  }
  const double m = static_cast<double>(n);
  const double mean = m * (m + 1.0) / 4.0;
  const double variance = m * (m + 1.0) * (2.0 * m + 1.0) / 24.0 - tie_term / 48.0;
  return variance > 0.0 ? (w_plus - mean) / std::sqrt(variance) : 0.0;
}

}  // namespace stepcal::trainer::diagnosis
