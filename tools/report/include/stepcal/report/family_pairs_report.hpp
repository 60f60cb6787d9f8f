// The diagnosis's pairs of families (trainer::FamilyPairTest) as text, JSON and an HTML section;
// and the geometry pin of the extended model (trainer::GeometryPin) the same three ways.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/trainer/diagnose.hpp"

namespace stepcal::report {

/// The verdict's sentences, one per pair the rows cannot tell apart whose chosen family is a
/// named effect, e.g. "joint_coupling (joint 2 -> joint 3) and nonlinear_stiffness (joint 2),
/// round 2: their columns correlate at ρ = 0.98 (variance inflation 25); beside each other
/// neither adds (z 0.4, 0.2 % held out; z 1.1, 0.5 %): the rows cannot say which, the first
/// named stands for either".
std::vector<std::string> familyPairLines(const trainer::Diagnosis& d);

/// `family_pairs`: every pair tested, [{chosen, other: {name, joint (1-based, null)}, named (the
/// chosen is an effect of the verdict), round, canonical_correlation, variance_inflation (null:
/// infinite), chosen_beside_other, other_beside_chosen: {cv_gain_mm, relative_reduction,
/// z_statistic, p_value, significant}, told_apart}].
nlohmann::json familyPairsJson(const trainer::Diagnosis& d);

/// The HTML report's section (id "pairs"): a table of every pair tested; empty when none was.
std::string familyPairsSection(const trainer::Diagnosis& d);

/// The verdict's sentence on the extended model's geometry, e.g. "pinned by the 300 unloaded fit
/// rows: they reject the global fit's geometry (F = 12.0 on 30 directions, above 3), so the
/// extended model's geometry is theirs; it moves the tip by 0.031 mm RMS (0.085 most) over the
/// fit rows"; empty when not tested.
std::string geometryPinText(const trainer::GeometryPin& pin);

/// `geometry_pin`: {tested, pinned, unloaded_rows, rank, f_statistic, f_limit,
/// tip_shift_rms_mm, tip_shift_max_mm, text}.
nlohmann::json geometryPinJson(const trainer::GeometryPin& pin);

}  // namespace stepcal::report
