#include "stepcal/report/unexplained_report.hpp"

#include <algorithm>

#include "stepcal/common/units.hpp"
#include "stepcal/report/html/page.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

// Variables the JSON and the table show whatever their score: what a drift or a load follows.
bool isReference(const trainer::UnexplainedVariable& v) {
  return v.name == "load_kg" || v.name == "temp_c" || v.name == "seq";
}

std::string variableLine(const trainer::UnexplainedVariable& v) {
  return format("    %-28s gain %8.4f mm  removes %5.1f %%  z %6.1f  %s  (%s)\n", v.name.c_str(),
                v.cv_gain_mm, 100.0 * v.relative_reduction, v.z_statistic,
                v.significant ? "significant" : "           ", v.description.c_str());
}

}  // namespace

std::string unexplainedText(const trainer::UnexplainedPart& u) {
  constexpr int kListed = 8;
  std::string out = "  unexplained: " + u.text + "\n";
  int listed = 0;
  for (const trainer::UnexplainedVariable& v : u.variables) {
    if ((v.significant && listed < kListed) || v.name == "seq") {
      out += variableLine(v);
      listed += v.significant ? 1 : 0;
    }
  }
  return out;
}

nlohmann::json unexplainedJson(const trainer::UnexplainedPart& u) {
  nlohmann::json variables = nlohmann::json::array();
  for (const trainer::UnexplainedVariable& v : u.variables) {
    if (!v.significant && !isReference(v)) continue;
    variables.push_back({{"name", v.name},
                         {"description", v.description},
                         {"joint", v.joint >= 0 ? nlohmann::json(v.joint + 1) : nlohmann::json(nullptr)},
                         {"perpendicular_moment", v.perpendicular_moment},
                         {"cv_gain_mm", v.cv_gain_mm},
                         {"relative_reduction", v.relative_reduction},
                         {"z", v.z_statistic},
                         {"p_value", v.p_value},
                         {"significant", v.significant}});
  }
  return {{"any", u.any},
          {"residual_mm", kMmPerM * u.residual_m},
          {"residual_rows", u.residual_rows},
          {"floor_mm", kMmPerM * u.floor_m},
          {"ratio", u.ratio},
          {"noise_stated", u.noise_stated},
          {"variables_tested", u.variables_tested},
          {"variables", variables},
          {"learner_features", u.learner_features},
          {"learner_gain_mm", u.learner_gain_mm},
          {"learner_relative_reduction", u.learner_relative_reduction},
          {"learner_z", u.learner_z},
          {"learner_significant", u.learner_significant},
          {"text", u.text}};
}

std::string unexplainedSection(const trainer::UnexplainedPart& u) {
  using html::escape;
  constexpr size_t kRows = 12;
  std::string out =
      "<h2 id=\"unexplained\">What the catalogue does not explain</h2>\n<p>" + escape(u.text) +
      ".</p>\n<p>Each variable is judged held out as a family is (folds over poses, signed-rank "
      "test, Bonferroni over the " +
      std::to_string(u.variables_tested) +
      " variables): a cubic in it, in the tracker's axes and, where it belongs to a joint, "
      "through that joint's link angle or the tilt and shift of its frame.</p>\n"
      "<table><tr><th>variable</th><th>what it is</th><th>held-out gain (mm)</th><th>z</th>"
      "<th></th><th></th></tr>\n";
  double largest = 0.0;
  for (const trainer::UnexplainedVariable& v : u.variables) largest = std::max(largest, v.cv_gain_mm);
  size_t shown = 0;
  for (const trainer::UnexplainedVariable& v : u.variables) {
    if (shown >= kRows && !isReference(v)) continue;
    ++shown;
    const double width = largest > 0.0 ? 100.0 * std::max(0.0, v.cv_gain_mm) / largest : 0.0;
    out += "<tr><td>" + escape(v.name) + "</td><td>" + escape(v.description) + "</td><td>" +
           format("%.4f", v.cv_gain_mm) + "</td><td>" + format("%.1f", v.z_statistic) + "</td><td>" +
           (v.significant ? "significant" : "") +
           format("</td><td><div style=\"background:#c44;height:0.8em;width:%.0fpx\"></div></td></tr>\n",
                  width);
  }
  out += "</table>\n";
  return out;
}

std::string residualNote(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  if (!campaign.tracker.stated || !(outcome.floor_position_m > 0.0)) return "";
  const bool gpr = outcome.gpr && outcome.gpr->taken;
  const char* method = outcome.has_stiffness
                           ? (gpr ? trainer::kMethodPoeStiffnessGpr : trainer::kMethodPoeStiffness)
                           : (gpr ? trainer::kMethodPoeGpr : trainer::kMethodPoe);
  double sum_m = 0.0;
  int rows = 0;
  for (const trainer::AccuracySummary& s : outcome.accuracy) {
    if (s.set != RowSet::kValidation || s.method != method) continue;
    sum_m += s.mean_position_m * s.rows;
    rows += s.rows;
  }
  if (rows == 0) return "";
  const double mean_m = sum_m / rows, ratio = mean_m / outcome.floor_position_m;
  if (ratio <= kResidualNoteRatio) return "";
  std::string directories;
  for (int s = 0; s < campaign.sessionCount(); ++s) directories += " " + campaign.directoryOf(s);
  return format("note: the calibrated model (%s) leaves %.4f mm on the %d validation rows, %.1f "
                "times the tracker-noise floor of %.4f mm: the robot does something the model "
                "lacks; `stepcal diagnose%s` names the cause, or what no catalogued cause explains",
                method, kMmPerM * mean_m, rows, ratio, kMmPerM * outcome.floor_position_m,
                directories.c_str());
}

}  // namespace stepcal::report
