// The HTML report: a simulated paper campaign, calibrated, rendered and checked for structure
// (balanced tags, entities, finite coordinates), content (a figure per validation load, every
// method, the noise floor), escaping of the campaign path and size.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "report_html.hpp"
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
  r.html = cli::htmlReport(r.campaign, r.outcome);
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

TEST(HtmlReport, PaperCampaignIsWellFormed) {
  const std::string& html = paperReport().html;
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(structuralProblem(html), "");
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("http://", 0), html.find("http://www.w3.org/2000/svg"));  // no external files
  EXPECT_EQ(nonFiniteText(html), "");
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
  const std::string html = cli::htmlReport(r.campaign, r.outcome);
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

}  // namespace
}  // namespace stepcal
