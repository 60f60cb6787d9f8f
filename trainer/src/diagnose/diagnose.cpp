// stepcal::trainer::diagnose: rounds of screening and refitting (diagnose.hpp), then the verdict,
// the extended model and its gain.
#include "stepcal/trainer/diagnose.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>

#include "candidates.hpp"
#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"
#include "parallel.hpp"
#include "profiles.hpp"
#include "residual_statistics.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal::trainer {
namespace {

using namespace diagnosis;

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<Measurement> validationRows(const Campaign& campaign) {
  std::vector<Measurement> rows;
  for (const Measurement& m : campaign.rows) {
    if (m.set == RowSet::kValidation) rows.push_back(m);
  }
  return rows;
}

// One family's best configuration in a round, with its held-out outcome.
struct Scored {
  CandidateScore score;
  CrossValidation::Outcome outcome;
  const Family* family = nullptr;
  double lambda = 0.0;  // a profile's absolute ridge
  int spent = 0;        // parameters it spends
};

// Candidate parameters from the coefficients fitted on every row (index folds of x).
void storeCoefficients(const Family& family, const CrossValidation::Correction& c, size_t offset,
                       Mechanism& m) {
  const Eigen::VectorXd& x = c.x.back();
  for (size_t k = 0; k < family.free.size(); ++k) {
    m.parameters[static_cast<size_t>(family.free[k])] = x(static_cast<Eigen::Index>(offset + k));
  }
}

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
  const MechanismKind kind = family.mechanism.kind;
  s.score.physical = !family.negative_compliance &&
                     !((kind == MechanismKind::kBacklash || kind == MechanismKind::kNonlinearStiffness) &&
                       s.score.mechanism.parameters[0] < 0.0);
  s.spent = static_cast<int>(family.free.size() + family.compliance.size()) +
            (family.mechanism.kind == MechanismKind::kNonlinearStiffness ? 1 : 0);
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

// A profile's largest harmonic amplitude, rad.
double largestAmplitude(const Mechanism& profile) {
  double largest = 0.0;
  for (int k = 0; k < profile.order; ++k) {
    largest = std::max(largest, std::hypot(profile.parameters[static_cast<size_t>(2 * k)],
                                           profile.parameters[static_cast<size_t>(2 * k + 1)]));
  }
  return largest;
}

// Whether a profile's single harmonics mean anything: not when its largest amplitude exceeds 3×
// its RMS over the fit rows (rms_rad), where neighbouring harmonics cancel each other.
bool harmonicsSeparable(const Mechanism& profile, double rms_rad) {
  return largestAmplitude(profile) <= 3.0 * rms_rad;
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
// masses (24 free parameters), a coupling c·q_i, or backlash and nonlinear stiffness (on an
// unloaded arm functions of the pose through its own gravity torque) can instead stand for any
// smooth error of the angles they were fitted on: they compete with the profiles on equal terms. (On the real UR10, giving them
// priority too made series A → D 0.05 mm worse: README, "On a real robot".)
// Then the family with the largest held-out reduction, unless one spending fewer parameters is
// not significantly worse (paired t < 2 on the per-pose errors): then the simplest such
// (nonlinear stiffness with a small τ₀ imitates backlash, for instance).
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

// A family that explained nearly as much as the one chosen (at least kRivalShare of its
// reduction of the held-out error) in the round it was chosen, and its reduction then.
constexpr double kRivalShare = 0.8;
struct Rival {
  Mechanism mechanism;
  double relative_reduction = 0.0;
};

bool sameCandidate(const Mechanism& a, const Mechanism& b) {
  return a.kind == b.kind && a.joint == b.joint && a.source_joint == b.source_joint;
}

// The rivals of the effect named last that this round's scores (with that effect in the model)
// show to explain nothing more: no configuration of them removes the practical minimum or a
// quarter of what they removed before. They explained the same error: the rows cannot tell
// them from the effect.
void namePreviousAlternatives(const std::vector<Scored>& scored, const DiagnoseOptions& options,
                              const std::vector<Rival>& rivals, FoundEffect& effect) {
  for (const Rival& rival : rivals) {
    double now = -std::numeric_limits<double>::infinity();
    for (const Scored& s : scored) {
      if (sameCandidate(s.score.mechanism, rival.mechanism)) {
        now = std::max(now, s.score.relative_reduction);
      }
    }
    bool named = false;  // one name per candidate (nonlinear stiffness has several τ₀)
    for (const Mechanism& m : effect.alternatives) named = named || sameCandidate(m, rival.mechanism);
    if (!named && std::isfinite(now) &&
        now < std::max(options.min_relative_reduction, 0.25 * rival.relative_reduction)) {
      effect.alternatives.push_back(rival.mechanism);
    }
  }
}

// Adds a chosen family to the model: a profile (its coefficients come from the next stage-2
// fit), or a global mechanism (the caller refits the global part; the profiles then need a fit
// on what it leaves).
void addFamily(DiagnosisModel& model, const Scored& chosen) {
  const Family& family = *chosen.family;
  if (family.stage == Stage::kProfile) {
    Profile p;
    p.mechanism = chosen.score.mechanism;
    std::fill(p.mechanism.parameters.begin(), p.mechanism.parameters.end(), 0.0);
    p.ridge = chosen.lambda;
    model.profiles.push_back(std::move(p));
  } else {
    Mechanism m = family.mechanism;  // from zero: the first Gauss–Newton step is the linear fit
    for (int j : family.compliance) model.compliance_free[static_cast<size_t>(j)] = true;
    if (m.kind == MechanismKind::kSelfWeight && family.free.empty()) model.masses_from_urdf = true;
    model.global.mechanisms.push_back(std::move(m));
  }
}

// Index in d.effects of the k-th global cause found (effects other than profiles are the global
// mechanisms found, in the same order).
long globalEffect(const Diagnosis& d, size_t k) {
  size_t global_index = 0;
  for (size_t e = 0; e < d.effects.size(); ++e) {
    if (d.effects[e].mechanism.kind == MechanismKind::kTransmissionError) continue;
    if (global_index++ == k) return static_cast<long>(e);
  }
  STEPCAL_INVARIANT(false, "every global mechanism found has its effect");
  return -1;
}

// Joint fits of the whole model once every cause is named (each rebuilds the screening).
constexpr int kJointFitPasses = 2;

// Whether a fitted global mechanism has a size: one of its fitted parameters at least one σ from
// zero (self weight under the URDF's masses fits none: its size is the compliance it frees). A
// profile's is its size_chi2.
bool hasSize(const Mechanism& m, bool masses_from_urdf) {
  const std::vector<int> fitted = freeParameters(m, masses_from_urdf);
  if (m.kind == MechanismKind::kSelfWeight && fitted.empty()) return true;
  return std::any_of(fitted.begin(), fitted.end(), [&m](int i) {
    return std::abs(m.parameters[static_cast<size_t>(i)]) > m.sigma[static_cast<size_t>(i)];
  });
}

// Whether a found mechanism's sign-constrained parameter (lost motion, extra compliance) is
// negative.
bool wrongSign(const Mechanism& m) {
  return (m.kind == MechanismKind::kBacklash || m.kind == MechanismKind::kNonlinearStiffness) &&
         m.parameters[0] < 0.0;
}

// The global part refitted under its physics' signs (an active set): a compliance that comes out
// negative is held at zero, a mechanism found here whose lost motion or extra compliance turns
// negative once refitted with the rest is dropped (with its effect), and the refit repeats.
// Says what it did in identifiability.
void refitPhysical(DiagnosisModel& model, const FitRows& fit, const DiagnoseOptions& options,
                   size_t base_globals, JointVector& compliance_sigma, Diagnosis& d,
                   bool hold_profiles = false) {
  for (;;) {
    refitGlobal(model, fit, options.refit_iterations, compliance_sigma, hold_profiles);
    JointVector& c = model.global.compliance_rad_per_nm;
    Eigen::Index joint = -1;
    for (Eigen::Index j = 0; j < c.size(); ++j) {
      if (model.compliance_free[static_cast<size_t>(j)] && c(j) < 0.0) joint = j;
    }
    if (joint >= 0) {
      char line[200];
      std::snprintf(line, sizeof line,
                    "joint %ld's compliance came out negative (%.3g rad/(N·m)) refitted with the "
                    "rest: held at zero, the data show no deflection of it under load",
                    static_cast<long>(joint + 1), c(joint));
      d.identifiability.push_back(line);
      c(joint) = 0.0;
      compliance_sigma(joint) = 0.0;
      model.compliance_free[static_cast<size_t>(joint)] = false;
      continue;
    }
    size_t dropped = model.global.mechanisms.size();
    for (size_t k = base_globals; k < model.global.mechanisms.size(); ++k) {
      if (wrongSign(model.global.mechanisms[k])) dropped = k;
    }
    if (dropped == model.global.mechanisms.size()) return;
    const Mechanism& m = model.global.mechanisms[dropped];
    d.identifiability.push_back(describe(m) + ": dropped, its " +
                                mechanismParameterNames(m.kind, 0)[0] +
                                " turned negative once refitted with the other causes found "
                                "(another of them explains what it did)");
    d.effects.erase(d.effects.begin() + globalEffect(d, dropped - base_globals));
    model.global.mechanisms.erase(model.global.mechanisms.begin() + static_cast<long>(dropped));
  }
}

// The whole model fitted jointly, linearised where the screening was built: every current
// column (geometry, global parameters, profiles) in one least-squares problem, the ridges on
// their values, so what a global cause and a profile share goes to the one without a ridge (the
// global cause: physics that holds everywhere). Alternating the two fits converges there only
// slowly where they share much (a lumped self weight and a shoulder profile over a narrow arc).
// Applied to the model, with r0 and the screening's values moved to it; the global parameters get
// their σ from it (compliance_sigma: n entries), the profiles their σ and shares of the geometry
// (storeStage2), the global geometry what is left of its change.
void jointStep(DiagnosisModel& model, Screening& sc, FoldGrams& grams, const FitRows& fit,
               Eigen::Index geometry, JointVector& compliance_sigma) {
  const std::vector<Parameter> params = globalParameters(model);
  STEPCAL_INVARIANT(sc.stage1.size() == static_cast<size_t>(geometry) + params.size(),
                    "stage 1 holds the geometry and every global parameter");
  std::vector<Eigen::Index> columns = sc.stage1;
  const std::vector<Eigen::Index> profile_columns(sc.stage2.begin() + geometry, sc.stage2.end());
  columns.insert(columns.end(), profile_columns.begin(), profile_columns.end());
  const CrossValidation cv(grams, fit, sc.stage1, sc.stage2, sc.ridge, sc.current);
  const CrossValidation::JointFit joint = cv.jointFit(columns);
  const Eigen::VectorXd& delta = joint.change;
  Eigen::VectorXd moved = Eigen::VectorXd::Zero(sc.current.size());
  for (size_t k = 0; k < columns.size(); ++k) moved(columns[k]) = -delta(static_cast<Eigen::Index>(k));

  for (size_t c = 0; c < params.size(); ++c) {
    const Eigen::Index k = geometry + static_cast<Eigen::Index>(c);
    shift(model.global, params[c], delta(k));
    const double sigma = std::sqrt(joint.variance * joint.unit_variance(k));
    if (params[c].mechanism < 0) {
      compliance_sigma(params[c].index) = sigma;
    } else {
      model.global.mechanisms[static_cast<size_t>(params[c].mechanism)]
          .sigma[static_cast<size_t>(params[c].index)] = sigma;
    }
  }
  Eigen::VectorXd old_share = Eigen::VectorXd::Zero(geometry);
  for (const Profile& p : model.profiles) {
    if (p.geometry.size() == geometry) old_share += p.geometry;
  }
  const Eigen::Index width = static_cast<Eigen::Index>(sc.stage2.size());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(width);
  const Eigen::Index first_profile = static_cast<Eigen::Index>(sc.stage1.size());
  for (Eigen::Index c = geometry; c < width; ++c) {
    x(c) = sc.current(sc.stage2[static_cast<size_t>(c)]) + delta(first_profile + c - geometry);
  }
  Eigen::MatrixXd H = grams.G[static_cast<size_t>(fit.folds)](sc.stage2, sc.stage2);
  H.diagonal() += sc.ridge(sc.stage2);
  storeStage2(model, H, x, joint.variance);
  Eigen::VectorXd new_share = Eigen::VectorXd::Zero(geometry);
  for (const Profile& p : model.profiles) new_share += p.geometry;
  model.global.chain_Tracker =
      model.global.chain_Tracker.corrected(delta.head(geometry) + old_share - new_share);

  for (size_t c = 0; c < params.size(); ++c) {
    sc.current(sc.stage1[static_cast<size_t>(geometry) + c]) += delta(geometry + static_cast<Eigen::Index>(c));
  }
  setStage2(sc, model, geometry);
  grams.takeOut(moved);
}

// The round's screening and its Grams, built at the model as it stands and moved to its joint
// fit (jointStep) when it has profiles.
void buildScreening(DiagnosisModel& model, const FitRows& fit, const DiagnoseOptions& options,
                    const std::optional<std::vector<double>>& body_masses, Screening& sc,
                    std::unique_ptr<FoldGrams>& grams, JointVector& compliance_sigma,
                    const Mechanism* only = nullptr) {
  const RoundStart start = roundStart(model, fit);
  sc = screening(model, fit, start, options, body_masses, only);
  grams = std::make_unique<FoldGrams>(std::move(sc.A), start.evaluation.r, fit);
  sc.A.resize(0, 0);
  if (!model.profiles.empty()) {
    jointStep(model, sc, *grams, fit, 6 * (model.global.chain_Tracker.dof() + 1), compliance_sigma);
  }
}

// The model without its global mechanism k: the compliances only it made identifiable (self
// weight) go back to the starting model's.
void dropGlobal(DiagnosisModel& model, size_t k, const FoundEffect& effect,
                const std::vector<bool>& starting_compliance) {
  const Mechanism& m = model.global.mechanisms[k];
  for (int j : effect.compliance_joints) {
    if (starting_compliance[static_cast<size_t>(j)]) continue;
    model.global.compliance_rad_per_nm(j) = 0.0;
    model.compliance_free[static_cast<size_t>(j)] = false;
  }
  if (m.kind == MechanismKind::kSelfWeight) model.masses_from_urdf = false;
  model.global.mechanisms.erase(model.global.mechanisms.begin() + static_cast<long>(k));
}

// Global mechanism k (found here) tried again as a candidate with every other cause in the
// model: its best configuration's comparison when it is no longer significant (so it is to be
// dropped), nullopt when it still is or cannot be tried.
std::optional<Comparison> withoutGlobal(const DiagnosisModel& model, size_t k, size_t base_globals,
                                        const FitRows& fit, const DiagnoseOptions& options,
                                        const std::optional<std::vector<double>>& body_masses,
                                        const std::vector<bool>& starting_compliance,
                                        const Diagnosis& d) {
  DiagnosisModel trial = model;
  Diagnosis scratch = d;
  const Mechanism removed = model.global.mechanisms[k];
  dropGlobal(trial, k, d.effects[static_cast<size_t>(globalEffect(d, k - base_globals))],
             starting_compliance);
  scratch.effects.erase(scratch.effects.begin() + globalEffect(d, k - base_globals));
  JointVector sigma = JointVector::Zero(trial.global.chain_Tracker.dof());
  refitPhysical(trial, fit, options, base_globals, sigma, scratch, true);
  if (trial.global.mechanisms.size() + 1 != model.global.mechanisms.size()) return std::nullopt;
  Screening one;
  std::unique_ptr<FoldGrams> grams;
  buildScreening(trial, fit, options, body_masses, one, grams, sigma, &removed);
  if (one.families.empty()) return std::nullopt;
  const CrossValidation cv(*grams, fit, one.stage1, one.stage2, one.ridge, one.current);
  const CrossValidation::Outcome base = cv.heldOut(cv.base());
  std::optional<Comparison> best;
  bool significant = false;
  for (Family& family : one.families) {
    pruneNegativeCompliance(family, cv, one.stage1.size(), trial);
    const Scored scored = scoreGlobal(family, cv, base, one.stage1.size());
    const Comparison c = compare(base, scored.outcome);
    significant = significant ||
                  (scored.score.physical &&
                   c.p < options.family_alpha / static_cast<double>(one.families.size()) &&
                   c.relative_reduction >= options.min_relative_reduction);
    if (!best || c.relative_reduction > best->relative_reduction) best = c;
  }
  if (significant) return std::nullopt;
  return best;
}

std::string percent(double share) {
  char s[16];
  std::snprintf(s, sizeof s, "%.0f %%", 100.0 * share);
  return s;
}

}  // namespace

const char* toString(Verdict verdict) noexcept {
  switch (verdict) {
    case Verdict::kFound: return "found";
    case Verdict::kNone: return "none";
    case Verdict::kUnexplained: return "unexplained";
  }
  return "unknown";
}

Diagnosis diagnose(const Campaign& campaign, const CalibratedModel& model,
                   const DiagnoseOptions& options) {
  Diagnosis d;
  const int n = model.chain_Tracker.dof();
  requireJointCount(campaign, n);
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) {
    if (row.set != RowSet::kValidation) rows.push_back(&row);
  }
  const FitRows fit = makeFitRows(rows, campaign.tracker, options.folds);
  if (fit.poses < 4 * options.folds) {
    throw InputError("diagnosis needs at least " + std::to_string(4 * options.folds) +
                         " fit poses (distinct pose_id outside set=validation) for " +
                         std::to_string(options.folds) + "-fold cross-validation, got " +
                         std::to_string(fit.poses),
                     campaign.directory + "/" + campaign.measurements_file);
  }
  d.fit_rows = static_cast<int>(rows.size());
  d.fit_poses = fit.poses;
  d.folds = options.folds;
  const std::optional<std::vector<double>> body_masses = bodyMassesFromUrdf(
      campaign.urdf_xml, campaign.base_link, campaign.tip_link,
      campaign.directory.empty() ? campaign.robot_file : campaign.directory + "/" + campaign.robot_file);

