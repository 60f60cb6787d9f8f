// Scoring a round's families on held-out poses, and choosing among the significant ones
// (scoring.hpp).
#include "scoring.hpp"

#include <algorithm>
#include <string>

#include "parallel.hpp"
#include "profiles.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

// Candidate parameters from the coefficients fitted on every row (index folds of x).
void storeCoefficients(const Family& family, const CrossValidation::Correction& c, size_t offset,
                       Mechanism& m) {
  const Eigen::VectorXd& x = c.x.back();
  for (size_t k = 0; k < family.free.size(); ++k) {
    m.parameter(family.free[k]) = x(static_cast<Eigen::Index>(offset + k));
  }
}

// The family's bounds on its candidate columns' values (a bounded parameter's value is its
// column's x, as storeCoefficients reads it), C x ≥ d, over its columns (free, then compliance);
// a bound on no free parameter is left out.
void candidateBounds(const Family& family, Eigen::MatrixXd& C, Eigen::VectorXd& d) {
  std::vector<Eigen::VectorXd> rows;
  std::vector<double> floors;
  for (const PhysicalBound& b : family.bounds) {
    Eigen::VectorXd row = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(family.columns.size()));
    double floor = 0.0;
    bool touches = false;
    for (const auto& [index, coefficient] : b.terms) {
      const auto at = std::find(family.free.begin(), family.free.end(), index);
      if (at == family.free.end()) {
        floor -= coefficient * family.mechanism.parameter(index);
      } else {
        row(at - family.free.begin()) += coefficient;
        touches = true;
      }
    }
    if (touches && floor <= 0.0) {
      rows.push_back(std::move(row));
      floors.push_back(floor);
    }
  }
  C.resize(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(family.columns.size()));
  d.resize(static_cast<Eigen::Index>(rows.size()));
  for (size_t r = 0; r < rows.size(); ++r) {
    C.row(static_cast<Eigen::Index>(r)) = rows[r].transpose();
    d(static_cast<Eigen::Index>(r)) = floors[r];
  }
}

// A global family's correction: fitted freely, and when that fit is physically impossible
// (brokenBound) fitted again within the bounds (the unbounded one kept for the report).
struct GlobalCorrections {
  CrossValidation::Correction fitted;     // within the bounds where they were needed
  CrossValidation::Correction unbounded;  // only where they were
  std::string impossible;                 // what the unbounded fit broke, "" none
};

GlobalCorrections globalCorrections(const Family& family, const CrossValidation& cv,
                                    size_t stage1_size) {
  GlobalCorrections g;
  g.fitted = cv.withGlobal(family.columns);
  Mechanism m = family.mechanism;
  storeCoefficients(family, g.fitted, stage1_size, m);
  g.impossible = brokenBound(m, family.bounds);
  if (g.impossible.empty()) return g;
  Eigen::MatrixXd C;
  Eigen::VectorXd d;
  candidateBounds(family, C, d);
  g.unbounded = std::move(g.fitted);
  g.fitted = cv.withGlobal(family.columns, C, d);
  return g;
}

}  // namespace

