// One diagnosis in progress and its phases, in the order diagnose() runs them (internal to
// stepcal::trainer):
//   rounds.cpp    screen every family, add the significant one, refit, until none is left;
//   refine.cpp    backward elimination, each profile's order and ridge chosen again, the final
//                 joint fits, and the causes the final fit leaves without a size dropped;
//   effects.cpp   what each found effect is on the fit rows (its RMS, its share of the geometry,
//                 the torques it was identified over, the joints its self weight identifies);
//   campaign_profiles.cpp  with several campaigns, whether one profile serves them all;
//   drift.cpp     what drifted in time and temperature, and what the rows tell apart;
//   gain.cpp      the extended model with its GPR, and its gain on the validation rows.
// Each phase reads and changes the Search; what it finds goes into the Diagnosis as structured
// results (the words are the report's: tools/report/src/diagnosis_report.cpp).
#pragma once

#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "candidates.hpp"
#include "cross_validation.hpp"
#include "fit_rows.hpp"
#include "model.hpp"
#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::trainer::diagnosis {

struct Search {
  Search(const FitRows& fit_rows, const DiagnoseOptions& diagnose_options,
         std::optional<std::vector<double>> urdf_masses, Diagnosis& diagnosis)
      : fit(fit_rows), options(diagnose_options), body_masses(std::move(urdf_masses)), d(diagnosis) {}

  const FitRows& fit;
  const DiagnoseOptions& options;
  /// The URDF's link masses and first moments (bodyMassesFromUrdf), if it has them.
  std::optional<std::vector<double>> body_masses;
  Diagnosis& d;

  DiagnosisModel model;
  JointVector compliance_sigma;          ///< n entries, rad/(N·m)
  std::vector<bool> starting_compliance;  ///< per joint: fitted in the starting model
  /// Per later campaign, its station and tool as the given model places them (session_frames).
  std::vector<Mechanism> starting_frames;
  /// The starting model's global mechanisms and profiles come first; the causes found follow.
  size_t base_globals = 0, base_profiles = 0;
  Eigen::Index geometry = 0;  ///< 6(n+1) initial-pose corrections
  /// The screening at the model as it stands and its Grams (null: to be rebuilt).
  Screening screening;
  std::unique_ptr<FoldGrams> grams;
};

/// Rounds of screening: each adds the significant family chosen (physical constants first) and
/// refits, until no family is significant or options.max_rounds is reached.
void searchRounds(Search& s);

/// Backward elimination, each profile's order and ridge chosen again, the final joint fits, every
/// effect's parameters and σ from them, and the causes left without a size in the final fit
/// dropped (with a ModelChange each).
void refine(Search& s);

/// What each found effect is on the fit rows, for the verdict: a profile's RMS, separability and
/// share of the geometry, a torque-driven mechanism's torque range, self weight's identified
/// joints and the gravity torque spread of the others.
void describeEffects(Search& s);

/// With several campaigns: per later campaign, whether each profile serves it as it serves the
/// first (DiagnosedCampaign::profile_differences), the model left as it is.
void judgeCampaignProfiles(Search& s);

/// What drifted (DriftVerdict): the drift effects found, the candidates of the last round, each
/// time-order family's standing confound test (the rounds ran them, confounds.hpp), what moves
/// with the time order, and the trends left, in sentences.
void judgeDrift(Search& s);

/// The extended model (the starting model with the found physical model and a GPR on its
/// residual) and its gain on the campaign's validation rows.
void extendAndEvaluate(const Campaign& campaign, const CalibratedModel& model,
                       const PhysicalModel& extended, Search& s);

}  // namespace stepcal::trainer::diagnosis
