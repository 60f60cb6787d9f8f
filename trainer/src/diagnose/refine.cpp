// Refining the model once the rounds are done (search.hpp): backward elimination, each profile's
// order and ridge chosen again, the final joint fits, and the causes they leave without a size
// dropped.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "model_fits.hpp"
#include "profiles.hpp"
#include "scoring.hpp"
#include "search.hpp"
#include "sizes.hpp"
#include "stepcal/common/error.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Joint fits of the whole model once every cause is named (each rebuilds the screening).
constexpr int kJointFitPasses = 2;

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
  dropGlobal(trial, k, d.effects[globalEffect(d, k - base_globals)],
             starting_compliance);
  scratch.effects.erase(scratch.effects.begin() + static_cast<long>(globalEffect(d, k - base_globals)));
  JointVector sigma = JointVector::Zero(trial.global.chain_Tracker.dof());
  refitPhysical(trial, fit, options, base_globals, sigma, scratch, true);
  if (trial.global.mechanisms.size() + 1 != model.global.mechanisms.size()) return std::nullopt;
  Screening one;
  std::unique_ptr<FoldGrams> grams;
  buildScreening(trial, fit, options, body_masses, one, grams, sigma, {true, &removed});
  if (one.families.empty()) return std::nullopt;
  const CrossValidation cv(*grams, fit, one.stage1, one.stage2, one.ridge, one.current);
  for (Family& family : one.families) pruneNegativeCompliance(family, cv, one.stage1.size(), trial);
  const std::vector<Scored> scored = scoreFamilies(one.families, cv, one.stage1.size(), *grams,
                                                   options, fit, [](const CandidateScore&) { return false; });
  std::optional<Comparison> best;
  bool significant = false;
  for (const Scored& s : scored) {
    Comparison c;
    c.relative_reduction = s.score.relative_reduction;
    c.z = s.score.z_statistic;
    c.p = s.score.p_value;
    c.gain_mm = s.score.cv_gain_mm;
    significant = significant ||
                  (s.score.physical &&
                   c.p < options.family_alpha / static_cast<double>(one.families.size()) &&
                   c.relative_reduction >= options.min_relative_reduction);
    if (!best || c.relative_reduction > best->relative_reduction) best = c;
  }
  if (significant) return std::nullopt;
  return best;
}

// A global cause named in an early round that the causes named after it explain is dropped (a
// physical constant goes first when it is significant, and may only have stood for a part of
// what a later cause explains in full).
void eliminateBackward(Search& search) {
  const FitRows& fit = search.fit;
  DiagnosisModel& dm = search.model;
  Diagnosis& d = search.d;
  const size_t base_globals = search.base_globals;
  for (size_t k = base_globals; k < dm.global.mechanisms.size();) {
    const auto clock = std::chrono::steady_clock::now();
    const std::optional<Comparison> without =
        withoutGlobal(dm, k, base_globals, fit, search.options, search.body_masses,
                      search.starting_compliance, d);
    d.seconds_screening += secondsSince(clock);
    if (!without) {
      ++k;
      continue;
    }
    ModelChange change;
    change.kind = ModelChange::Kind::kDroppedExplained;
    change.mechanism = dm.global.mechanisms[k];
    change.relative_reduction = without->relative_reduction;
    change.z_statistic = without->z;
    d.changes.push_back(std::move(change));
    const size_t effect = globalEffect(d, k - base_globals);
    dropGlobal(dm, k, d.effects[effect], search.starting_compliance);
    d.effects.erase(d.effects.begin() + static_cast<long>(effect));
    refitPhysical(dm, fit, search.options, base_globals, search.compliance_sigma, d, true);
    fitProfiles(dm, fit);
    search.grams.reset();
  }
}

