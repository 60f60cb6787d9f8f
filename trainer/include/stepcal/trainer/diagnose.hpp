// Diagnosis: what the physical model (geometry + compliance) gets wrong, which catalogued
// mechanism (mechanisms.hpp) explains it, and how much the extended model gains.
//
// 1. The physical model is refitted jointly on every fit row (geometry δ, compliances, the
//    mechanisms found so far; Gauss–Newton, truncated SVD). Its residual is compared with the
//    tracker noise and tested for trends in q_j, τ_j, load, temperature and seq.
// 2. Every candidate (each mechanism on each joint, each harmonic, each coupling) is added to the
//    linearised model and judged by cross-validation over poses (folds by pose_id): the held-out
//    squared error per pose, noise-weighted, with and without it. A one-sided t-test on the
//    per-pose reductions, Bonferroni-corrected over the round's candidates, keeps chance from
//    naming a cause. The most significant is added and everything refitted; repeat.
// 3. Verdict: found (the causes with parameters and 1-σ), none (nothing significant and the
//    residual at the noise level), unexplained (significant structure no mechanism explains).
// 4. The extended model (with a GPR refitted on its residual) and its gain on validation rows.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/mechanisms.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::trainer {

struct DiagnoseOptions {
  int folds = 5;                ///< cross-validation folds over poses
  int max_harmonic = 8;         ///< transmission_error candidates k = 1 … max_harmonic
  int max_mechanisms = 4;       ///< rounds of "add the best, refit"
  double family_alpha = 0.01;   ///< false-positive rate per round, all candidates together
  /// A cause must also remove at least this fraction of the held-out noise-weighted squared
  /// error: significant in practice, not only statistically (tiny, consistent misfits of the
  /// model otherwise accumulate as spurious causes).
  double min_relative_reduction = 0.01;
  int refit_iterations = 12;    ///< Gauss–Newton iterations of a joint refit
  /// A residual this many times the stated tracker noise (RMS of noise-weighted entries) counts
  /// as unexplained even when it follows no tested variable.
  double noise_ratio_limit = 1.3;
  CalibrationOptions calibration;  ///< GPR options of the extended model's step 3
};

enum class Verdict { kFound, kNone, kUnexplained };
/// "found", "none" or "unexplained".
const char* toString(Verdict verdict) noexcept;

/// One candidate of one round, scored on held-out poses.
struct CandidateScore {
  Mechanism mechanism;       ///< parameters fitted on all fit rows (linearised), SI
  int round = 1;
  double cv_gain_mm = 0.0;   ///< held-out mean position error without minus with it, mm
  double relative_reduction = 0.0;  ///< fraction of the held-out squared error it removes
  double t_statistic = 0.0;  ///< of the per-pose reduction of the noise-weighted squared error
  double p_value = 1.0;      ///< one-sided, normal approximation
  bool significant = false;  ///< p < family_alpha / (candidates in the round), enough removed
  bool chosen = false;
};

/// A candidate that could not be tried on this campaign, and why.
struct UntestableCandidate {
  std::string name;
  std::string reason;
};

/// A named cause, in the order found.
struct FoundEffect {
  Mechanism mechanism;  ///< parameters and 1-σ from the final joint refit
  int round = 1;
  double cv_gain_mm = 0.0, t_statistic = 0.0, p_value = 1.0;
};

/// A cross-validated trend of the residual in one variable (cubic in the variable).
struct TrendScore {
  std::string variable;      ///< e.g. "q2_deg", "tau3_nm", "load_kg", "temp_c", "seq"
  double cv_gain_mm = 0.0;   ///< held-out mean position error removed by the trend, mm
  double t_statistic = 0.0, p_value = 1.0;
  bool significant = false;  ///< Bonferroni over the variables tested
};

/// What a physical model gets wrong on the fit rows.
struct ResidualStatistics {
  int rows = 0;
  double mean_position_m = 0.0, rms_position_m = 0.0, max_position_m = 0.0;
  double rms_orientation_rad = 0.0;   ///< over rows with orientation
  double noise_ratio = 0.0;           ///< RMS of the noise-weighted entries: 1 = tracker noise
  std::vector<TrendScore> trends;     ///< most significant first
  std::vector<double> position_error_m;  ///< per fit row, for plots
};

/// Accuracy on one validation load: physical model before and after, and the GPR references.
struct GainRow {
  double load_kg = 0.0;
  int rows = 0;
  AccuracySummary before, after, gpr, after_gpr;
};

struct Diagnosis {
  Verdict verdict = Verdict::kNone;
  std::vector<FoundEffect> effects;
  std::vector<CandidateScore> candidates;  ///< every round's, in order
  std::vector<UntestableCandidate> untestable;
  ResidualStatistics before, after;        ///< of the joint refit without / with the effects
  std::string unexplained_trend;           ///< verdict unexplained: what the residual follows
  std::vector<GainRow> gain;               ///< per validation load
  std::string gpr_method;                  ///< the GPR reference, e.g. "poe+stiffness+gpr"
  double floor_position_m = 0.0;           ///< mean error the tracker noise alone gives
  CalibratedModel extended_model;          ///< the model with the effects and its GPR
  /// Fit-row variables for plots: names (trend variables) and values (row-major, per fit row).
  std::vector<std::string> variable_names;
  std::vector<std::vector<double>> variable_values;
  int fit_rows = 0, fit_poses = 0, validation_rows = 0, folds = 0;
  double seconds_refit = 0.0, seconds_screening = 0.0, seconds_trends = 0.0,
         seconds_gpr = 0.0, seconds_evaluation = 0.0;  ///< wall time of each part
};

/// Diagnoses a campaign against a calibrated model (its chain, compliance and mechanisms are
/// the starting point; its GPR, if any, is the reference of the gain table). Throws InputError
/// when the campaign does not fit the model or has too few fit poses for the folds.
Diagnosis diagnose(const Campaign& campaign, const CalibratedModel& model,
                   const DiagnoseOptions& options = {});

}  // namespace stepcal::trainer
