// Human-readable and JSON renderings of a calibration outcome (mm and degrees).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/trainer/plan.hpp"

namespace stepcal::report {

/// What session k of a merged campaign fitted, against the first session.
struct SessionSummary {
  Pose X_TrackerBase;  ///< base_link in its tracker as fitted (joint 1's frame error folded in), m
  double tool_offset_m = 0.0, tool_angle_rad = 0.0;  ///< its tool against session 1's
};
SessionSummary sessionSummary(const trainer::CalibrationOutcome& outcome, size_t k);

/// The accuracy tables and step reports as text.
std::string formatReport(const Campaign& campaign, const trainer::CalibrationOutcome& outcome);

/// The same as JSON: `validation` → [{method, load_kg, rows, mean_position_mm, max_position_mm,
/// mean_orientation_deg}], `stiffness_nm_per_rad` → [{joint, identified, stiffness_nm_per_rad,
/// sigma_nm_per_rad, max_torque_nm}], `stiffness_validation` → [{load_kg, pairs,
/// mean_deviation_pct, max_deviation_pct}], `gpr`, plus `fit`, `noise_floor`, `geometry`.
nlohmann::json reportJson(const Campaign& campaign, const trainer::CalibrationOutcome& outcome);

/// What a model file holds, for people: chain, registration, compliances, GPR, provenance.
std::string formatModel(const CalibratedModel& model, size_t file_bytes);

/// One line of a model's validation figures: method, load, rows, mean / max position (mm) and
/// mean orientation (deg), indented, with its newline.
std::string formatValidationFigure(const ValidationFigure& figure);

/// Accuracy table (rows = set and load, columns = methods) as text.
std::string formatAccuracyTable(const std::vector<trainer::AccuracySummary>& summaries);

/// Accuracy summaries as a JSON list.
nlohmann::json accuracyJson(const std::vector<trainer::AccuracySummary>& summaries);

/// What a plan found: candidates kept and why others were not, its information and the
/// selected poses' coverage of every joint's range.
std::string formatPlan(const trainer::CampaignPlan& plan, const trainer::PlanOptions& options);

}  // namespace stepcal::report
