#include "cross_validation.hpp"

#include "../least_squares.hpp"
#include "chunked_gram.hpp"
#include "parallel.hpp"
#include "profiles.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Eigenvalues>

#include "stepcal/common/error.hpp"
#include "stepcal/common/units.hpp"

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

Eigen::Index ColumnLayout::compactSize() const {
  Eigen::Index size = dense;
  for (Eigen::Index s : scaled) size += s;
  return size;
}

Eigen::Index ColumnLayout::compactIndex(Eigen::Index c) const {
  const Place& at = place[static_cast<size_t>(c)];
  if (at.joint < 0) return at.index;
  Eigen::Index offset = dense;
  for (int j = 0; j < at.joint; ++j) offset += scaled[static_cast<size_t>(j)];
  return offset + at.index;
}

namespace {

// Chunks of fit rows whose held-out errors are made on the cores at once before they are summed
// per pose in row order.
constexpr size_t kHeldOutChunks = 8;
// The per-pose errors heldOut holds for a batch of corrections (heldOutBatch), bytes.
constexpr double kHeldOutBudgetBytes = 512e6;

// A chunk's rows of one fold, gathered: their equations of the dense and link-angle columns and
// of r0, their rows of each joint's scaled columns.
struct FoldPart {
  std::vector<size_t> rows;         // in the chunk
  std::vector<Eigen::Index> start;  // per row its first equation in the part, then the count
  Eigen::MatrixXd dense, link_angle;
  std::vector<Eigen::MatrixXd> scaled;
  Eigen::VectorXd r0;
};

// The chunk of fit rows [begin, end) split by fold.
std::vector<FoldPart> foldParts(const ColumnChunk& chunk, const Eigen::VectorXd& r0,
                                const FitRows& fit, size_t begin, size_t end) {
  std::vector<FoldPart> parts(static_cast<size_t>(fit.folds));
  for (size_t i = begin; i < end; ++i) {
    FoldPart& part = parts[static_cast<size_t>(fit.fold[i])];
    if (part.start.empty()) part.start.push_back(0);
    part.rows.push_back(i - begin);
    part.start.push_back(part.start.back() + fit.equations(i));
  }
  const Eigen::Index first = equationOf(fit, begin);
  const size_t n = chunk.scaled.size();
  for (FoldPart& part : parts) {
    if (part.rows.empty()) continue;
    const Eigen::Index count = part.start.back(), m = static_cast<Eigen::Index>(part.rows.size());
    part.dense.resize(count, chunk.dense.cols());
    part.link_angle.resize(count, chunk.link_angle.cols());
    part.r0.resize(count);
    part.scaled.resize(n);
    for (size_t j = 0; j < n; ++j) part.scaled[j].resize(m, chunk.scaled[j].cols());
    for (Eigen::Index r = 0; r < m; ++r) {
      const size_t local = part.rows[static_cast<size_t>(r)];
      const Eigen::Index from = fit.start[begin + local] - first, e = part.start[static_cast<size_t>(r)];
      const Eigen::Index k = part.start[static_cast<size_t>(r) + 1] - e;
      part.dense.middleRows(e, k) = chunk.dense.middleRows(from, k);
      part.link_angle.middleRows(e, k) = chunk.link_angle.middleRows(from, k);
      part.r0.segment(e, k) = r0.segment(fit.start[begin + local], k);
      for (size_t j = 0; j < n; ++j) {
        part.scaled[j].row(r) = chunk.scaled[j].row(static_cast<Eigen::Index>(local));
      }
    }
  }
  return parts;
}

// First compact column of each joint's scaled columns.
std::vector<Eigen::Index> scaledOffsets(const ColumnLayout& layout) {
  std::vector<Eigen::Index> offset;
  Eigen::Index at = layout.dense;
  for (Eigen::Index s : layout.scaled) {
    offset.push_back(at);
    at += s;
  }
  return offset;
}

// Adds a fold part's AᵀA (lower triangle) and Aᵀr0 in compact columns. A scaled column (j, φ)
// meets a dense one d in Σ_rows φ (L_rowᵀ D_row)_jd and a scaled (k, ψ) in Σ_rows φ ψ
// (L_rowᵀ L_row)_jk: n × n products per row instead of the equations' products of every pair.
void addGram(const FoldPart& part, const ColumnLayout& layout, Eigen::MatrixXd& G,
             Eigen::VectorXd& b) {
  const Eigen::Index D = layout.dense;
  G.topLeftCorner(D, D).selfadjointView<Eigen::Lower>().rankUpdate(part.dense.transpose());
  b.head(D).noalias() += part.dense.transpose() * part.r0;
  const Eigen::Index n = static_cast<Eigen::Index>(layout.scaled.size());
  if (n == 0) return;
  const Eigen::Index m = static_cast<Eigen::Index>(part.rows.size());
  std::vector<Eigen::MatrixXd> LtD(static_cast<size_t>(n), Eigen::MatrixXd(m, D));
  Eigen::MatrixXd LtL(m, n * n), Ltr(m, n);
  for (Eigen::Index r = 0; r < m; ++r) {
    const Eigen::Index e = part.start[static_cast<size_t>(r)];
    const Eigen::Index k = part.start[static_cast<size_t>(r) + 1] - e;
    const auto L = part.link_angle.middleRows(e, k);
    const Eigen::MatrixXd products = L.transpose() * part.dense.middleRows(e, k);
    for (Eigen::Index j = 0; j < n; ++j) LtD[static_cast<size_t>(j)].row(r) = products.row(j);
    const Eigen::MatrixXd gram = L.transpose() * L;
    LtL.row(r) = Eigen::Map<const Eigen::RowVectorXd>(gram.data(), n * n);
    Ltr.row(r) = (L.transpose() * part.r0.segment(e, k)).transpose();
  }
  const std::vector<Eigen::Index> offset = scaledOffsets(layout);
  for (Eigen::Index j = 0; j < n; ++j) {
    const Eigen::MatrixXd& Phi = part.scaled[static_cast<size_t>(j)];
    const Eigen::Index sj = Phi.cols(), oj = offset[static_cast<size_t>(j)];
    if (sj == 0) continue;
    G.block(oj, 0, sj, D).noalias() += Phi.transpose() * LtD[static_cast<size_t>(j)];
    b.segment(oj, sj).noalias() += Phi.transpose() * Ltr.col(j);
    for (Eigen::Index k = 0; k < j; ++k) {
      const Eigen::MatrixXd& Psi = part.scaled[static_cast<size_t>(k)];
      if (Psi.cols() == 0) continue;
      G.block(oj, offset[static_cast<size_t>(k)], sj, Psi.cols()).noalias() +=
          Phi.transpose() * (LtL.col(k * n + j).asDiagonal() * Psi);
    }
    // The joint's own block: ‖L_j‖² ≥ 0 per row, so a rank update of the rows scaled by ‖L_j‖.
    const Eigen::MatrixXd weighted = LtL.col(j * n + j).cwiseSqrt().asDiagonal() * Phi;
    G.block(oj, oj, sj, sj).selfadjointView<Eigen::Lower>().rankUpdate(weighted.transpose());
  }
}

// A fold part's A·V (its equations × V's columns), V in compact columns.
Eigen::MatrixXd times(const FoldPart& part, const ColumnLayout& layout, const Eigen::MatrixXd& V) {
  const Eigen::Index D = layout.dense;
  Eigen::MatrixXd out = part.dense * V.topRows(D);
  const Eigen::Index n = static_cast<Eigen::Index>(layout.scaled.size());
  if (n == 0) return out;
  const Eigen::Index m = static_cast<Eigen::Index>(part.rows.size());
  const std::vector<Eigen::Index> offset = scaledOffsets(layout);
  // Per joint, its scaled columns times V: a row's link-angle offsets per column of V.
  std::vector<Eigen::MatrixXd> Y(static_cast<size_t>(n));
  for (Eigen::Index j = 0; j < n; ++j) {
    const Eigen::MatrixXd& Phi = part.scaled[static_cast<size_t>(j)];
    if (Phi.cols() == 0) {
      Y[static_cast<size_t>(j)].setZero(m, V.cols());
    } else {
      Y[static_cast<size_t>(j)].noalias() = Phi * V.middleRows(offset[static_cast<size_t>(j)], Phi.cols());
    }
  }
  Eigen::MatrixXd y(n, V.cols());
  for (Eigen::Index r = 0; r < m; ++r) {
    const Eigen::Index e = part.start[static_cast<size_t>(r)];
    const Eigen::Index k = part.start[static_cast<size_t>(r) + 1] - e;
    for (Eigen::Index j = 0; j < n; ++j) y.row(j) = Y[static_cast<size_t>(j)].row(r);
    out.middleRows(e, k).noalias() += part.link_angle.middleRows(e, k) * y;
  }
  return out;
}

// Column values v of A in compact columns (shared places summed).
Eigen::MatrixXd compactValues(const ColumnLayout& layout, const std::vector<Eigen::Index>& columns,
                              const Eigen::VectorXd& v) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(layout.compactSize(), 1);
  for (size_t a = 0; a < columns.size(); ++a) {
    out(layout.compactIndex(columns[a]), 0) += v(static_cast<Eigen::Index>(a));
  }
  return out;
}

}  // namespace

