// Pairs of families the rows may not tell apart (family_pairs.hpp).
#include "family_pairs.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace stepcal::trainer::diagnosis {
namespace {

// The other families a chosen one is tried against, those that removed most: one pass over the
// fit rows holds two corrections per pair.
constexpr size_t kMostPairs = 8;
// Eigenvalues of a scaled Gram below this fraction of its largest are directions the rows do
// not determine (left out of its pseudo-inverse).
constexpr double kRankTolerance = 1e-10;

// (S)^(-1/2) of a symmetric positive semi-definite S, its undetermined directions left out (power
// −1: the pseudo-inverse).
Eigen::MatrixXd inversePower(const Eigen::MatrixXd& S, double power) {
  if (S.rows() == 0) return S;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(S);
  const Eigen::VectorXd& values = eig.eigenvalues();
  const double floor = kRankTolerance * std::max(values.maxCoeff(), 0.0);
  Eigen::VectorXd inverse = Eigen::VectorXd::Zero(values.size());
  for (Eigen::Index k = 0; k < values.size(); ++k) {
    if (values(k) > floor && values(k) > 0.0) inverse(k) = std::pow(values(k), power);
  }
  return eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
}

std::vector<Eigen::Index> without(std::vector<Eigen::Index> columns,
                                  const std::vector<Eigen::Index>& shared) {
  columns.erase(std::remove_if(columns.begin(), columns.end(),
                               [&](Eigen::Index c) {
                                 return std::find(shared.begin(), shared.end(), c) != shared.end();
                               }),
                columns.end());
  return columns;
}

FamilyPairTest::Beside besideOf(const Comparison& c,
                                const std::function<bool(double, double)>& passes) {
  return {c.gain_mm, c.relative_reduction, c.z, c.p, passes(c.p, c.relative_reduction)};
}

}  // namespace

double canonicalCorrelation(const FoldGrams& grams, std::vector<Eigen::Index> model,
                            std::vector<Eigen::Index> a, std::vector<Eigen::Index> b) {
  std::vector<Eigen::Index> shared;
  for (Eigen::Index c : a) {
    if (std::find(b.begin(), b.end(), c) != b.end()) shared.push_back(c);
  }
  model.insert(model.end(), shared.begin(), shared.end());
  a = without(std::move(a), shared);
  b = without(std::move(b), shared);
  if (a.empty() || b.empty()) return 1.0;  // one of them is the other's parameters
  std::vector<Eigen::Index> all = model;
  all.insert(all.end(), a.begin(), a.end());
  all.insert(all.end(), b.begin(), b.end());
  // The Gram scaled to unit diagonal (columns of any unit), then the model's columns taken out:
  // the Gram of what a and b do that the model cannot.
  const Eigen::VectorXd s = grams.scale(all);
  const Eigen::MatrixXd G = s.cwiseInverse().asDiagonal() *
                            grams.G.back()(all, all) * s.cwiseInverse().asDiagonal();
  const Eigen::Index m = static_cast<Eigen::Index>(model.size());
  const Eigen::Index rest = G.rows() - m;
  Eigen::MatrixXd C = G.bottomRightCorner(rest, rest);
  if (m > 0) {
    C -= G.bottomLeftCorner(rest, m) * inversePower(G.topLeftCorner(m, m), -1.0) *
         G.topRightCorner(m, rest);
  }
  const Eigen::Index na = static_cast<Eigen::Index>(a.size());
  const Eigen::Index nb = rest - na;
  const Eigen::MatrixXd Wa = inversePower(C.topLeftCorner(na, na), -0.5);
  const Eigen::MatrixXd Wb = inversePower(C.bottomRightCorner(nb, nb), -0.5);
  const Eigen::MatrixXd K = Wa * C.topRightCorner(na, nb) * Wb;
  if (K.size() == 0) return 0.0;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(K);
  return std::clamp(svd.singularValues()(0), 0.0, 1.0);
}

void testFamilyPairs(const std::vector<Scored>& scored, size_t chosen,
                     const std::vector<size_t>& significant, const CrossValidation& cv,
                     const FoldGrams& grams, const Screening& screening,
                     const std::function<bool(double p, double reduction)>& passes, int round,
                     std::vector<FamilyPairTest>& pairs) {
  const Family& first = *scored[chosen].family;
  if (first.stage != Stage::kGlobal || first.columns.empty()) return;
  std::vector<size_t> others;
  for (size_t k : significant) {
    const Family& f = *scored[k].family;
    if (k != chosen && f.stage == Stage::kGlobal && !f.columns.empty()) others.push_back(k);
  }
  std::stable_sort(others.begin(), others.end(), [&](size_t x, size_t y) {
    return scored[x].score.relative_reduction > scored[y].score.relative_reduction;
  });
  // One configuration per candidate, its best (a degree of a drift or a τ₀ of a curve is no other
  // cause), and none of the chosen candidate's own.
  std::vector<size_t> distinct;
  for (size_t k : others) {
    const Mechanism& m = scored[k].score.mechanism;
    const auto same = [&](size_t o) { return sameCandidate(scored[o].score.mechanism, m); };
    if (!same(chosen) && std::none_of(distinct.begin(), distinct.end(), same)) distinct.push_back(k);
  }
  others = std::move(distinct);
  if (others.size() > kMostPairs) others.resize(kMostPairs);
  if (others.empty()) return;
  std::vector<Eigen::Index> model = screening.stage1;
  model.insert(model.end(), screening.stage2.begin(), screening.stage2.end());
  // Per pair: the model with the chosen, with the other, and with both.
  const CrossValidation::Correction with_chosen = cv.withGlobal(first.columns);
  std::vector<CrossValidation::Correction> with_other, with_both;
  for (size_t k : others) {
    const Family& other = *scored[k].family;
    with_other.push_back(cv.withGlobal(other.columns));
    std::vector<Eigen::Index> both = other.columns;
    for (Eigen::Index c : first.columns) {
      if (std::find(both.begin(), both.end(), c) == both.end()) both.push_back(c);
    }
    with_both.push_back(cv.withGlobal(both));
  }
  std::vector<const CrossValidation::Correction*> corrections{&with_chosen};
  for (size_t i = 0; i < others.size(); ++i) {
    corrections.push_back(&with_other[i]);
    corrections.push_back(&with_both[i]);
  }
  const std::vector<CrossValidation::Outcome> outcomes = cv.heldOut(corrections);
  for (size_t i = 0; i < others.size(); ++i) {
    const Scored& other = scored[others[i]];
    FamilyPairTest t;
    t.chosen = scored[chosen].score.mechanism;
    t.other = other.score.mechanism;
    t.round = round;
    t.canonical_correlation = canonicalCorrelation(grams, model, first.columns, other.family->columns);
    const double unexplained = 1.0 - t.canonical_correlation * t.canonical_correlation;
    t.variance_inflation =
        unexplained > 0.0 ? 1.0 / unexplained : std::numeric_limits<double>::infinity();
    const CrossValidation::Outcome& other_alone = outcomes[1 + 2 * i];
    const CrossValidation::Outcome& both = outcomes[2 + 2 * i];
    t.chosen_beside_other = besideOf(compare(other_alone, both), passes);
    t.other_beside_chosen = besideOf(compare(outcomes[0], both), passes);
    t.told_apart = t.chosen_beside_other.significant || t.other_beside_chosen.significant;
    pairs.push_back(std::move(t));
  }
}

}  // namespace stepcal::trainer::diagnosis