// Each profile's order and ridge chosen again with every other cause in the model: when it was
// chosen, the profiles found after it were not there to explain their part. It is taken out of
// the linearised model (its values and its share of the geometry) and tried again.
void retuneProfiles(Search& search) {
  const FitRows& fit = search.fit;
  const DiagnoseOptions& options = search.options;
  DiagnosisModel& dm = search.model;
  Diagnosis& d = search.d;
  Screening& sc = search.screening;
  std::unique_ptr<FoldGrams>& grams = search.grams;
  const Eigen::Index geometry = search.geometry;
  const auto clock = std::chrono::steady_clock::now();
  if (!grams) {
    buildScreening(dm, fit, options, search.body_masses, sc, grams, search.compliance_sigma,
                   {false, nullptr});
  } else {
    jointStep(dm, sc, *grams, fit, geometry, search.compliance_sigma);
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
      taken(sc.profiled[i].columns[static_cast<size_t>(c)]) = m.parameter(c);
    }
    for (Eigen::Index c = 0; c < geometry; ++c) {
      taken(sc.stage2[static_cast<size_t>(c)]) = found[i].geometry(c);
    }
    for (Eigen::Index c : sc.profiled[i].columns) others.current(c) = 0.0;
    const FoldGrams grams_without = grams->without(taken);
    const CrossValidation cv(grams_without, fit, others.stage1, others.stage2, others.ridge,
                             others.current);
    const std::vector<Family> family = {sc.profiled[i]};
    const Scored again = scoreFamilies(family, cv, others.stage1.size(), grams_without, options,
                                       fit, [](const CandidateScore&) { return false; })
                             .front();
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
}

// Whether every compliance the fit frees and every global mechanism keeps its physics' signs and
// bounds (a linear joint step may leave one beyond them).
bool boundsHold(const DiagnosisModel& dm) {
  const int n = dm.global.chain_Tracker.dof();
  for (int j = 0; j < n; ++j) {
    if (dm.compliance_free[static_cast<size_t>(j)] && dm.global.compliance_rad_per_nm(j) < 0.0) {
      return false;
    }
  }
  for (const Mechanism& m : dm.global.mechanisms) {
    const bool lumped = m.kind != MechanismKind::kSelfWeight || !dm.masses_from_urdf;
    if (wrongSign(m) ||
        (lumped && !brokenBound(m, physicalBounds(m, dm.global.chain_Tracker)).empty())) {
      return false;
    }
  }
  return true;
}

// The final fit: the profiles at their orders, then twice the global part refitted under its
// signs (refitPhysical) and the whole model fitted jointly from there (the joint step is
// linear); the σ of every parameter are the joint fit's. Should the last joint step have taken a
// compliance or a sign-constrained parameter below zero, the global refit holds it again.
// Without profiles, the global refit alone.
void finalFit(Search& search) {
  const FitRows& fit = search.fit;
  const DiagnoseOptions& options = search.options;
  DiagnosisModel& dm = search.model;
  Diagnosis& d = search.d;
  const size_t base_globals = search.base_globals;
  const auto clock = std::chrono::steady_clock::now();
  if (dm.profiles.empty()) {
    refitPhysical(dm, fit, options, base_globals, search.compliance_sigma, d, true);
  } else {
    fitProfiles(dm, fit);
    for (int pass = 0; pass < kJointFitPasses; ++pass) {
      refitPhysical(dm, fit, options, base_globals, search.compliance_sigma, d, true);
      buildScreening(dm, fit, options, search.body_masses, search.screening, search.grams,
                     search.compliance_sigma, {false, nullptr});
    }
    if (!boundsHold(dm)) {
      refitPhysical(dm, fit, options, base_globals, search.compliance_sigma, d, true);
    }
  }
  search.grams.reset();
  d.seconds_refit += secondsSince(clock);
}

// What the fit loses without global cause `effect`, in units of the residual variance: the model
// refitted without it (as the backward elimination does), the rise of the residual's squared
// norm. For a cause whose fit ended on a bound of its physics this, not the linearised χ², is its
// size: at a bound the χ² measures the estimate pressed onto it, not the fit it makes (seed 97 of
// the stress run: a lumped self weight with link 2's first moment at its reach, χ² 8.3 on 9
// directions, while the fit without it rises by ~100 times the variance). Under no cause both
// are χ² on the directions the data determine.
double lossWithout(const Search& search, size_t effect, const CauseSize& size) {
  const Diagnosis& d = search.d;
  size_t index = search.base_globals;
  for (size_t e = 0; e < effect; ++e) {
    if (d.effects[e].mechanism.kind != MechanismKind::kTransmissionError) ++index;
  }
  DiagnosisModel without = search.model;
  Diagnosis scratch = d;
  dropGlobal(without, index, d.effects[effect], search.starting_compliance);
  scratch.effects.erase(scratch.effects.begin() + static_cast<long>(effect));
  JointVector sigma = search.compliance_sigma;
  refitPhysical(without, search.fit, search.options, search.base_globals, sigma, scratch, true);
  if (!without.profiles.empty()) fitProfiles(without, search.fit);
  const double with_cost = residuals(search.model.combined(), search.fit).squaredNorm();
  const double without_cost = residuals(without.combined(), search.fit).squaredNorm();
  return (without_cost - with_cost) / size.variance;
}

