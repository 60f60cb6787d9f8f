// stepcal::trainer::diagnose: rounds of screening and refitting (diagnose.hpp), then the verdict,
// the extended model and its gain.
#include "stepcal/trainer/diagnose.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>

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
  s.score.t_statistic = cmp.t;
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

// A profile family over the grid of orders and ridges: the best ridge per order by held-out
// squared error, then the lowest order not significantly worse than the best (paired t < 2).
Scored scoreProfile(const Family& family, const CrossValidation& cv,
                    const CrossValidation::Outcome& base, const FoldGrams& grams,
                    const DiagnoseOptions& options) {
  const CrossValidation::ProfileCandidate prepared = cv.prepareProfile(family.columns);
  double mean_diag = 0.0;
  for (Eigen::Index c : family.columns) mean_diag += grams.scale(c) * grams.scale(c);
  mean_diag /= static_cast<double>(family.columns.size());
  std::vector<int> orders = options.profile_orders;
  std::sort(orders.begin(), orders.end());
  struct PerOrder {
    int order;
    double rho, lambda;
    CrossValidation::Correction correction;
  };
  std::vector<PerOrder> best;
  for (int order : orders) {
    if (2 * order > static_cast<int>(family.columns.size())) continue;
    PerOrder p{order, 0.0, 0.0, {}};
    bool first = true;
    for (double rho : options.profile_ridges) {
      CrossValidation::Correction c = cv.withProfile(prepared, 2 * order, rho * mean_diag);
      if (first || c.sse < p.correction.sse) {
        p = {order, rho, rho * mean_diag, std::move(c)};
        first = false;
      }
    }
    best.push_back(std::move(p));
  }
  size_t top = 0;
  for (size_t i = 1; i < best.size(); ++i) {
    if (best[i].correction.sse < best[top].correction.sse) top = i;
  }
  const CrossValidation::Outcome top_outcome = cv.heldOut(best[top].correction);
  size_t chosen = top;
  CrossValidation::Outcome chosen_outcome = top_outcome;
  for (size_t i = 0; i < top; ++i) {
    CrossValidation::Outcome o = cv.heldOut(best[i].correction);
    if (pairedT(o.pose_sse, top_outcome.pose_sse) < 2.0) {
      chosen = i;
      chosen_outcome = std::move(o);
      break;
    }
  }
  const int order = best[chosen].order;
  Scored s;
  s.family = &family;
  s.outcome = std::move(chosen_outcome);
  s.lambda = best[chosen].lambda;
  Mechanism m = family.mechanism;
  m.order = order;
  m.parameters.assign(static_cast<size_t>(2 * order), 0.0);
  m.sigma.assign(m.parameters.size(), 0.0);
  const Eigen::VectorXd& x = best[chosen].correction.x.back();
  for (int i = 0; i < 2 * order; ++i) {
    m.parameters[static_cast<size_t>(i)] = x(x.size() - 2 * order + i);
  }
  s.score.mechanism = std::move(m);
  s.score.ridge = best[chosen].rho;
  s.score.configurations = static_cast<int>(best.size() * options.profile_ridges.size());
  const Comparison cmp = compare(base, s.outcome);
  s.score.cv_gain_mm = cmp.gain_mm;
  s.score.relative_reduction = cmp.relative_reduction;
  s.score.t_statistic = cmp.t;
  s.score.p_value = cmp.p;
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
    if (pairedT(scored[k].outcome.pose_sse, scored[best].outcome.pose_sse) < 2.0) chosen = k;
  }
  return chosen;
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
                   size_t base_globals, JointVector& compliance_sigma, Diagnosis& d) {
  for (;;) {
    refitGlobal(model, fit, options.refit_iterations, compliance_sigma);
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
    // Its effect: the (dropped − base_globals)-th global one in the order found.
    size_t global_index = 0;
    for (auto e = d.effects.begin(); e != d.effects.end(); ++e) {
      if (e->mechanism.kind == MechanismKind::kTransmissionError) continue;
      if (global_index++ == dropped - base_globals) {
        d.effects.erase(e);
        break;
      }
    }
    model.global.mechanisms.erase(model.global.mechanisms.begin() + static_cast<long>(dropped));
  }
}