size_t heldOutBatch(const FitRows& fit) {
  const double per_outcome = 8.0 * std::max(1, fit.poses);
  return std::max<size_t>(kMinHeldOutBatch, static_cast<size_t>(kHeldOutBudgetBytes / per_outcome));
}

FoldGrams::FoldGrams(ScreeningColumns columns, Eigen::VectorXd r0, const FitRows& fit)
    : columns_(std::make_shared<const ScreeningColumns>(std::move(columns))),
      r0_(std::make_shared<const Eigen::VectorXd>(std::move(r0))),
      fit_(&fit) {
  const ColumnLayout& layout = columns_->layout;
  STEPCAL_INVARIANT(r0_->size() == fit.count, "r0 has an entry per fit equation");
  for (const ColumnLayout::Place& at : layout.place) {
    const bool placed = at.joint < 0 ? at.index < layout.dense
                                     : at.joint < static_cast<int>(layout.scaled.size()) &&
                                           at.index < layout.scaled[static_cast<size_t>(at.joint)];
    STEPCAL_INVARIANT(at.index >= 0 && placed, "every screening column has its place");
  }
  const size_t folds = static_cast<size_t>(fit.folds);
  const Eigen::Index q = layout.compactSize(), p = layout.size();
  // Per slice and fold, in compact columns; the slices summed in order.
  std::vector<std::vector<Eigen::MatrixXd>> Gc(kGramSlices, std::vector<Eigen::MatrixXd>(folds, Eigen::MatrixXd::Zero(q, q)));
  std::vector<std::vector<Eigen::VectorXd>> bc(kGramSlices, std::vector<Eigen::VectorXd>(folds, Eigen::VectorXd::Zero(q)));
  std::vector<std::vector<double>> e0c(kGramSlices, std::vector<double>(folds, 0.0));
  forEachChunk([&](size_t slice, size_t begin, size_t end, const ColumnChunk& chunk) {
    const std::vector<FoldPart> parts = foldParts(chunk, *r0_, fit, begin, end);
    for (size_t f = 0; f < folds; ++f) {
      if (parts[f].rows.empty()) continue;
      addGram(parts[f], layout, Gc[slice][f], bc[slice][f]);
      e0c[slice][f] += parts[f].r0.squaredNorm();
    }
  });
  std::vector<Eigen::Index> compact(static_cast<size_t>(p));
  for (Eigen::Index c = 0; c < p; ++c) compact[static_cast<size_t>(c)] = layout.compactIndex(c);
  G.assign(folds + 1, Eigen::MatrixXd::Zero(p, p));
  b.assign(folds + 1, Eigen::VectorXd::Zero(p));
  e0.assign(folds, 0.0);
  for (size_t f = 0; f < folds; ++f) {
    Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(q, q);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(q);
    for (size_t s = 0; s < kGramSlices; ++s) {
      sum += Gc[s][f];
      rhs += bc[s][f];
      e0[f] += e0c[s][f];
      Gc[s][f] = Eigen::MatrixXd();
    }
    sum.triangularView<Eigen::StrictlyUpper>() = sum.transpose();
    G[f] = sum(compact, compact);
    b[f] = rhs(compact);
    G[folds] += G[f];
    b[folds] += b[f];
  }
  scale = G[folds].diagonal().cwiseSqrt();
  for (Eigen::Index col = 0; col < p; ++col) {
    if (!(scale(col) > 0.0)) scale(col) = 1.0;
  }
  taken_out = Eigen::VectorXd::Zero(p);
}