  // The starting model: its global part, its profiles (their ridge as the middle of the grid).
  DiagnosisModel dm;
  dm.global = physicalModelOf(model);
  dm.global.mechanisms.clear();
  // A given model's profiles are refitted on this campaign, over the angles its fit rows cover
  // (so every fit row lies inside every gate); their geometry shares are fitted with them.
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind == MechanismKind::kProfileGeometry) continue;
    if (m.kind != MechanismKind::kTransmissionError) {
      dm.global.mechanisms.push_back(m);
      dm.masses_from_urdf = dm.masses_from_urdf ||
                            (m.kind == MechanismKind::kSelfWeight && body_masses &&
                             m.parameters == *body_masses);
      continue;
    }
    Profile p;
    p.mechanism = m;
    std::vector<double> angles;
    for (const Measurement* row : rows) angles.push_back(row->q_rad(m.joint));
    p.mechanism.coverage = coverageOfAngles(angles, options.coverage_gap_deg * kDegToRad,
                                            options.coverage_fade_deg * kDegToRad);
    dm.profiles.push_back(std::move(p));
  }
  for (int j = 0; j < n; ++j) dm.compliance_free.push_back(dm.global.compliance_rad_per_nm(j) > 0.0);
  const std::vector<bool> starting_compliance = dm.compliance_free;
  if (!dm.profiles.empty()) {
    const Evaluation e = evaluate(dm.global, fit);
    const Linearisation lin = linearise(dm.global, fit, e.r);
    const double rho = options.profile_ridges[options.profile_ridges.size() / 2];
    for (Profile& p : dm.profiles) {
      const Mechanism& m = p.mechanism;
      const Eigen::MatrixXd B = profileColumns(lin.link_angle, fit, m.joint, m.coverage, m.order);
      p.ridge = rho * B.colwise().squaredNorm().mean();
    }
  }

  // 1. The model refitted jointly; what it gets wrong.
  auto clock = std::chrono::steady_clock::now();
  JointVector compliance_sigma = model.compliance_sigma_rad_per_nm.size() == n
                                     ? model.compliance_sigma_rad_per_nm
                                     : JointVector(JointVector::Zero(n));
  refitPhysical(dm, fit, options, dm.global.mechanisms.size(), compliance_sigma, d);
  fitProfiles(dm, fit);
  d.seconds_refit += secondsSince(clock);
  clock = std::chrono::steady_clock::now();
  {
    const Evaluation e = evaluate(dm.combined(), fit);
    const Variables variables = trendVariables(fit, e.tau_nm, n);
    d.variable_names = variables.names;
    d.variable_values = variables.values;
    d.before = statistics(e.r, fit, variables, options.family_alpha);
  }
  d.seconds_trends += secondsSince(clock);

  // 2. Families, round by round. The screening (columns and their per-fold Grams, linearised at
  // the whole model) is rebuilt whenever the model changes.
  const size_t base_globals = dm.global.mechanisms.size(), base_profiles = dm.profiles.size();
  const Eigen::Index geometry = 6 * (n + 1);
  Screening sc;
  std::unique_ptr<FoldGrams> grams;
  std::vector<Rival> rivals;  // of the effect named last
  for (int round = 1; round <= options.max_rounds; ++round) {
    clock = std::chrono::steady_clock::now();
    if (!grams) {
      buildScreening(dm, fit, options, body_masses, sc, grams, compliance_sigma);
      d.untestable = sc.untestable;  // what the model as it now stands cannot try
    } else {
      jointStep(dm, sc, *grams, fit, geometry, compliance_sigma);  // with the profile named last
    }
    const CrossValidation cv(*grams, fit, sc.stage1, sc.stage2, sc.ridge, sc.current);
    const CrossValidation::Outcome base = cv.heldOut(cv.base());
    for (Family& family : sc.families) pruneNegativeCompliance(family, cv, sc.stage1.size(), dm);
    std::vector<Scored> scored(sc.families.size());
    parallelFor(sc.families.size(), [&](size_t k) {
      const Family& family = sc.families[k];
      scored[k] = family.stage == Stage::kGlobal
                      ? scoreGlobal(family, cv, base, sc.stage1.size())
                      : scoreProfile(family, cv, base, *grams, options, fit);
    });
    if (!d.effects.empty()) namePreviousAlternatives(scored, options, rivals, d.effects.back());
    int configurations = 0;
    for (const Scored& s : scored) configurations += s.score.configurations;
    std::vector<size_t> significant;
    for (size_t k = 0; k < scored.size(); ++k) {
      CandidateScore& s = scored[k].score;
      s.round = round;
      s.significant = s.physical &&
                      s.p_value < options.family_alpha / std::max(1, configurations) &&
                      s.relative_reduction >= options.min_relative_reduction;
      if (s.significant) significant.push_back(k);
    }
    d.seconds_screening += secondsSince(clock);
    if (significant.empty()) {
      for (Scored& s : scored) d.candidates.push_back(std::move(s.score));
      break;
    }
    const size_t chosen = choose(scored, significant);
    scored[chosen].score.chosen = true;
    addFamily(dm, scored[chosen]);
    FoundEffect effect;
    effect.round = round;
    effect.cv_gain_mm = scored[chosen].score.cv_gain_mm;
    effect.z_statistic = scored[chosen].score.z_statistic;
    effect.p_value = scored[chosen].score.p_value;
    effect.ridge = scored[chosen].score.ridge;
    effect.compliance_joints = scored[chosen].family->compliance;
    effect.mechanism = scored[chosen].score.mechanism;
    rivals.clear();
    for (size_t k : significant) {
      if (k != chosen && scored[k].score.relative_reduction >=
                             kRivalShare * scored[chosen].score.relative_reduction) {
        rivals.push_back({scored[k].score.mechanism, scored[k].score.relative_reduction});
      }
    }
    d.effects.push_back(std::move(effect));
    const Family& family = *scored[chosen].family;
    if (family.stage == Stage::kProfile) {
      // Its leading 2·order columns join stage 2 with its ridge (value 0 until the next joint
      // step); the other families stay.
      sc.profiled.push_back(family);
      sc.families.erase(sc.families.begin() + static_cast<long>(&family - sc.families.data()));
      setStage2(sc, dm, geometry);
    } else {
      // Refitted with the profiles held; the screening is rebuilt at the new model.
      clock = std::chrono::steady_clock::now();
      refitPhysical(dm, fit, options, base_globals, compliance_sigma, d, true);
      d.seconds_refit += secondsSince(clock);
      grams.reset();
    }
    for (Scored& s : scored) d.candidates.push_back(std::move(s.score));
  }
  // Backward: a global cause named in an early round that the causes named after it explain is
  // dropped (a physical constant goes first when it is significant, and may only have stood for
  // a part of what a later cause explains in full).
  for (size_t k = base_globals; k < dm.global.mechanisms.size();) {
    clock = std::chrono::steady_clock::now();
    const std::optional<Comparison> without = withoutGlobal(dm, k, base_globals, fit, options,
                                                            body_masses, starting_compliance, d);
    d.seconds_screening += secondsSince(clock);
    if (!without) {
      ++k;
      continue;
    }
    const Mechanism removed = dm.global.mechanisms[k];
    char line[300];
    std::snprintf(line, sizeof line,
                  ": dropped, the causes named after it explain what it did (tried again with "
                  "them in the model it removes %.1f %% of the held-out error, z = %.1f: not "
                  "significant)",
                  100.0 * without->relative_reduction, without->z);
    d.identifiability.push_back(describe(removed) + line);
    DiagnosisModel trial = dm;
    dropGlobal(trial, k, d.effects[static_cast<size_t>(globalEffect(d, k - base_globals))],
               starting_compliance);
    d.effects.erase(d.effects.begin() + globalEffect(d, k - base_globals));
    dm = std::move(trial);
    refitPhysical(dm, fit, options, base_globals, compliance_sigma, d, true);
    fitProfiles(dm, fit);
    grams.reset();
  }
  // Each profile's order and ridge chosen again with every other cause in the model: when it
  // was chosen, the profiles found after it were not there to explain their part. It is taken
  // out of the linearised model (its values and its share of the geometry) and tried again.
  if (!dm.profiles.empty()) {
    clock = std::chrono::steady_clock::now();
    if (!grams) {
      buildScreening(dm, fit, options, body_masses, sc, grams, compliance_sigma);
    } else {
      jointStep(dm, sc, *grams, fit, geometry, compliance_sigma);
    }
    const std::vector<Profile> found = dm.profiles;
    for (size_t i = 0; i < found.size(); ++i) {
      DiagnosisModel without = dm;
      without.profiles = found;
      without.profiles.erase(without.profiles.begin() + static_cast<long>(i));
      Screening others = sc;
      others.profiled.erase(others.profiled.begin() + static_cast<long>(i));
      setStage2(others, without, geometry);
      Eigen::VectorXd taken = Eigen::VectorXd::Zero(others.current.size());
      const Mechanism& m = found[i].mechanism;
      for (int c = 0; c < 2 * m.order; ++c) {
        taken(sc.profiled[i].columns[static_cast<size_t>(c)]) = m.parameters[static_cast<size_t>(c)];
      }
      for (Eigen::Index c = 0; c < geometry; ++c) {
        taken(sc.stage2[static_cast<size_t>(c)]) = found[i].geometry(c);
      }
      for (Eigen::Index c : sc.profiled[i].columns) others.current(c) = 0.0;
      const FoldGrams grams_without = grams->without(taken);
      const CrossValidation cv(grams_without, fit, others.stage1, others.stage2, others.ridge,
                               others.current);
      const Scored again =
          scoreProfile(sc.profiled[i], cv, cv.heldOut(cv.base()), grams_without, options, fit);
      Profile& p = dm.profiles[i];
      p.mechanism.order = again.score.mechanism.order;
      p.mechanism.parameters.assign(static_cast<size_t>(2 * p.mechanism.order), 0.0);
      p.mechanism.sigma.assign(p.mechanism.parameters.size(), 0.0);
      p.ridge = again.lambda;
      for (FoundEffect& e : d.effects) {
        if (e.mechanism.kind == MechanismKind::kTransmissionError &&
            e.mechanism.joint == p.mechanism.joint) {
          e.ridge = again.score.ridge;
        }
      }
    }
    d.seconds_screening += secondsSince(clock);

    // The profiles at their new orders, then twice the global part refitted under its signs
    // (refitPhysical) and the whole model fitted jointly from there (the joint step is linear);
    // the σ of every parameter are the joint fit's. Should the last joint step have taken a
    // compliance or a sign-constrained parameter below zero, the global refit holds it again.
    clock = std::chrono::steady_clock::now();
    fitProfiles(dm, fit);
    for (int pass = 0; pass < kJointFitPasses; ++pass) {
      refitPhysical(dm, fit, options, base_globals, compliance_sigma, d, true);
      buildScreening(dm, fit, options, body_masses, sc, grams, compliance_sigma);
    }
    bool signs_hold = true;
    for (int j = 0; j < n; ++j) {
      signs_hold = signs_hold && (!dm.compliance_free[static_cast<size_t>(j)] ||
                                  dm.global.compliance_rad_per_nm(j) >= 0.0);
    }
    for (const Mechanism& m : dm.global.mechanisms) signs_hold = signs_hold && !wrongSign(m);
    if (!signs_hold) refitPhysical(dm, fit, options, base_globals, compliance_sigma, d, true);
    grams.reset();
    d.seconds_refit += secondsSince(clock);
  }

  // Every effect's parameters and σ from the final fit, in the order found.
  {
    size_t next_global = base_globals, next_profile = base_profiles;
    for (FoundEffect& e : d.effects) {
      if (e.mechanism.kind == MechanismKind::kTransmissionError) {
        const Profile& p = dm.profiles[next_profile++];
        e.mechanism = p.mechanism;
        STEPCAL_INVARIANT(p.size_chi2 > 2.0 * p.mechanism.order,
                          (describe(e.mechanism) +
                           " was named, yet its fitted coefficients lie within one σ of zero")
                              .c_str());
      } else {
        e.mechanism = dm.global.mechanisms[next_global++];
        STEPCAL_INVARIANT(hasSize(e.mechanism, dm.masses_from_urdf),
                          (describe(e.mechanism) +
                           " was named, yet every parameter fitted for it lies within one σ of zero")
                              .c_str());
      }
    }
  }
  const PhysicalModel extended_physical = dm.combined();

  // Identifiability of what was found.
  for (const FoundEffect& f : d.effects) {
    for (const Mechanism& other : f.alternatives) {
      d.identifiability.push_back(
          describe(f.mechanism) + " and " + describe(other) +
          " explain the same error: the second removed nearly as much held-out error as the "
          "first (at least 80 %), and nothing once the first was in the model; these rows cannot "
          "tell them apart (the first was named)");
    }
  }
  {
    const Evaluation e = evaluate(dm.global, fit);
    const Linearisation lin = linearise(dm.global, fit, e.r);
    for (FoundEffect& f : d.effects) {
      const Mechanism& m = f.mechanism;
      if (m.kind == MechanismKind::kTransmissionError) {
        f.rms_rad = profileRms(m, fit);
        const double largest = largestAmplitude(m);
        f.harmonics_separable = harmonicsSeparable(m, f.rms_rad);
        if (!f.harmonics_separable) {
          char line[300];
          std::snprintf(line, sizeof line,
                        ": its harmonics cannot be told apart on the angles it covers (the "
                        "largest amplitude, %.0f urad, is %.0f times its RMS of %.0f urad: they "
                        "cancel each other there); its values over those angles are determined, "
                        "its single harmonics are not",
                        1e6 * largest, largest / f.rms_rad, 1e6 * f.rms_rad);
          d.identifiability.push_back(describe(m) + line);
        }
        f.geometry_share = geometryShare(
            lin.geometry, profileColumns(lin.link_angle, fit, m.joint, m.coverage, m.order));
        std::string shared;
        for (size_t k = 0; k < f.geometry_share.size(); ++k) {
          if (f.geometry_share[k] < 0.5) continue;
          shared += (shared.empty() ? "harmonic " : ", ") + std::to_string(k + 1) + " " +
                    percent(f.geometry_share[k]);
        }
        if (!shared.empty()) {
          d.identifiability.push_back(
              describe(m) + ": " + shared +
              " within reach of a geometric error on these rows (a tilt, offset or "
              "eccentricity of the joint): the profile and the geometry were fitted together and "
              "the ridge keeps what they share small; what the geometry took of the profile is "
              "its profile_geometry, switched with it");
        }
      } else if (m.kind == MechanismKind::kSelfWeight && dm.masses_from_urdf) {
        std::vector<double> spread;
        const std::vector<int> joints = gravityLoadedJoints(dm.global, fit, e.theta_rad, m.parameters, &spread);
        std::string text = "self_weight: link masses and centres of mass from the URDF; the "
                           "compliance of joint(s)";
        for (int j : joints) text += " " + std::to_string(j + 1);
        text += " is identified from the arm's own weight";
        for (int j = 0; j < n; ++j) {
          if (std::find(joints.begin(), joints.end(), j) != joints.end() ||
              dm.compliance_free[static_cast<size_t>(j)]) {
            continue;
          }
          char line[160];
          std::snprintf(line, sizeof line,
                        "; joint %d's gravity torque varies by %.2f N·m (std), too little for its "
                        "compliance",
                        j + 1, spread[static_cast<size_t>(j)]);
          text += line;
        }
        d.identifiability.push_back(text);
      } else if (m.kind == MechanismKind::kSelfWeight) {
        d.identifiability.push_back(
            "self_weight: only the gravity torques of the lumped link masses on the compliant "
            "joints are identifiable; the masses themselves are a representative (a weak prior of "
            "50 kg, 50 kg·m holds the rest near zero)");
      }
    }
  }

  // 3. Verdict.
  clock = std::chrono::steady_clock::now();
  {
    const Evaluation e = evaluate(extended_physical, fit);
    d.after = statistics(e.r, fit, trendVariables(fit, e.tau_nm, n), options.family_alpha);
  }
  d.seconds_trends += secondsSince(clock);
  const std::string remaining = trendSummary(d.after, options.noise_ratio_limit);
  if (!d.effects.empty()) {
    d.verdict = Verdict::kFound;
    d.unexplained_trend = remaining;
  } else if (!remaining.empty()) {
    d.verdict = Verdict::kUnexplained;
    d.unexplained_trend = remaining;
  }

  // 4. The extended model with its GPR, and the gain on validation rows.
  clock = std::chrono::steady_clock::now();
  CalibratedModel& ext = d.extended_model;
  ext = model;
  ext.chain_Tracker = extended_physical.chain_Tracker;
  ext.mechanisms = extended_physical.mechanisms;
  const bool any_compliance = extended_physical.compliance_rad_per_nm.maxCoeff() > 0.0;
  if (model.compliance_rad_per_nm.size() == n || any_compliance) {
    ext.compliance_rad_per_nm = extended_physical.compliance_rad_per_nm;
    ext.compliance_sigma_rad_per_nm = compliance_sigma;
  }
  std::vector<const Measurement*> gpr_rows = campaign.rowsIn(RowSet::kResidual);
  std::string gpr_set = "residual";
  if (gpr_rows.empty()) {
    gpr_rows = campaign.rowsIn(RowSet::kGeometry);
    gpr_set = "geometry";
  }
  const PoseModel after = physicalPoseModel(extended_physical);
  const ResidualModel residual = fitResidual(after, gpr_rows, gpr_set, options.calibration);
  ext.gpr = residual.gp.parameters();
  d.seconds_gpr = secondsSince(clock);

  clock = std::chrono::steady_clock::now();
  const std::vector<Measurement> validation = validationRows(campaign);
  d.validation_rows = static_cast<int>(validation.size());
  d.floor_position_m = noiseFloorMean(campaign.tracker.position_sigma_m);
  if (!validation.empty()) {
    const auto base_layers = modelLayers(model);
    const PoseModel before = physicalPoseModel(physicalModelOf(model));
    const bool has_gpr = model.gpr.has_value();
    d.gpr_method = has_gpr ? base_layers.back().first : "";
    const auto s_before = summarize("before", before, validation);
    const auto s_after = summarize(kMethodExtended, after, validation);
    const auto s_after_gpr =
        summarize(kMethodExtendedGpr, withResidual(after, residual.gp), validation);
    std::vector<AccuracySummary> s_gpr;
    if (has_gpr) s_gpr = summarize(d.gpr_method, base_layers.back().second, validation);
    for (size_t g = 0; g < s_before.size(); ++g) {
      GainRow row;
      row.load_kg = s_before[g].load_kg;
      row.rows = s_before[g].rows;
      row.before = s_before[g];
      row.after = s_after[g];
      row.after_gpr = s_after_gpr[g];
      if (has_gpr) row.gpr = s_gpr[g];
      d.gain.push_back(row);
    }
    ext.provenance.validation.clear();
    for (const auto& [method, layer] : modelLayers(ext)) {
      for (const AccuracySummary& s : summarize(method, layer, validation)) {
        ext.provenance.validation.push_back({s.method, s.load_kg, s.rows, s.mean_position_m,
                                             s.max_position_m, s.mean_orientation_rad});
      }
    }
  }
  d.seconds_evaluation = secondsSince(clock);
  return d;
}

}  // namespace stepcal::trainer
