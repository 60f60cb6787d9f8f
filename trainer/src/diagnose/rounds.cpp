// Rounds of screening (search.hpp): every family not in the model scored on held-out poses,
// the significant one chosen added, the model refitted, until nothing significant is left.
#include <chrono>
#include <cmath>
#include <limits>

#include "confounds.hpp"
#include "family_pairs.hpp"
#include "model_fits.hpp"
#include "modulated_stand_in.hpp"
#include "profile_load_check.hpp"
#include "scoring.hpp"
#include "search.hpp"

namespace stepcal::trainer::diagnosis {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A family that explained nearly as much as the one chosen (at least kRivalShare of its
// reduction of the held-out error) in the round it was chosen, and its reduction then.
constexpr double kRivalShare = 0.8;
struct Rival {
  Mechanism mechanism;
  double relative_reduction = 0.0;
};


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
// fit), a global mechanism (the caller refits the global part; the profiles then need a fit
// on what it leaves), or the part a joint's torque–deflection curve lacked (the curve replaces
// the mechanism it extends).
void addFamily(DiagnosisModel& model, const Scored& chosen) {
  const Family& family = *chosen.family;
  if (family.stage == Stage::kProfile) {
    Profile p;
    p.mechanism = chosen.score.mechanism;
    std::fill(p.mechanism.parameters.begin(), p.mechanism.parameters.end(), 0.0);
    p.ridge = chosen.lambda;
    model.profiles.push_back(std::move(p));
  } else {
    // From zero (what it adds): the first Gauss–Newton step is the linear fit.
    Mechanism m = family.mechanism;
    for (int j : family.compliance) model.compliance_free[static_cast<size_t>(j)] = true;
    if (m.kind == MechanismKind::kSelfWeight && family.free.empty()) model.masses_from_urdf = true;
    if (family.extends >= 0) {
      model.global.mechanisms[static_cast<size_t>(family.extends)] = std::move(m);
    } else {
      model.global.mechanisms.push_back(std::move(m));
    }
  }
}

}  // namespace

void searchRounds(Search& search) {
  const FitRows& fit = search.fit;
  const DiagnoseOptions& options = search.options;
  DiagnosisModel& dm = search.model;
  Diagnosis& d = search.d;
  Screening& sc = search.screening;
  std::unique_ptr<FoldGrams>& grams = search.grams;
  const Eigen::Index geometry = search.geometry;
  JointVector& compliance_sigma = search.compliance_sigma;
  auto clock = std::chrono::steady_clock::now();
  std::vector<Rival> rivals;  // of the effect named last
  for (int round = 1; round <= options.max_rounds; ++round) {
    clock = std::chrono::steady_clock::now();
    if (!grams) {
      buildScreening(dm, fit, options, search.body_masses, sc, grams, compliance_sigma);
      d.untestable = sc.untestable;  // what the model as it now stands cannot try
    } else {
      jointStep(dm, sc, *grams, fit, geometry, compliance_sigma);  // with the profile named last
    }
    const CrossValidation cv(*grams, fit, sc.stage1, sc.stage2, sc.ridge, sc.current);
    for (Family& family : sc.families) pruneNegativeCompliance(family, cv, sc.stage1.size(), dm);
    int tried = 0;  // configurations, for the family-wise level
    for (const Family& family : sc.families) tried += configurations(family, options);
    const auto passes = [&](double p_value, double relative_reduction) {
      return p_value < options.family_alpha / std::max(1, tried) &&
             relative_reduction >= options.min_relative_reduction;
    };
    const auto isSignificant = [&](const CandidateScore& s) {
      return s.physical && passes(s.p_value, s.relative_reduction);
    };
    std::vector<Scored> scored =
        scoreFamilies(sc.families, cv, sc.stage1.size(), *grams, options, fit, isSignificant);
    if (!d.effects.empty()) namePreviousAlternatives(scored, options, rivals, d.effects.back());
    for (Scored& s : scored) {
      s.score.round = round;
      s.score.significant = isSignificant(s.score);
      s.score.unbounded_significant =
          !s.score.impossible_unbounded.empty() &&
          passes(s.score.unbounded_p_value, s.score.unbounded_relative_reduction);
    }
    // A time-order family is named only where the rows tell it from what moves with its driver.
    testConfounds(scored, cv, isSignificant, round, d.drift.confound_tests);
    std::vector<size_t> significant;
    for (size_t k = 0; k < scored.size(); ++k) {
      if (scored[k].score.significant) significant.push_back(k);
    }
    setAsideLoadModulatedProfiles(scored, significant, cv, dm, options, round, d);
    setAsideModulatedStandIns(scored, significant, cv, options, isSignificant);
    d.seconds_screening += secondsSince(clock);
    if (significant.empty()) {
      for (Scored& s : scored) d.candidates.push_back(std::move(s.score));
      break;
    }
    const size_t chosen = choose(scored, significant);
    scored[chosen].score.chosen = true;
    // Whether the rows tell it from the others that explained the residual too.
    testFamilyPairs(scored, chosen, significant, cv, *grams, sc, passes, round, d.family_pairs);
    addFamily(dm, scored[chosen]);
    rivals.clear();
    if (scored[chosen].family->extends >= 0) {
      // The joint's curve, found in an earlier round, gains a part: no new effect.
      clock = std::chrono::steady_clock::now();
      refitPhysical(dm, fit, options, search.base_globals, compliance_sigma, d, true);
      d.seconds_refit += secondsSince(clock);
      grams.reset();
      for (Scored& s : scored) d.candidates.push_back(std::move(s.score));
      continue;
    }
    FoundEffect effect;
    effect.round = round;
    effect.cv_gain_mm = scored[chosen].score.cv_gain_mm;
    effect.z_statistic = scored[chosen].score.z_statistic;
    effect.p_value = scored[chosen].score.p_value;
    effect.ridge = scored[chosen].score.ridge;
    effect.compliance_joints = scored[chosen].family->compliance;
    effect.mechanism = scored[chosen].score.mechanism;
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
      refitPhysical(dm, fit, options, search.base_globals, compliance_sigma, d, true);
      d.seconds_refit += secondsSince(clock);
      grams.reset();
    }
    for (Scored& s : scored) d.candidates.push_back(std::move(s.score));
  }
}

}  // namespace stepcal::trainer::diagnosis
