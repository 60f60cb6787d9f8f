// Scoring a round's families on held-out poses, and choosing among the significant ones
// (scoring.hpp).
#include "scoring.hpp"

#include <algorithm>
#include <numeric>

#include "profiles.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Candidate parameters from the coefficients fitted on every row (index folds of x).
void storeCoefficients(const Family& family, const CrossValidation::Correction& c, size_t offset,
                       Mechanism& m) {
  const Eigen::VectorXd& x = c.x.back();
  for (size_t k = 0; k < family.free.size(); ++k) {
    m.parameters[static_cast<size_t>(family.free[k])] = x(static_cast<Eigen::Index>(offset + k));
  }
}

}  // namespace

Scored scoreGlobal(const Family& family, const CrossValidation& cv,
                   const CrossValidation::Outcome& base, size_t stage1_size) {
  Scored s;
  s.family = &family;
  const CrossValidation::Correction c = cv.withGlobal(family.columns);
  s.outcome = cv.heldOut(c);
  s.score.mechanism = family.mechanism;
  storeCoefficients(family, c, stage1_size, s.score.mechanism);
  const Comparison cmp = compare(base, s.outcome);
  s.score.cv_gain_mm = cmp.gain_mm;
  s.score.relative_reduction = cmp.relative_reduction;
  s.score.z_statistic = cmp.z;
  s.score.p_value = cmp.p;
  s.score.physical = !family.negative_compliance;
  for (int i : signConstrained(s.score.mechanism)) {
    s.score.physical = s.score.physical && s.score.mechanism.parameters[static_cast<size_t>(i)] >= 0.0;
  }
  s.spent = static_cast<int>(family.free.size() + family.compliance.size()) + family.chosen;
  return s;
}

// Drops from a family the joints whose compliance it would make negative (fitted on every row):
// a joint that deflects against its load under the arm's weight is not deflecting under it.
void pruneNegativeCompliance(Family& family, const CrossValidation& cv, size_t stage1_size,
                             const DiagnosisModel& model) {
  if (family.compliance.empty()) return;
  const CrossValidation::Correction c = cv.withGlobal(family.columns);
  const Eigen::VectorXd& x = c.x.back();
  Family kept = family;
  kept.compliance.clear();
  kept.columns.resize(family.free.size());
  for (size_t k = 0; k < family.compliance.size(); ++k) {
    const int j = family.compliance[k];
    const size_t at = family.free.size() + k;
    if (model.global.compliance_rad_per_nm(j) + x(static_cast<Eigen::Index>(stage1_size + at)) >= 0.0) {
      kept.compliance.push_back(j);
      kept.columns.push_back(family.columns[at]);
    }
  }
  if (kept.compliance.empty()) {
    family.negative_compliance = true;
  } else if (kept.compliance.size() < family.compliance.size()) {
    family = std::move(kept);
  }
}

