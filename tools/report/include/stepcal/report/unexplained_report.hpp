// The verdict's "unexplained" part (trainer::UnexplainedPart) as text, JSON and an HTML section,
// and calibrate's one line when its model's residual stands far above the tracker noise.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"

namespace stepcal::report {

/// The text report's lines: the part's sentences, then the variables it follows (the
/// significant ones, at most 8, and the time order), each with its held-out gain and z.
std::string unexplainedText(const trainer::UnexplainedPart& unexplained);

/// `unexplained`: {any, residual_mm, residual_rows, floor_mm, ratio, noise_stated,
/// variables_tested, variables → [{name, description, joint (1-based, null for none),
/// perpendicular_moment, cv_gain_mm, relative_reduction, z, p_value, significant}] (the
/// significant ones, then load_kg, temp_c and seq whatever their score), learner_features,
/// learner_gain_mm, learner_relative_reduction, learner_z, learner_significant, text}.
nlohmann::json unexplainedJson(const trainer::UnexplainedPart& unexplained);

/// The HTML report's section (id "unexplained"): the sentences and a table of the variables
/// tested, strongest first (the significant ones and the next few), with bars of their gain.
std::string unexplainedSection(const trainer::UnexplainedPart& unexplained);

/// A calibrated model whose mean position error on the validation rows (its final layer: the
/// GPR when taken, else the physical model) is above this many times the tracker-noise floor
/// stands far above the noise.
inline constexpr double kResidualNoteRatio = 3.0;

/// calibrate's one line (no newline) when its model stands far above the noise, pointing to
/// `stepcal diagnose`; empty when it does not, when the campaign has no validation rows, or when
/// it states no tracker noise (its floor is then an assumption, nothing to judge against).
std::string residualNote(const Campaign& campaign, const trainer::CalibrationOutcome& outcome);

}  // namespace stepcal::report
