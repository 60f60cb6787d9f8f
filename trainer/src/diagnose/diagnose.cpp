// stepcal::trainer::diagnose (diagnose.hpp): the starting model, the phases of search.hpp in
// order, and the verdict.
#include "stepcal/common/units.hpp"
#include "stepcal/trainer/diagnose.hpp"

#include <chrono>

#include "model_fits.hpp"
#include "profiles.hpp"
#include "residual_statistics.hpp"
#include "search.hpp"
#include "session_frames.hpp"
#include "unexplained.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal::trainer {
namespace {

using namespace diagnosis;

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The campaign's fit rows: every row outside set=validation.
std::vector<const Measurement*> fitRowsOf(const Campaign& campaign) {
  std::vector<const Measurement*> rows;
  for (const Measurement& row : campaign.rows) {
    if (row.set != RowSet::kValidation) rows.push_back(&row);
  }
  return rows;
}

/// Throws when the fit rows hold too few poses for options.folds-fold cross-validation.
void requireEnoughPoses(const FitRows& fit, const DiagnoseOptions& options,
                        const Campaign& campaign) {
  if (fit.poses < 4 * options.folds) {
    throw InputError("diagnosis needs at least " + std::to_string(4 * options.folds) +
                         " fit poses (distinct pose_id outside set=validation) for " +
                         std::to_string(options.folds) + "-fold cross-validation, got " +
                         std::to_string(fit.poses),
                     campaign.directory + "/" + campaign.measurements_file);
  }
}

/// The campaign URDF's link masses and first moments, if it has them.
std::optional<std::vector<double>> urdfBodyMasses(const Campaign& campaign) {
  return bodyMassesFromUrdf(campaign.urdf_xml, campaign.base_link, campaign.tip_link,
                            campaign.directory.empty()
                                ? campaign.robot_file
                                : campaign.directory + "/" + campaign.robot_file);
}

/// The starting model: the given model's global part, and its profiles to be refitted.
void startFromGivenModel(Search& search, const CalibratedModel& model,
                         const std::vector<const Measurement*>& rows) {
  const std::optional<std::vector<double>>& body_masses = search.body_masses;
  const DiagnoseOptions& options = search.options;
  DiagnosisModel& dm = search.model;
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
    p.mechanism.coverage = coverageOfAngles(angles, options.coverage_gap_deg * kRadPerDeg,
                                            options.coverage_fade_deg * kRadPerDeg);
    dm.profiles.push_back(std::move(p));
  }
}

/// Several campaigns: each later one's own tracker station and tool as the given model places
/// it, then fitted with the rest.
void addStartingSessionFrames(Search& search, const Campaign& campaign,
                              const CalibratedModel& model,
                              const std::vector<const Measurement*>& rows) {
  const int sessions = campaign.sessionCount();
  std::vector<std::string> directories;
  for (int s = 0; s < sessions; ++s) directories.push_back(campaign.directoryOf(s));
  search.starting_frames =
      startingSessionFrames(physicalModelOf(model), rows, sessions, campaign.tracker, directories);
  DiagnosisModel& dm = search.model;
  dm.global.mechanisms.insert(dm.global.mechanisms.end(), search.starting_frames.begin(),
                              search.starting_frames.end());
}

/// The starting model's fitted compliances, and its profiles' ridge (the middle of the grid).
void startComplianceAndRidges(Search& search, int n) {
  DiagnosisModel& dm = search.model;
  for (int j = 0; j < n; ++j) {
    dm.compliance_free.push_back(dm.global.compliance_rad_per_nm(j) > 0.0);
  }
  search.starting_compliance = dm.compliance_free;
  if (!dm.profiles.empty()) {
    const DiagnoseOptions& options = search.options;
    const Eigen::VectorXd r = residuals(dm.global, search.fit);
    const double rho = options.profile_ridges[options.profile_ridges.size() / 2];
    for (Profile& p : dm.profiles) {
      p.ridge = rho * profileRidgeScale(dm.global, r, p.mechanism, search.fit);
    }
  }
}

/// Phase 1: the starting model refitted jointly on the fit rows (the given model's compliance
/// prior, if it has one).
void refitStartingModel(Search& search, const CalibratedModel& model, int n) {
  const auto clock = std::chrono::steady_clock::now();
  DiagnosisModel& dm = search.model;
  search.compliance_sigma = model.compliance_sigma_rad_per_nm.size() == n
                                ? model.compliance_sigma_rad_per_nm
                                : JointVector(JointVector::Zero(n));
  refitPhysical(dm, search.fit, search.options, dm.global.mechanisms.size(),
                search.compliance_sigma, search.d);
  fitProfiles(dm, search.fit);
  search.d.seconds_refit += secondsSince(clock);
}