// Whether data, not the code, left a named cause without a size: in the final fit what the data
// identify of it lies within one σ of zero (sizes.hpp), or, for a cause at a bound of its
// physics, the fit loses less than that without it (lossWithout). Such a cause is dropped, the
// weakest first, with a line in the verdict, and the model fitted again without it; the rest of
// the diagnosis stands.
void dropCausesWithoutSize(Search& search) {
  DiagnosisModel& dm = search.model;
  Diagnosis& d = search.d;
  for (;;) {
    std::vector<CauseSize> sizes =
        causeSizes(dm, search.fit, d, search.base_globals, search.base_profiles);
    size_t weakest = sizes.size();
    for (size_t e = 0; e < sizes.size(); ++e) {
      CauseSize& s = sizes[e];
      if (!s.hasSize() && s.on_bound && s.dof > 0 && s.variance > 0.0) {
        s.chi2 = lossWithout(search, e, s);
      }
      d.effects[e].size_chi2 = s.chi2;
      d.effects[e].size_dof = s.dof;
      if (s.hasSize()) continue;
      const auto ratio = [](const CauseSize& x) { return x.dof > 0 ? x.chi2 / x.dof : 0.0; };
      if (weakest == sizes.size() || ratio(s) < ratio(sizes[weakest])) weakest = e;
    }
    if (weakest == sizes.size()) return;
    ModelChange change;
    change.kind = ModelChange::Kind::kDroppedWithoutSize;
    change.mechanism = d.effects[weakest].mechanism;
    change.size_chi2 = sizes[weakest].chi2;
    change.size_dof = sizes[weakest].dof;
    d.changes.push_back(change);
    // Its index among the profiles or the global causes found, in the order found.
    size_t index = search.base_globals, profile = search.base_profiles;
    for (size_t e = 0; e < weakest; ++e) {
      (d.effects[e].mechanism.kind == MechanismKind::kTransmissionError ? profile : index)++;
    }
    if (d.effects[weakest].mechanism.kind == MechanismKind::kTransmissionError) {
      dm.profiles.erase(dm.profiles.begin() + static_cast<long>(profile));
    } else {
      dropGlobal(dm, index, d.effects[weakest], search.starting_compliance);
    }
    d.effects.erase(d.effects.begin() + static_cast<long>(weakest));
    finalFit(search);
  }
}

// Every effect's parameters and σ from the final fit, in the order found.
void storeFinalParameters(Search& search) {
  size_t next_global = search.base_globals, next_profile = search.base_profiles;
  for (FoundEffect& e : search.d.effects) {
    e.mechanism = e.mechanism.kind == MechanismKind::kTransmissionError
                      ? search.model.profiles[next_profile++].mechanism
                      : search.model.global.mechanisms[next_global++];
  }
}

}  // namespace

void refine(Search& search) {
  eliminateBackward(search);
  if (!search.model.profiles.empty()) {
    retuneProfiles(search);
    finalFit(search);
  } else if (!boundsHold(search.model)) {
    // The last round's joint step is linear: where it left a cause beyond its physics, the
    // global refit brings it back (without profiles nothing else refits it).
    refitPhysical(search.model, search.fit, search.options, search.base_globals,
                  search.compliance_sigma, search.d, true);
  }
  dropCausesWithoutSize(search);
  globalSigma(search.model, search.fit, search.compliance_sigma);
  storeFinalParameters(search);
}

}  // namespace stepcal::trainer::diagnosis