CrossValidation::Correction globalBeside(const Scored& scored, const CrossValidation& cv,
                                         const std::vector<Eigen::Index>& extra) {
  const Family& family = *scored.family;
  std::vector<Eigen::Index> columns = family.columns;
  columns.insert(columns.end(), extra.begin(), extra.end());
  if (scored.score.impossible_unbounded.empty()) return cv.withGlobal(columns);
  Eigen::MatrixXd C;
  Eigen::VectorXd d;
  candidateBounds(family, C, d);
  Eigen::MatrixXd padded = Eigen::MatrixXd::Zero(C.rows(), static_cast<Eigen::Index>(columns.size()));
  padded.leftCols(C.cols()) = C;
  return cv.withGlobal(columns, padded, d);
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

int configurations(const Family& family, const DiagnoseOptions& options) {
  if (family.stage == Stage::kGlobal) return 1;
  int orders = 0;
  for (int order : options.profile_orders) orders += 2 * order <= static_cast<int>(family.columns.size());
  return orders * static_cast<int>(options.profile_ridges.size());
}

namespace {

// A profile family over the grid of orders and ridges, the simplest configuration the held-out
// poses do not show to be worse than the best: the best ridge per order by held-out squared
// error; the lowest order whose best is not significantly worse than the best order's (signed-rank
// z < 2 on the per-pose errors); at that order, the largest ridge not significantly worse than
// its best. The cross-validated error is flat near its minimum, so the minimum itself moves with
// small changes of the data; the simplest configuration on the flat part does not.
struct ProfileScoring {
  struct Configuration {
    int order = 0;
    double rho = 0.0;
    CrossValidation::Correction correction;
  };
  // Per order, every ridge's correction (ascending ridge) and the index of the best.
  std::vector<std::vector<Configuration>> grid;
  std::vector<size_t> best_ridge;
  size_t top = 0;           // the order whose best is best
  double mean_diag = 0.0;   // what the relative ridges scale
  size_t order_index = 0;   // the order chosen, with its best's outcome
  CrossValidation::Outcome order_outcome;
  Comparison best;          // the best configuration against the base

  const Configuration& bestOf(size_t o) const { return grid[o][best_ridge[o]]; }
};

ProfileScoring profileGrid(const Family& family, const CrossValidation& cv, const FoldGrams& grams,
                           const DiagnoseOptions& options) {
  ProfileScoring p;
  const CrossValidation::ProfileCandidate prepared = cv.prepareProfile(family.columns);
  for (Eigen::Index c : family.columns) p.mean_diag += grams.scale(c) * grams.scale(c);
  p.mean_diag /= static_cast<double>(family.columns.size());
  std::vector<int> orders = options.profile_orders;
  std::sort(orders.begin(), orders.end());
  std::vector<double> ridges = options.profile_ridges;
  std::sort(ridges.begin(), ridges.end());
  for (int order : orders) {
    if (2 * order > static_cast<int>(family.columns.size())) continue;
    std::vector<ProfileScoring::Configuration> row;
    for (double rho : ridges) {
      row.push_back({order, rho, cv.withProfile(prepared, 2 * order, rho * p.mean_diag)});
    }
    size_t best = 0;
    for (size_t i = 1; i < row.size(); ++i) {
      if (row[i].correction.sse < row[best].correction.sse) best = i;
    }
    p.grid.push_back(std::move(row));
    p.best_ridge.push_back(best);
  }
  for (size_t o = 1; o < p.grid.size(); ++o) {
    if (p.bestOf(o).correction.sse < p.bestOf(p.top).correction.sse) p.top = o;
  }
  return p;
}

// The order chosen from the held-out outcomes of each order's best up to the top one: of the
// orders not significantly worse than the top, the lowest whose harmonics are separable on these
// angles if any is (a lower order can hold a faster harmonic on a narrow arc only by cancelling
// amplitudes many times its RMS, and what it then misses other profiles take up).
void chooseOrder(ProfileScoring& p, std::vector<CrossValidation::Outcome> by_order,
                 const Family& family, const FitRows& fit) {
  const auto separable = [&](const ProfileScoring::Configuration& c) {
    Mechanism m = family.mechanism;
    m.order = c.order;
    const Eigen::VectorXd& x = c.correction.x.back();
    m.parameters.assign(x.data() + x.size() - 2 * c.order, x.data() + x.size());
    return harmonicsSeparable(m, profileRms(m, fit));
  };
  const CrossValidation::Outcome& top_outcome = by_order[p.top];
  p.order_index = p.top;
  for (const bool need_separable : {true, false}) {
    bool found = false;
    for (size_t o = 0; o < p.top && !found; ++o) {
      if (need_separable && !separable(p.bestOf(o))) continue;
      if (signedRankZ(by_order[o].pose_sse, top_outcome.pose_sse) < 2.0) {
        p.order_index = o;
        found = true;
      }
    }
    if (found || (need_separable && separable(p.bestOf(p.top)))) break;
  }
  p.order_outcome = std::move(by_order[p.order_index]);
}

// The profile's score at the chosen order and the largest of its ridges above the best whose
// outcome is not significantly worse (ridge_outcomes: of the ridges above the best, ascending),
// else the best.
Scored finishProfile(const Family& family, ProfileScoring& p, const CrossValidation::Outcome& base,
                     std::vector<CrossValidation::Outcome> ridge_outcomes,
                     const DiagnoseOptions& options) {
  size_t ridge_index = p.best_ridge[p.order_index];
  CrossValidation::Outcome chosen_outcome = std::move(p.order_outcome);
  for (size_t i = ridge_outcomes.size(); i-- > 0;) {
    if (signedRankZ(ridge_outcomes[i].pose_sse, chosen_outcome.pose_sse) < 2.0) {
      ridge_index = p.best_ridge[p.order_index] + 1 + i;
      chosen_outcome = std::move(ridge_outcomes[i]);
      break;
    }
  }
  const ProfileScoring::Configuration& chosen = p.grid[p.order_index][ridge_index];
  const int order = chosen.order;
  Scored s;
  s.family = &family;
  s.outcome = std::move(chosen_outcome);
  s.lambda = chosen.rho * p.mean_diag;
  Mechanism m = family.mechanism;
  m.order = order;
  m.parameters.assign(static_cast<size_t>(2 * order), 0.0);
  m.sigma.assign(m.parameters.size(), 0.0);
  const Eigen::VectorXd& x = chosen.correction.x.back();
  for (int i = 0; i < 2 * order; ++i) {
    m.parameter(i) = x(x.size() - 2 * order + i);
  }
  s.score.mechanism = std::move(m);
  s.score.ridge = chosen.rho;
  s.score.configurations = configurations(family, options);
  // Its gain is that of the configuration added; its test that of the best configuration
  // (whether the family explains anything at all; Bonferroni covers the choice among them).
  const Comparison added = compare(base, s.outcome);
  s.score.cv_gain_mm = added.gain_mm;
  s.score.relative_reduction = added.relative_reduction;
  s.score.z_statistic = p.best.z;
  s.score.p_value = p.best.p;
  s.spent = 2 * order;
  return s;
}

// A global family added to stage 1, from its correction's held-out outcome.
Scored finishGlobal(const Family& family, const CrossValidation::Correction& c,
                    CrossValidation::Outcome outcome, const CrossValidation::Outcome& base,
                    size_t stage1_size) {
  Scored s;
  s.family = &family;
  s.outcome = std::move(outcome);
  s.score.mechanism = family.mechanism;
  storeCoefficients(family, c, stage1_size, s.score.mechanism);
  const Comparison cmp = compare(base, s.outcome);
  s.score.cv_gain_mm = cmp.gain_mm;
  s.score.relative_reduction = cmp.relative_reduction;
  s.score.z_statistic = cmp.z;
  s.score.p_value = cmp.p;
  s.score.physical = !family.negative_compliance && brokenBound(s.score.mechanism, family.bounds).empty();
  s.spent = static_cast<int>(family.free.size() + family.compliance.size()) + family.chosen;
  return s;
}

}  // namespace

std::vector<Scored> scoreFamilies(const std::vector<Family>& families, const CrossValidation& cv,
                                  size_t stage1_size, const FoldGrams& grams,
                                  const DiagnoseOptions& options, const FitRows& fit,
                                  const std::function<bool(const CandidateScore&)>& keep) {
  const size_t count = families.size();
  // Every configuration fitted from the Grams (on the cores).
  std::vector<GlobalCorrections> global(count);
  std::vector<ProfileScoring> profile(count);
  parallelFor(count, [&](size_t k) {
    if (families[k].stage == Stage::kGlobal) {
      global[k] = globalCorrections(families[k], cv, stage1_size);
    } else {
      profile[k] = profileGrid(families[k], cv, grams, options);
    }
  });
  // Held out, first the base model with every global family and each profile's best per order
  // up to its top one; then each profile's larger ridges at the order chosen.
  std::vector<std::vector<const CrossValidation::Correction*>> groups(count + 1);
  groups[0] = {&cv.base()};
  for (size_t k = 0; k < count; ++k) {
    if (families[k].stage == Stage::kGlobal) {
      groups[k + 1] = {&global[k].fitted};
      if (!global[k].impossible.empty()) groups[k + 1].push_back(&global[k].unbounded);
      continue;
    }
    for (size_t o = 0; o <= profile[k].top; ++o) groups[k + 1].push_back(&profile[k].bestOf(o).correction);
  }
  CrossValidation::Outcome base;
  std::vector<Scored> scored(count);
  const auto kept = [&](Scored& s) {
    s.total = s.outcome.total();
    if (!keep(s.score)) s.outcome.pose_sse = std::vector<double>();
  };
  // Each pass's groups finished on the cores (the base first: every comparison is with it).
  using Outcomes = std::vector<std::vector<CrossValidation::Outcome>>;
  cv.heldOutInGroups(groups, heldOutBatch(fit), [&](size_t first, Outcomes outcomes) {
    if (first == 0) base = std::move(outcomes.front().front());
    parallelFor(outcomes.size(), [&](size_t i) {
      if (first + i == 0) return;
      const size_t k = first + i - 1;
      if (families[k].stage == Stage::kGlobal) {
        scored[k] = finishGlobal(families[k], global[k].fitted, std::move(outcomes[i].front()),
                                 base, stage1_size);
        if (!global[k].impossible.empty()) {
          const Comparison unbounded = compare(base, outcomes[i].back());
          scored[k].score.impossible_unbounded = global[k].impossible;
          scored[k].score.unbounded_cv_gain_mm = unbounded.gain_mm;
          scored[k].score.unbounded_relative_reduction = unbounded.relative_reduction;
          scored[k].score.unbounded_z_statistic = unbounded.z;
          scored[k].score.unbounded_p_value = unbounded.p;
        }
        kept(scored[k]);
        return;
      }
      profile[k].best = compare(base, outcomes[i][profile[k].top]);
      chooseOrder(profile[k], std::move(outcomes[i]), families[k], fit);
    });
  });
  std::vector<std::vector<const CrossValidation::Correction*>> ridges(count);
  for (size_t k = 0; k < count; ++k) {
    if (families[k].stage == Stage::kGlobal) continue;
    const ProfileScoring& p = profile[k];
    const std::vector<ProfileScoring::Configuration>& row = p.grid[p.order_index];
    for (size_t i = p.best_ridge[p.order_index] + 1; i < row.size(); ++i) {
      ridges[k].push_back(&row[i].correction);
    }
  }
  cv.heldOutInGroups(ridges, heldOutBatch(fit), [&](size_t first, Outcomes outcomes) {
    parallelFor(outcomes.size(), [&](size_t i) {
      const size_t k = first + i;
      if (families[k].stage == Stage::kGlobal) return;
      scored[k] = finishProfile(families[k], profile[k], base, std::move(outcomes[i]), options);
      kept(scored[k]);
    });
  });
  return scored;
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
  auto total = [&](size_t k) { return scored[k].total; };
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