/// Phase 1: what the refitted model gets wrong, its trends and, with several campaigns, each
/// one's mean error.
void trendsBefore(Search& search, const Campaign& campaign,
                  const std::vector<const Measurement*>& rows, int n) {
  const auto clock = std::chrono::steady_clock::now();
  Diagnosis& d = search.d;
  const FitRows& fit = search.fit;
  const int sessions = campaign.sessionCount();
  const Evaluation e = evaluate(search.model.combined(), fit);
  const Variables variables = trendVariables(fit, e.tau_nm, n);
  d.variable_names = variables.names;
  d.variable_values = variables.values;
  d.before = statistics(e.r, fit, variables, search.options.family_alpha);
  if (sessions > 1) {
    const std::vector<double> mean = sessionMeanErrors(e.r, fit, sessions);
    for (int s = 0; s < sessions; ++s) {
      DiagnosedCampaign c;
      c.directory = campaign.directoryOf(s);
      c.before_mean_m = mean[static_cast<size_t>(s)];
      for (const Measurement* row : rows) c.fit_rows += row->session == s ? 1 : 0;
      d.campaigns.push_back(std::move(c));
    }
  }
  d.seconds_trends += secondsSince(clock);
}

/// Phase 3: the trends the extended model leaves and, with several campaigns, each one's mean
/// error and fitted station and tool.
void trendsAfter(Search& search, const PhysicalModel& extended_physical, int sessions, int n) {
  const auto clock = std::chrono::steady_clock::now();
  Diagnosis& d = search.d;
  const FitRows& fit = search.fit;
  const Evaluation e = evaluate(extended_physical, fit);
  d.after = statistics(e.r, fit, trendVariables(fit, e.tau_nm, n), search.options.family_alpha);
  if (sessions > 1) {
    const std::vector<double> mean = sessionMeanErrors(e.r, fit, sessions);
    for (int s = 0; s < sessions; ++s) {
      d.campaigns[static_cast<size_t>(s)].after_mean_m = mean[static_cast<size_t>(s)];
    }
    for (const Mechanism& m : extended_physical.mechanisms) {
      if (m.kind == MechanismKind::kSessionFrames) {
        d.campaigns[static_cast<size_t>(m.order)].frames = m;
      }
    }
  }
  d.seconds_trends += secondsSince(clock);
}

/// Phase 3: found (effects), unexplained (a trend left above the noise) or none.
void giveVerdict(Diagnosis& d, const DiagnoseOptions& options) {
  const std::string remaining = trendSummary(d.after, options.noise_ratio_limit);
  if (!d.effects.empty()) {
    d.verdict = Verdict::kFound;
    d.unexplained_trend = remaining;
  } else if (!remaining.empty()) {
    d.verdict = Verdict::kUnexplained;
    d.unexplained_trend = remaining;
  }
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
  requireCampaignOfModelRobot(model, campaign, "");
  requireJointCount(campaign, n);
  const std::vector<const Measurement*> rows = fitRowsOf(campaign);
  const FitRows fit = makeFitRows(rows, campaign.tracker, options.folds);
  requireEnoughPoses(fit, options, campaign);
  d.fit_rows = static_cast<int>(rows.size());
  d.fit_poses = fit.poses;
  d.folds = options.folds;
  Search search(fit, options, urdfBodyMasses(campaign), d);

  startFromGivenModel(search, model, rows);
  addStartingSessionFrames(search, campaign, model, rows);
  startComplianceAndRidges(search, n);

  // 1. The model refitted jointly; what it gets wrong.
  refitStartingModel(search, model, n);
  trendsBefore(search, campaign, rows, n);

  // 2. Families, round by round; then the model refined and its effects described.
  search.base_globals = search.model.global.mechanisms.size();
  search.base_profiles = search.model.profiles.size();
  search.geometry = 6 * (n + 1);
  searchRounds(search);
  refine(search);
  describeEffects(search);
  const PhysicalModel extended_physical = search.model.combined();

  // 3. Verdict.
  trendsAfter(search, extended_physical, campaign.sessionCount(), n);
  judgeDrift(search);
  judgeCampaignProfiles(search);
  giveVerdict(d, options);

  // 4. The extended model with its GPR, the gain on validation rows, and what it leaves.
  extendAndEvaluate(campaign, model, extended_physical, search);
  judgeUnexplained(search, extended_physical, campaign.tracker);
  return d;
}

}  // namespace stepcal::trainer