// The profiles' coefficients and σ from stage 2 fitted on every row (stage-2 columns are the
// profiles' in model order). Exact for the linearised model: a profile moves the link angles by
// ~1e-3 rad, so the Jacobian's change it causes is far below the noise.
void storeProfiles(DiagnosisModel& model, const CrossValidation& cv) {
  const CrossValidation::Stage2 s = cv.stage2OnAllRows();
  Eigen::Index at = 0;
  for (Profile& p : model.profiles) {
    for (size_t i = 0; i < p.mechanism.parameters.size(); ++i) {
      p.mechanism.parameters[i] = s.x(at);
      p.mechanism.sigma[i] = s.sigma(at);
      ++at;
    }
  }
  STEPCAL_INVARIANT(at == s.x.size(), "stage 2 holds every profile's columns");
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
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) {
    if (row.q_rad.size() != n) {
      throw InputError("row has " + std::to_string(row.q_rad.size()) +
                           " joint angles but the model's chain has " + std::to_string(n),
                       campaign.measurements_file, row.source_line);
    }
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
  for (const Mechanism& m : model.mechanisms) {
    if (m.kind != MechanismKind::kTransmissionError) {
      dm.global.mechanisms.push_back(m);
      dm.masses_from_urdf = dm.masses_from_urdf ||
                            (m.kind == MechanismKind::kSelfWeight && body_masses &&
                             m.parameters == *body_masses);
    } else {
      dm.profiles.push_back({m, 0.0});
    }
  }
  for (int j = 0; j < n; ++j) dm.compliance_free.push_back(dm.global.compliance_rad_per_nm(j) > 0.0);
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

  // 2. Families, round by round. The screening (columns and their per-fold Grams) is rebuilt only
  // when the global model changes: a profile added changes none of it, it only joins stage 2.
  const size_t base_globals = dm.global.mechanisms.size(), base_profiles = dm.profiles.size();
  RoundStart start;
  Screening sc;
  std::unique_ptr<FoldGrams> grams;
  for (int round = 1; round <= options.max_rounds; ++round) {
    clock = std::chrono::steady_clock::now();
    const bool rebuilt = !grams;
    if (rebuilt) {
      start.global = evaluate(dm.global, fit);
      start.linear = linearise(dm.global, fit, start.global.r);
      sc = screening(dm, fit, start, options, body_masses);
      if (round == 1) d.untestable = sc.untestable;
      grams = std::make_unique<FoldGrams>(std::move(sc.A), start.global.r, fit);
      sc.A.resize(0, 0);
    }
    const CrossValidation cv(*grams, start.global.r, fit, sc.stage1, sc.stage2, sc.ridge);
    if (rebuilt) storeProfiles(dm, cv);  // on what the new global model leaves
    const CrossValidation::Outcome base = cv.heldOut(cv.base());
    for (Family& family : sc.families) pruneNegativeCompliance(family, cv, sc.stage1.size(), dm);
    std::vector<Scored> scored(sc.families.size());
    parallelFor(sc.families.size(), [&](size_t k) {
      const Family& family = sc.families[k];
      scored[k] = family.stage == Stage::kGlobal
                      ? scoreGlobal(family, cv, base, sc.stage1.size())
                      : scoreProfile(family, cv, base, *grams, options);
    });
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
    effect.t_statistic = scored[chosen].score.t_statistic;
    effect.p_value = scored[chosen].score.p_value;
    effect.ridge = scored[chosen].score.ridge;
    effect.compliance_joints = scored[chosen].family->compliance;
    effect.mechanism = scored[chosen].score.mechanism;
    for (size_t k : significant) {
      if (k != chosen && std::abs(pairedT(scored[k].outcome.pose_sse,
                                          scored[chosen].outcome.pose_sse)) < 2.0) {
        effect.alternatives.push_back(scored[k].score.mechanism);
      }
    }
    d.effects.push_back(std::move(effect));
    const Family& family = *scored[chosen].family;
    if (family.stage == Stage::kProfile) {
      // Its leading 2·order columns join stage 2 with its ridge; the other families stay.
      for (int c = 0; c < 2 * scored[chosen].score.mechanism.order; ++c) {
        sc.stage2.push_back(family.columns[static_cast<size_t>(c)]);
        sc.ridge(family.columns[static_cast<size_t>(c)]) = scored[chosen].lambda;
      }
      sc.families.erase(sc.families.begin() + static_cast<long>(&family - sc.families.data()));
      storeProfiles(dm, CrossValidation(*grams, start.global.r, fit, sc.stage1, sc.stage2, sc.ridge));
    } else {
      clock = std::chrono::steady_clock::now();
      refitPhysical(dm, fit, options, base_globals, compliance_sigma, d);
      d.seconds_refit += secondsSince(clock);
      grams.reset();
    }
    for (Scored& s : scored) d.candidates.push_back(std::move(s.score));
  }
  if (!grams) fitProfiles(dm, fit);  // the last round changed the global model

  // Every effect's parameters and σ from the final fit, in the order found.
  {
    size_t next_global = base_globals, next_profile = base_profiles;
    for (FoundEffect& e : d.effects) {
      if (e.mechanism.kind == MechanismKind::kTransmissionError) {
        e.mechanism = dm.profiles[next_profile++].mechanism;
      } else {
        e.mechanism = dm.global.mechanisms[next_global++];
      }
    }
  }
  const PhysicalModel extended_physical = dm.combined();

  // Identifiability of what was found.
  for (const FoundEffect& f : d.effects) {
    for (const Mechanism& other : f.alternatives) {
      d.identifiability.push_back(describe(f.mechanism) + " and " + describe(other) +
                                  " explain the held-out poses equally well (paired |t| < 2): "
                                  "these rows cannot tell them apart; the first was named");
    }
  }
  {
    const Evaluation e = evaluate(dm.global, fit);
    const Linearisation lin = linearise(dm.global, fit, e.r);
    for (FoundEffect& f : d.effects) {
      const Mechanism& m = f.mechanism;
      if (m.kind == MechanismKind::kTransmissionError) {
        f.rms_rad = profileRms(m, fit);
        double largest = 0.0;
        for (int k = 0; k < m.order; ++k) {
          largest = std::max(largest, std::hypot(m.parameters[static_cast<size_t>(2 * k)],
                                                 m.parameters[static_cast<size_t>(2 * k + 1)]));
        }
        f.harmonics_separable = largest <= 3.0 * f.rms_rad;
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
        for (size_t k = 0; k < f.geometry_share.size(); ++k) {
          if (f.geometry_share[k] < 0.5) continue;
          d.identifiability.push_back(
              describe(m) + ": harmonic " + std::to_string(k + 1) + " is " +
              percent(f.geometry_share[k]) +
              " within reach of a geometric error (a tilt, offset or eccentricity of the joint); "
              "the geometry was fitted first, so the profile carries only what it cannot explain");
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