// A profile family over the grid of orders and ridges, the simplest configuration the held-out
// poses do not show to be worse than the best: the best ridge per order by held-out squared
// error; the lowest order whose best is not significantly worse than the best order's (signed-rank
// z < 2 on the per-pose errors); at that order, the largest ridge not significantly worse than
// its best. The cross-validated error is flat near its minimum, so the minimum itself moves with
// small changes of the data; the simplest configuration on the flat part does not.
Scored scoreProfile(const Family& family, const CrossValidation& cv,
                    const CrossValidation::Outcome& base, const FoldGrams& grams,
                    const DiagnoseOptions& options, const FitRows& fit) {
  const CrossValidation::ProfileCandidate prepared = cv.prepareProfile(family.columns);
  double mean_diag = 0.0;
  for (Eigen::Index c : family.columns) mean_diag += grams.scale(c) * grams.scale(c);
  mean_diag /= static_cast<double>(family.columns.size());
  std::vector<int> orders = options.profile_orders;
  std::sort(orders.begin(), orders.end());
  std::vector<double> ridges = options.profile_ridges;
  std::sort(ridges.begin(), ridges.end());
  struct Configuration {
    int order = 0;
    double rho = 0.0;
    CrossValidation::Correction correction;
  };
  // Per order, every ridge's correction (ascending ridge) and the index of the best.
  std::vector<std::vector<Configuration>> grid;
  std::vector<size_t> best_ridge;
  for (int order : orders) {
    if (2 * order > static_cast<int>(family.columns.size())) continue;
    std::vector<Configuration> row;
    for (double rho : ridges) {
      row.push_back({order, rho, cv.withProfile(prepared, 2 * order, rho * mean_diag)});
    }
    size_t best = 0;
    for (size_t i = 1; i < row.size(); ++i) {
      if (row[i].correction.sse < row[best].correction.sse) best = i;
    }
    grid.push_back(std::move(row));
    best_ridge.push_back(best);
  }
  auto bestOf = [&](size_t o) -> const Configuration& { return grid[o][best_ridge[o]]; };
  size_t top = 0;
  for (size_t o = 1; o < grid.size(); ++o) {
    if (bestOf(o).correction.sse < bestOf(top).correction.sse) top = o;
  }
  const CrossValidation::Outcome top_outcome = cv.heldOut(bestOf(top).correction);
  // Of the orders not significantly worse, the lowest whose harmonics are separable on these
  // angles if any is: a lower order can hold a faster harmonic on a narrow arc only by
  // cancelling amplitudes many times its RMS, and what it then misses other profiles take up.
  const auto separable = [&](const Configuration& c) {
    Mechanism m = family.mechanism;
    m.order = c.order;
    const Eigen::VectorXd& x = c.correction.x.back();
    m.parameters.assign(x.data() + x.size() - 2 * c.order, x.data() + x.size());
    return harmonicsSeparable(m, profileRms(m, fit));
  };
  size_t order_index = top;
  CrossValidation::Outcome order_outcome = top_outcome;
  for (const bool need_separable : {true, false}) {
    bool found = false;
    for (size_t o = 0; o < top && !found; ++o) {
      if (need_separable && !separable(bestOf(o))) continue;
      CrossValidation::Outcome outcome = cv.heldOut(bestOf(o).correction);
      if (signedRankZ(outcome.pose_sse, top_outcome.pose_sse) < 2.0) {
        order_index = o;
        order_outcome = std::move(outcome);
        found = true;
      }
    }
    if (found || (need_separable && separable(bestOf(top)))) break;
  }
  size_t ridge_index = best_ridge[order_index];
  CrossValidation::Outcome chosen_outcome = order_outcome;
  for (size_t i = grid[order_index].size(); i-- > best_ridge[order_index] + 1;) {
    CrossValidation::Outcome outcome = cv.heldOut(grid[order_index][i].correction);
    if (signedRankZ(outcome.pose_sse, order_outcome.pose_sse) < 2.0) {
      ridge_index = i;
      chosen_outcome = std::move(outcome);
      break;
    }
  }
  const Configuration& chosen = grid[order_index][ridge_index];
  const int order = chosen.order;
  Scored s;
  s.family = &family;
  s.outcome = std::move(chosen_outcome);
  s.lambda = chosen.rho * mean_diag;
  Mechanism m = family.mechanism;
  m.order = order;
  m.parameters.assign(static_cast<size_t>(2 * order), 0.0);
  m.sigma.assign(m.parameters.size(), 0.0);
  const Eigen::VectorXd& x = chosen.correction.x.back();
  for (int i = 0; i < 2 * order; ++i) {
    m.parameters[static_cast<size_t>(i)] = x(x.size() - 2 * order + i);
  }
  s.score.mechanism = std::move(m);
  s.score.ridge = chosen.rho;
  s.score.configurations = static_cast<int>(grid.size() * ridges.size());
  // Its gain is that of the configuration added; its test that of the best configuration
  // (whether the family explains anything at all; Bonferroni covers the choice among them).
  const Comparison added = compare(base, s.outcome), best = compare(base, top_outcome);
  s.score.cv_gain_mm = added.gain_mm;
  s.score.relative_reduction = added.relative_reduction;
  s.score.z_statistic = best.z;
  s.score.p_value = best.p;
  s.spent = 2 * order;
  return s;
}

// Physical constants of the arm first: among the significant families of self weight under the
// URDF's masses, thermal expansion and sensor bias if there is one, else among all. Each of these
// has a form fixed by physics and parameters that are constants of the arm (a compliance, an
// expansion coefficient, the sensor's offset), so it holds at poses far from the fit rows. Lumped
// masses (24 free parameters), a coupling c·q_i, or a torque–deflection curve (on an unloaded arm
// a function of the pose through its own gravity torque) can instead stand for any smooth error
// of the angles they were fitted on: they compete with the profiles on equal terms. (On the real
// UR10, giving them priority too made the A → D case of docs/diagnosis.md, "On the real UR10",
// 0.05 mm worse when this rule was chosen.) Then the family with the largest held-out reduction,
// unless one spending fewer parameters is not significantly worse (signed-rank z < 2 on the
// per-pose errors): then the simplest such (nonlinear stiffness with a small τ₀ imitates
// backlash, for instance).
size_t choose(const std::vector<Scored>& scored, std::vector<size_t> significant) {
  std::vector<size_t> constants;
  for (size_t k : significant) {
    const Family& f = *scored[k].family;
    const MechanismKind kind = f.mechanism.kind;
    if ((kind == MechanismKind::kSelfWeight && f.free.empty()) ||
        kind == MechanismKind::kThermalExpansion || kind == MechanismKind::kSensorBias) {
      constants.push_back(k);
    }
  }
  if (!constants.empty()) significant = constants;
  auto total = [&](size_t k) {
    return std::accumulate(scored[k].outcome.pose_sse.begin(), scored[k].outcome.pose_sse.end(), 0.0);
  };
  size_t best = significant.front();
  for (size_t k : significant) {
    if (total(k) < total(best)) best = k;
  }
  size_t chosen = best;
  for (size_t k : significant) {
    if (scored[k].spent >= scored[chosen].spent) continue;
    if (signedRankZ(scored[k].outcome.pose_sse, scored[best].outcome.pose_sse) < 2.0) chosen = k;
  }
  return chosen;
}

bool sameCandidate(const Mechanism& a, const Mechanism& b) {
  return a.kind == b.kind && a.joint == b.joint && a.source_joint == b.source_joint;
}

}  // namespace stepcal::trainer::diagnosis
