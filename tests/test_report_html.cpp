// The HTML reports: a simulated paper campaign, calibrated, rendered and checked for structure
// (balanced tags, entities, finite coordinates, every chart drawing data, nothing external),
// content (a figure per validation load, every method, the noise floor, the error's
// distribution, workspace and coverage), escaping of the campaign path and size; a diagnosis of a
// hidden backlash with its signature and the chosen candidates marked.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "stepcal/common/mechanisms/backlash.hpp"
#include "stepcal/report/report_html.hpp"
#include "stepcal/trainer/diagnose.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"

namespace stepcal {
namespace {

struct Rendered {
  Campaign campaign;
  trainer::CalibrationOutcome outcome;
  std::string html;
};

Rendered simulateAndRender(const std::string& protocol) {
  twin::TwinOptions options;
  options.protocol = protocol;
  options.seed = 3;
  Rendered r;
  r.campaign = twin::simulateCampaign(options, nullptr);
  r.campaign.directory = "/campaigns/irb4400-" + protocol;
  r.outcome = trainer::calibrateCampaign(r.campaign);
  r.html = report::htmlReport(r.campaign, r.outcome);
  return r;
}

// Calibrated once for every test below (the GPR fits take a while).
const Rendered& paperReport() {
  static const Rendered rendered = simulateAndRender("paper");
  return rendered;
}

size_t count(const std::string& text, const std::string& needle) {
  size_t n = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
  return n;
}

// The first structural problem of an HTML page, empty when none: every element opened is
// closed in order (void elements excepted), '<' only starts a tag or comment, '&' only starts
// an entity.
std::string structuralProblem(const std::string& html) {
  static const std::set<std::string> kVoidElements = {"meta", "br", "hr", "img", "input", "link"};
  static const std::regex kEntity("&(amp|lt|gt|quot|#39|#[0-9]{1,6});");
  std::vector<std::string> open;
  for (size_t i = 0; i < html.size();) {
    if (html[i] == '&') {
      std::smatch match;
      const std::string ahead = html.substr(i, 10);
      if (!std::regex_search(ahead, match, kEntity, std::regex_constants::match_continuous)) {
        return "bare '&' at offset " + std::to_string(i) + ": " + ahead;
      }
      i += static_cast<size_t>(match.length(0));
      continue;
    }
    if (html[i] != '<') {
      ++i;
      continue;
    }
    if (html.compare(i, 4, "<!--") == 0 || html.compare(i, 9, "<!DOCTYPE") == 0) {
      const size_t end = html.find('>', i);
      if (end == std::string::npos) return "unterminated declaration";
      i = end + 1;
      continue;
    }
    const size_t end = html.find('>', i);
    if (end == std::string::npos) return "unterminated tag at offset " + std::to_string(i);
    const std::string tag = html.substr(i + 1, end - i - 1);
    if (tag.find('<') != std::string::npos) return "'<' inside the tag <" + tag + ">";
    const bool closing = !tag.empty() && tag[0] == '/';
    const bool self_closing = !tag.empty() && tag.back() == '/';
    size_t name_end = closing ? 1 : 0;
    while (name_end < tag.size() && std::isalnum(static_cast<unsigned char>(tag[name_end]))) ++name_end;
    const std::string name = tag.substr(closing ? 1 : 0, name_end - (closing ? 1 : 0));
    if (name.empty()) return "'<' that starts no tag at offset " + std::to_string(i);
    if (closing) {
      if (open.empty() || open.back() != name) {
        return "</" + name + "> closes " + (open.empty() ? std::string("nothing") : "<" + open.back() + ">") +
               " at offset " + std::to_string(i);
      }
      open.pop_back();
    } else if (!self_closing && !kVoidElements.count(name)) {
      open.push_back(name);
    }
    i = end + 1;
  }
  return open.empty() ? "" : "<" + open.back() + "> never closed";
}

// Non-finite numbers printed anywhere: "nan" or "inf" not part of a longer word.
std::string nonFiniteText(const std::string& html) {
  std::string lower = html;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const std::string word : {"nan", "inf"}) {
    for (size_t at = lower.find(word); at != std::string::npos; at = lower.find(word, at + 1)) {
      const bool letter_before = at > 0 && std::isalpha(static_cast<unsigned char>(lower[at - 1]));
      const bool letter_after =
          at + 3 < lower.size() && std::isalpha(static_cast<unsigned char>(lower[at + 3]));
      if (!letter_before && !letter_after) return lower.substr(at > 30 ? at - 30 : 0, 60);
    }
  }
  return "";
}

// The first reference to anything outside the page, empty when none: a src attribute, a URL other
// than the SVG namespace, a url() other than a fragment, an @import.
std::string externalReference(const std::string& html) {
  static const std::regex kExternal(
      R"((src\s*=|https?://(?!www\.w3\.org/2000/svg")|url\((?!#)|@import))", std::regex::icase);
  std::smatch match;
  return std::regex_search(html, match, kExternal)
             ? html.substr(static_cast<size_t>(std::max<long>(match.position(0) - 30, 0)), 80)
             : "";
}

// Titles of the charts (svg class="chart") that draw no data mark.
std::vector<std::string> chartsWithoutData(const std::string& html) {
  std::vector<std::string> empty;
  const std::string open = "<svg class=\"chart\"";
  for (size_t at = html.find(open); at != std::string::npos; at = html.find(open, at + 1)) {
    const std::string chart = html.substr(at, html.find("</svg>", at) - at);
    if (!std::regex_search(chart, std::regex(R"(class="[^"]*\bmark\b)"))) {
      const size_t label = chart.find("aria-label=\"");
      empty.push_back(chart.substr(label + 12, chart.find('"', label + 12) - label - 12));
    }
  }
  return empty;
}

TEST(StructuralChecker, FindsUnbalancedTagsAndBareCharacters) {
  EXPECT_EQ(structuralProblem("<html><body><p>a &amp; b</p><br><svg><path d=\"M0 0\"/></svg></body></html>"), "");
  EXPECT_NE(structuralProblem("<svg><g></svg></g>"), "");
  EXPECT_NE(structuralProblem("<p>a < b</p>"), "");
  EXPECT_NE(structuralProblem("<p>a & b</p>"), "");
  EXPECT_NE(structuralProblem("<div>"), "");
  EXPECT_NE(nonFiniteText("<circle cx=\"nan\"/>"), "");
  EXPECT_NE(nonFiniteText("points=\"1,-inf\""), "");
  EXPECT_EQ(nonFiniteText("information, infinite, financial"), "");
}

TEST(StructuralChecker, FindsExternalReferencesAndChartsWithoutData) {
  EXPECT_EQ(externalReference("<svg xmlns=\"http://www.w3.org/2000/svg\"><path marker-mid=\"url(#m0)\"/></svg>"), "");
  EXPECT_NE(externalReference("<img src=\"plot.png\">"), "");
  EXPECT_NE(externalReference("<a href=\"https://example.com\">"), "");
  EXPECT_NE(externalReference("<style>body{background:url(x.png)}</style>"), "");
  EXPECT_TRUE(chartsWithoutData("<svg class=\"chart\" aria-label=\"a\"><rect class=\"box mark\"/></svg>").empty());
  EXPECT_EQ(chartsWithoutData("<svg class=\"chart\" aria-label=\"b\"><rect class=\"frame\"/></svg>"),
            std::vector<std::string>{"b"});
}

// Targets of the page's navigation links that no element of the page has as its id.
std::vector<std::string> danglingNavigation(const std::string& html) {
  std::vector<std::string> dangling;
  const size_t nav = html.find("<nav>"), end = html.find("</nav>", nav);
  for (size_t at = html.find("href=\"#", nav); at < end; at = html.find("href=\"#", at + 1)) {
    const std::string target = html.substr(at + 7, html.find('"', at + 7) - at - 7);
    if (html.find("id=\"" + target + "\"") == std::string::npos) dangling.push_back(target);
  }
  return dangling;
}

TEST(HtmlReport, PaperCampaignIsWellFormed) {
  const std::string& html = paperReport().html;
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(danglingNavigation(html), std::vector<std::string>{});
  EXPECT_EQ(html.find("href=\"#campaigns\""), std::string::npos) << "one campaign: no such section";
  EXPECT_EQ(structuralProblem(html), "");
  EXPECT_EQ(count(html, "<script>"), 1u);  // the inline check of the charts, nothing loaded
  EXPECT_EQ(externalReference(html), "");
  EXPECT_EQ(nonFiniteText(html), "");
  EXPECT_EQ(chartsWithoutData(html), std::vector<std::string>{});
}

TEST(HtmlReport, ShowsTheErrorsDistributionWorkspaceAndCoverage) {
  const Rendered& r = paperReport();
  for (const char* section : {"id=\"distribution\"", "id=\"workspace\"", "id=\"coverage\""}) {
    const size_t at = r.html.find(section);
    ASSERT_NE(at, std::string::npos) << section;
    const std::string body = r.html.substr(at, r.html.find("<h2", at) - at);
    EXPECT_GE(count(body, "<svg class=\"chart\""), 1u) << section;
  }
  // A box per load and calibrated method, in position and orientation.
  EXPECT_EQ(count(r.html, "class=\"box mark\""), 2u * 5u * 4u);
  // Two views per map, a dot per row in each: the whole hierarchy on every validation row, poe on
  // the unloaded ones.
  size_t validation_rows = 0, unloaded_rows = 0;
  for (const Measurement& m : r.campaign.rows) {
    validation_rows += m.set == RowSet::kValidation;
    unloaded_rows += m.set == RowSet::kValidation && m.load_kg == 0.0;
  }
  EXPECT_EQ(count(r.html, "class=\"dot mark\""), 2u * validation_rows + 2u * unloaded_rows);
  EXPECT_NE(r.html.find("validation loads no fit row has (extrapolation): 55 kg"), std::string::npos);
}

TEST(HtmlReport, HasOneFigurePerValidationLoad) {
  const Rendered& r = paperReport();
  std::set<double> loads;
  for (const Measurement& m : r.campaign.rows) {
    if (m.set == RowSet::kValidation) loads.insert(m.load_kg);
  }
  ASSERT_EQ(loads.size(), 5u);  // 0, 20, 30, 40 and 55 kg (extrapolation)
  EXPECT_EQ(count(r.html, "<figure class=\"per-load\""), loads.size());
  for (const double load : loads) {
    char id[64];
    std::snprintf(id, sizeof id, "id=\"load-%gkg\"", load);
    const size_t figure = r.html.find(id);
    ASSERT_NE(figure, std::string::npos) << id;
    const std::string body = r.html.substr(figure, r.html.find("</figure>", figure) - figure);
    EXPECT_EQ(count(body, "<svg"), 2u) << id;  // position and orientation
    for (const char* method : {trainer::kMethodPoe, trainer::kMethodPoeStiffness, trainer::kMethodPoeGpr,
                               trainer::kMethodPoeStiffnessGpr}) {
      EXPECT_EQ(count(body, std::string(">") + method + "</text>"), 2u) << id << " " << method;
    }
    EXPECT_EQ(count(body, "class=\"ref\""), 4u) << id;  // noise floor line and legend, twice
  }
}

TEST(HtmlReport, NamesEveryMethodAndTheNoiseFloor) {
  const Rendered& r = paperReport();
  ASSERT_EQ(r.outcome.row_errors.size(), 6u);
  for (const auto& [method, errors] : r.outcome.row_errors) {
    EXPECT_NE(r.html.find(">" + method + "<"), std::string::npos) << method;
  }
  char floor[64];
  std::snprintf(floor, sizeof floor, "noise floor %.4f mm", r.outcome.floor_position_m * 1e3);
  EXPECT_GE(count(r.html, floor), 2u) << floor;
  std::snprintf(floor, sizeof floor, "mean %.4f mm", r.outcome.floor_position_m * 1e3);
  EXPECT_NE(r.html.find(floor), std::string::npos) << floor;
  for (const char* section : {"id=\"convergence\"", "id=\"geometry\"", "id=\"against-load\"",
                              "id=\"stiffness\"", "id=\"gpr\"", "id=\"accuracy\""}) {
    EXPECT_NE(r.html.find(section), std::string::npos) << section;
  }
  EXPECT_NE(r.html.find("not identified"), std::string::npos);  // the paper loads leave a joint unexcited
}

TEST(HtmlReport, AccuracyTableHasTheTextReportsNumbers) {
  const Rendered& r = paperReport();
  for (const trainer::AccuracySummary& s : r.outcome.accuracy) {
    char cells[128];
    std::snprintf(cells, sizeof cells, "<td class=\"g\">%.4f</td><td>%.4f</td>", s.mean_position_m * 1e3,
                  s.max_position_m * 1e3);
    EXPECT_NE(r.html.find(cells), std::string::npos) << s.method << " " << s.load_kg;
  }
}

TEST(HtmlReport, IsCompact) {
  const size_t size = paperReport().html.size();
  EXPECT_GT(size, 20'000u);
  EXPECT_LT(size, 400'000u);
}

TEST(HtmlReport, EscapesTheCampaignPath) {
  Rendered r = paperReport();
  r.campaign.directory = "/data/odd <&> \"name\" 'x'";
  const std::string html = report::htmlReport(r.campaign, r.outcome);
  EXPECT_NE(html.find("/data/odd &lt;&amp;&gt; &quot;name&quot; &#39;x&#39;"), std::string::npos);
  EXPECT_EQ(html.find("<&>"), std::string::npos);
  EXPECT_EQ(structuralProblem(html), "");
}

TEST(HtmlReport, GeometryOnlyCampaignSaysWhatWasSkipped) {
  const Rendered r = simulateAndRender("geometry");
  EXPECT_EQ(structuralProblem(r.html), "");
  EXPECT_EQ(nonFiniteText(r.html), "");
  EXPECT_EQ(count(r.html, "<figure class=\"per-load\""), 1u);  // unloaded only
  EXPECT_NE(r.html.find("Skipped: the campaign has no loaded/unloaded stiffness pairs"), std::string::npos);
  EXPECT_NE(r.html.find("fewer than two loads"), std::string::npos);
  EXPECT_EQ(r.html.find(std::string(">") + trainer::kMethodPoeStiffnessGpr + "<"), std::string::npos);
}

struct RenderedDiagnosis {
  Campaign campaign;
  trainer::Diagnosis diagnosis;
  std::string html;
};

// The paper campaign of seed 3 hiding a backlash of joint 2 (docs/diagnosis.md), diagnosed once.
const RenderedDiagnosis& backlashDiagnosis() {
  static const RenderedDiagnosis rendered = [] {
    twin::TwinOptions options;
    options.seed = 3;
    options.hidden_effects = {{{"name", "backlash"}, {"joint", 2}, {"lost_motion_rad", 2e-4}}};
    RenderedDiagnosis r;
    r.campaign = twin::simulateCampaign(options, nullptr);
    r.campaign.directory = "/campaigns/backlash";
    r.diagnosis = trainer::diagnose(
        r.campaign, trainer::modelFromOutcome(r.campaign, trainer::calibrateCampaign(r.campaign)));
    r.html = report::diagnosisHtml(r.campaign, r.diagnosis);
    return r;
  }();
  return rendered;
}

const trainer::EffectSignature* findSignature(const std::vector<trainer::EffectSignature>& signatures,
                                              MechanismKind kind, int joint) {
  for (const trainer::EffectSignature& s : signatures) {
    if (s.mechanism.kind == kind && s.joint == joint) return &s;
  }
  return nullptr;
}

// Least-squares slope of the partial residuals on the fitted effect.
double slopeOnEffect(const trainer::EffectSignature& s) {
  double pe = 0.0, ee = 0.0;
  for (size_t i = 0; i < s.effect.size(); ++i) {
    pe += s.partial_residual[i] * s.effect[i];
    ee += s.effect[i] * s.effect[i];
  }
  return pe / ee;
}

TEST(DiagnosisHtml, IsWellFormedSelfContainedAndEveryChartDrawsData) {
  const std::string& html = backlashDiagnosis().html;
  EXPECT_EQ(structuralProblem(html), "");
  EXPECT_EQ(danglingNavigation(html), std::vector<std::string>{});
  EXPECT_EQ(nonFiniteText(html), "");
  EXPECT_EQ(externalReference(html), "");
  EXPECT_EQ(chartsWithoutData(html), std::vector<std::string>{});
}

TEST(DiagnosisHtml, MarksTheChosenCandidateOfEveryRoundAndShowsTheSignature) {
  const RenderedDiagnosis& r = backlashDiagnosis();
  std::set<int> rounds_with_a_choice;
  for (const trainer::CandidateScore& c : r.diagnosis.candidates) {
    if (c.chosen) rounds_with_a_choice.insert(c.round);
  }
  ASSERT_FALSE(rounds_with_a_choice.empty());
  EXPECT_EQ(count(r.html, "\u25c0 chosen"), rounds_with_a_choice.size());
  EXPECT_NE(r.html.find("aria-label=\"backlash (joint 2)\""), std::string::npos);
  EXPECT_NE(r.html.find("joint 2 link-angle offset (µrad)"), std::string::npos);
}

// The partial residuals hold what the model leaves along the effect: with the extended model they
// scatter about its curve (slope 1 on it); with its backlash halved, the residual holds the other
// half and the points come out at the whole backlash (slope 2).
TEST(EffectSignatures, PartialResidualsRecoverTheBacklash) {
  const RenderedDiagnosis& r = backlashDiagnosis();
  const auto signatures = trainer::effectSignatures(r.campaign, r.diagnosis);
  const trainer::EffectSignature* s = findSignature(signatures, MechanismKind::kBacklash, 1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->variable, trainer::SignatureVariable::kJointTorque);
  EXPECT_GT(s->x.size(), 0.9 * r.diagnosis.fit_rows);
  EXPECT_NEAR(slopeOnEffect(*s), 1.0, 0.05);
  EXPECT_FALSE(s->curve_x.empty());
  EXPECT_TRUE(std::is_sorted(s->curve_x.begin(), s->curve_x.end()));

  trainer::Diagnosis halved = r.diagnosis;
  for (Mechanism& m : halved.extended_model.mechanisms) {
    if (m.kind == MechanismKind::kBacklash) view<mechanism::Backlash>(m).lostMotion_rad() *= 0.5;
  }
  const auto halved_signatures = trainer::effectSignatures(r.campaign, halved);
  const trainer::EffectSignature* h = findSignature(halved_signatures, MechanismKind::kBacklash, 1);
  ASSERT_NE(h, nullptr);
  EXPECT_NEAR(slopeOnEffect(*h), 2.0, 0.1);
}

}  // namespace
}  // namespace stepcal