void FoldGrams::forEachChunk(
    const std::function<void(size_t slice, size_t begin, size_t end, const ColumnChunk& chunk)>& body)
    const {
  const std::vector<bool> every(static_cast<size_t>(columns_->layout.dense), true);
  diagnosis::forEachChunk(*fit_, [&](size_t slice, size_t begin, size_t end) {
    ColumnChunk chunk;
    columns_->make(begin, end, every, chunk);
    body(slice, begin, end, chunk);
  });
}

void FoldGrams::takeOut(const Eigen::VectorXd& v) {
  const size_t folds = e0.size();
  // Per fold, |r + A_f v|² = |r|² + 2 vᵀ A_fᵀ r + vᵀ G_f v and A_fᵀ (r + A_f v) = b_f + G_f v.
  b[folds].setZero();
  for (size_t f = 0; f < folds; ++f) {
    const Eigen::VectorXd Gv = G[f] * v;
    e0[f] += 2.0 * v.dot(b[f]) + v.dot(Gv);
    b[f] += Gv;
    b[folds] += b[f];
  }
  taken_out += v;
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
// eigen-decomposition (the geometry is rank deficient by construction: docs/method.md, rank 30 of 42).
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

// solveRidged under C x_last ≥ d on the last C.cols() of the columns: the same normalised,
// ridged Gram and cut (with no bound held the constrained solve is solveRidged's).
Eigen::VectorXd CrossValidation::solveRidgedBounded(int f, const std::vector<Eigen::Index>& columns,
                                                    const Eigen::MatrixXd& C,
                                                    const Eigen::VectorXd& d) const {
  const Eigen::Index m = static_cast<Eigen::Index>(columns.size());
  Eigen::MatrixXd G = trainingGram(f, columns, columns);
  const Eigen::VectorXd b = trainingRhs(f, columns);
  Eigen::VectorXd s(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    G(a, a) += ridge_(columns[static_cast<size_t>(a)]);
    s(a) = G(a, a) > 0.0 ? std::sqrt(G(a, a)) : 1.0;
  }
  const Eigen::MatrixXd Gs = s.cwiseInverse().asDiagonal() * G * s.cwiseInverse().asDiagonal();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(C.rows(), m);
  A.rightCols(C.cols()) = C * s.tail(C.cols()).cwiseInverse().asDiagonal();
  return solveConstrainedGram(Gs, b.cwiseQuotient(s), kGramRankTolerance, A, d).cwiseQuotient(s);
}

CrossValidation::Correction CrossValidation::withGlobal(
    const std::vector<Eigen::Index>& columns) const {
  return globalCorrection(columns, nullptr, nullptr);
}

CrossValidation::Correction CrossValidation::withGlobal(const std::vector<Eigen::Index>& columns,
                                                        const Eigen::MatrixXd& C,
                                                        const Eigen::VectorXd& d) const {
  return globalCorrection(columns, &C, &d);
}

CrossValidation::Correction CrossValidation::globalCorrection(
    const std::vector<Eigen::Index>& columns, const Eigen::MatrixXd* C,
    const Eigen::VectorXd* d) const {
  Correction out;
  const std::vector<Eigen::Index> stage1 = joined(stage1_, columns);
  out.columns = joined(stage1, stage2_);
  out.x.resize(static_cast<size_t>(fit_.folds) + 1);
  for (int f = 0; f <= fit_.folds; ++f) {
    const size_t k = static_cast<size_t>(f);
    const Eigen::VectorXd u = C ? solveRidgedBounded(f, stage1, *C, *d) : solveRidged(f, stage1);
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

double CrossValidation::Outcome::total() const {
  double sum = 0.0;
  for (double e : pose_sse) sum += e;
  return sum;
}

std::vector<CrossValidation::Outcome> CrossValidation::heldOut(
    const std::vector<const Correction*>& corrections) const {
  const ColumnLayout& layout = grams_.layout();
  const size_t K = corrections.size(), folds = static_cast<size_t>(fit_.folds);
  const Eigen::Index k_columns = static_cast<Eigen::Index>(K);
  // Per fold, every correction's values fitted without it less those taken out of the model
  // (its residual is r0 + A·taken_out), in a chunk's compact columns.
  std::vector<Eigen::Index> all(static_cast<size_t>(layout.size()));
  for (size_t c = 0; c < all.size(); ++c) all[c] = static_cast<Eigen::Index>(c);
  const Eigen::VectorXd taken = compactValues(layout, all, grams_.taken_out).col(0);
  std::vector<Eigen::MatrixXd> X(folds, Eigen::MatrixXd::Zero(layout.compactSize(), k_columns));
  for (size_t k = 0; k < K; ++k) {
    for (size_t f = 0; f < folds; ++f) {
      X[f].col(static_cast<Eigen::Index>(k)) =
          compactValues(layout, corrections[k]->columns, corrections[k]->x[f]).col(0) - taken;
    }
  }
  // The dense columns any correction or the part taken out uses.
  std::vector<bool> used(static_cast<size_t>(layout.dense), false);
  for (Eigen::Index d = 0; d < layout.dense; ++d) {
    for (size_t f = 0; f < folds && !used[static_cast<size_t>(d)]; ++f) {
      used[static_cast<size_t>(d)] = !X[f].row(d).isZero(0.0);
    }
  }
  std::vector<Outcome> out(K);
  for (Outcome& o : out) {
    o.pose_sse.assign(static_cast<size_t>(fit_.poses), 0.0);
    o.rows = fit_.rows.size();
  }
  // Chunks made on the cores a few at a time; each row's errors then summed per pose in row order.
  const size_t rows = fit_.rows.size(), span = kHeldOutChunks * kGramChunkRows;
  Eigen::MatrixXd row_sse(static_cast<Eigen::Index>(span), k_columns);
  Eigen::MatrixXd row_position(static_cast<Eigen::Index>(span), k_columns);
  for (size_t first = 0; first < rows; first += span) {
    const size_t last = std::min(rows, first + span);
    const size_t chunks = (last - first + kGramChunkRows - 1) / kGramChunkRows;
    parallelFor(chunks, [&](size_t c) {
      const size_t begin = first + c * kGramChunkRows, end = std::min(last, begin + kGramChunkRows);
      ColumnChunk chunk;
      grams_.make(begin, end, used, chunk);
      const std::vector<FoldPart> parts = foldParts(chunk, grams_.r0(), fit_, begin, end);
      for (size_t f = 0; f < folds; ++f) {
        const FoldPart& part = parts[f];
        if (part.rows.empty()) continue;
        const Eigen::MatrixXd e =
            part.r0.replicate(1, k_columns) - times(part, layout, X[f]);
        for (size_t r = 0; r < part.rows.size(); ++r) {
          const Eigen::Index at = part.start[r], k = part.start[r + 1] - at;
          const Eigen::Index row = static_cast<Eigen::Index>(begin + part.rows[r] - first);
          row_sse.row(row) = e.middleRows(at, k).colwise().squaredNorm();
          row_position.row(row) = e.middleRows(at, 3).colwise().norm() / fit_.w_p;
        }
      }
    });
    for (size_t i = first; i < last; ++i) {
      const size_t pose = static_cast<size_t>(fit_.pose[i]);
      const Eigen::Index row = static_cast<Eigen::Index>(i - first);
      for (size_t k = 0; k < K; ++k) {
        out[k].pose_sse[pose] += row_sse(row, static_cast<Eigen::Index>(k));
        out[k].position_sum_m += row_position(row, static_cast<Eigen::Index>(k));
      }
    }
  }
  return out;
}

void CrossValidation::heldOutInGroups(
    const std::vector<std::vector<const Correction*>>& groups, size_t batch,
    const std::function<void(size_t first, std::vector<std::vector<Outcome>> outcomes)>& done) const {
  for (size_t first = 0; first < groups.size();) {
    std::vector<const Correction*> corrections;
    size_t last = first;
    while (last < groups.size() &&
           (last == first || corrections.size() + groups[last].size() <= batch)) {
      corrections.insert(corrections.end(), groups[last].begin(), groups[last].end());
      ++last;
    }
    std::vector<Outcome> outcomes = corrections.empty() ? std::vector<Outcome>() : heldOut(corrections);
    std::vector<std::vector<Outcome>> by_group;
    auto at = outcomes.begin();
    for (size_t g = first; g < last; ++g) {
      const auto end = at + static_cast<long>(groups[g].size());
      by_group.emplace_back(std::make_move_iterator(at), std::make_move_iterator(end));
      at = end;
    }
    done(first, std::move(by_group));
    first = last;
  }
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
  c.gain_mm = kMmPerM * (base.position_sum_m - with.position_sum_m) /
              static_cast<double>(std::max<size_t>(1, base.rows));
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
