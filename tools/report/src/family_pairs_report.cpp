// Pairs of families the rows may not tell apart, and the geometry pin (family_pairs_report.hpp).
#include "stepcal/report/family_pairs_report.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "stepcal/common/units.hpp"
#include "stepcal/report/html/page.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

// The same candidate as a named effect: kind, joint and source joint (parameters differ after
// the final refit).
bool sameCandidate(const Mechanism& a, const Mechanism& b) {
  return a.kind == b.kind && a.joint == b.joint && a.source_joint == b.source_joint;
}

bool named(const trainer::Diagnosis& d, const Mechanism& m) {
  return std::any_of(d.effects.begin(), d.effects.end(),
                     [&](const trainer::FoundEffect& e) { return sameCandidate(e.mechanism, m); });
}

std::string inflationText(double vif) {
  return std::isfinite(vif) ? format("%.0f", vif) : std::string("infinite");
}

std::string besideText(const trainer::FamilyPairTest::Beside& b) {
  return format("z %.1f, %.1f %% held out", b.z_statistic, 100.0 * b.relative_reduction);
}

nlohmann::json candidateId(const Mechanism& m) {
  return {{"name", toString(m.kind)},
          {"joint", m.joint >= 0 ? nlohmann::json(m.joint + 1) : nlohmann::json(nullptr)},
          {"description", describe(m)}};
}

nlohmann::json besideJson(const trainer::FamilyPairTest::Beside& b) {
  return {{"cv_gain_mm", b.cv_gain_mm},
          {"relative_reduction", b.relative_reduction},
          {"z_statistic", b.z_statistic},
          {"p_value", b.p_value},
          {"significant", b.significant}};
}

}  // namespace

std::vector<std::string> familyPairLines(const trainer::Diagnosis& d) {
  std::vector<std::string> lines;
  for (const trainer::FamilyPairTest& t : d.family_pairs) {
    if (t.told_apart || !named(d, t.chosen)) continue;
    lines.push_back(format(
        "%s and %s, round %d: their columns correlate at rho = %.2f (variance inflation %s) "
        "beside the model's; beside each other neither adds (the first %s; the second %s): the "
        "rows cannot say which, the first, named, stands for either",
        describe(t.chosen).c_str(), describe(t.other).c_str(), t.round, t.canonical_correlation,
        inflationText(t.variance_inflation).c_str(), besideText(t.chosen_beside_other).c_str(),
        besideText(t.other_beside_chosen).c_str()));
  }
  return lines;
}

nlohmann::json familyPairsJson(const trainer::Diagnosis& d) {
  nlohmann::json pairs = nlohmann::json::array();
  for (const trainer::FamilyPairTest& t : d.family_pairs) {
    pairs.push_back({{"chosen", candidateId(t.chosen)},
                     {"other", candidateId(t.other)},
                     {"named", named(d, t.chosen)},
                     {"round", t.round},
                     {"canonical_correlation", t.canonical_correlation},
                     {"variance_inflation", std::isfinite(t.variance_inflation)
                                                ? nlohmann::json(t.variance_inflation)
                                                : nlohmann::json(nullptr)},
                     {"chosen_beside_other", besideJson(t.chosen_beside_other)},
                     {"other_beside_chosen", besideJson(t.other_beside_chosen)},
                     {"told_apart", t.told_apart}});
  }
  return pairs;
}

std::string familyPairsSection(const trainer::Diagnosis& d) {
  if (d.family_pairs.empty()) return "";
  using html::cell;
  using html::escape;
  std::ostringstream out;
  out << "<h3 id=\"pairs\">Families the rows may not tell apart</h3>\n"
         "<p>Per round, the family chosen against the other significant ones: ρ, the largest "
         "canonical correlation of their columns beside the model's, and each held out beside "
         "the other. Neither adding beside the other: the rows cannot say which.</p>\n"
         "<table>\n<tr><th>round</th><th class=\"l\">chosen</th><th class=\"l\">other</th>"
         "<th>ρ</th><th>chosen beside other: z</th><th>removes</th>"
         "<th>other beside chosen: z</th><th>removes</th><th class=\"l\">told apart</th></tr>\n";
  for (const trainer::FamilyPairTest& t : d.family_pairs) {
    out << "<tr><td>" << t.round << "</td><td class=\"l\">" << escape(describe(t.chosen))
        << (named(d, t.chosen) ? "" : " (not named)") << "</td><td class=\"l\">"
        << escape(describe(t.other)) << "</td><td>" << cell("%.3f", t.canonical_correlation)
        << "</td><td>" << cell("%.1f", t.chosen_beside_other.z_statistic) << "</td><td>"
        << cell("%.1f %%", 100.0 * t.chosen_beside_other.relative_reduction) << "</td><td>"
        << cell("%.1f", t.other_beside_chosen.z_statistic) << "</td><td>"
        << cell("%.1f %%", 100.0 * t.other_beside_chosen.relative_reduction)
        << "</td><td class=\"l\">" << (t.told_apart ? "yes" : "<b>no</b>") << "</td></tr>\n";
  }
  out << "</table>\n";
  return out.str();
}

std::string geometryPinText(const trainer::GeometryPin& pin) {
  if (!pin.tested) return "";
  const std::string shift =
      format("%.4f mm RMS (%.4f most) over the fit rows", kMmPerM * pin.tip_shift_rms_m,
             kMmPerM * pin.tip_shift_max_m);
  if (pin.pinned) {
    return format(
        "pinned by the %d unloaded fit rows: they reject the global fit's geometry (F = %.1f on "
        "%d directions, above %.0f), so the extended model's geometry is theirs alone (a load "
        "effect had leaked into it); it moves the tip by %s",
        pin.unloaded_rows, pin.f_statistic, pin.rank, pin.f_limit, shift.c_str());
  }
  return format(
      "not pinned: the %d unloaded fit rows accept the global fit's geometry (F = %.1f on %d "
      "directions, at most %.0f); theirs alone would move the tip by %s",
      pin.unloaded_rows, pin.f_statistic, pin.rank, pin.f_limit, shift.c_str());
}

nlohmann::json geometryPinJson(const trainer::GeometryPin& pin) {
  return {{"tested", pin.tested},
          {"pinned", pin.pinned},
          {"unloaded_rows", pin.unloaded_rows},
          {"rank", pin.rank},
          {"f_statistic", pin.f_statistic},
          {"f_limit", pin.f_limit},
          {"tip_shift_rms_mm", kMmPerM * pin.tip_shift_rms_m},
          {"tip_shift_max_mm", kMmPerM * pin.tip_shift_max_m},
          {"text", geometryPinText(pin)}};
}

}  // namespace stepcal::report
