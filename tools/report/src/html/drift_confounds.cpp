// The diagnosis page's confound section (drift_confounds.hpp).
#include "stepcal/report/html/drift_confounds.hpp"

#include <cstdio>
#include <sstream>

#include "stepcal/report/html/page.hpp"

namespace stepcal::report::html {
namespace {

// From this r a variable moves with the time order enough to be tested (confounds.hpp's rule).
constexpr double kShownFrom = 0.3;

std::string driverWords(const std::string& driver) {
  return driver == "seq" ? "the time order" : driver == "temp_c" ? "the temperature" : driver;
}

}  // namespace

std::string driftConfoundsSection(const trainer::DriftVerdict& drift) {
  if (drift.time_order_correlations.empty() && drift.confound_tests.empty()) return "";
  std::ostringstream out;
  out << "<h3 id=\"confounds\">What moves with the time order</h3>\n";
  if (!drift.time_order_correlations.empty()) {
    out << "<table>\n<tr><th class=\"l\">variable</th><th>r with the time order</th></tr>\n";
    for (size_t i = 0; i < drift.time_order_correlations.size(); ++i) {
      const trainer::DriverCorrelation& c = drift.time_order_correlations[i];
      if (i > 0 && c.r < kShownFrom) break;
      out << "<tr><td class=\"l\">" << escape(c.variable) << "</td><td>" << cell("%.2f", c.r)
          << "</td></tr>\n";
    }
    out << "</table>\n";
  }
  for (const trainer::ConfoundTest& t : drift.confound_tests) {
    out << "<p>" << escape(describe(t.mechanism)) << ", round " << t.round << ": z "
        << cell("%.1f", t.z_statistic) << " alone; "
        << (t.beside.empty() ? "nothing moves with " + escape(driverWords(t.driver))
                             : std::string(t.told_apart ? "told apart from every variable that "
                                                          "moves with "
                                                        : "<b>not told apart</b> from what moves "
                                                          "with ") +
                                   escape(driverWords(t.driver)))
        << ".</p>\n";
    if (t.beside.empty()) continue;
    out << "<table>\n<tr><th class=\"l\">beside</th><th>r</th><th>held-out gain (mm)</th>"
           "<th>removes</th><th>z</th><th class=\"l\">told apart</th></tr>\n";
    for (const trainer::ConfoundTest::Beside& b : t.beside) {
      out << "<tr><td class=\"l\">" << escape(b.variable) << "</td><td>" << cell("%.2f", b.r)
          << "</td><td>" << cell("%.4f", b.cv_gain_mm) << "</td><td>"
          << cell("%.1f %%", 100.0 * b.relative_reduction) << "</td><td>"
          << cell("%.1f", b.z_statistic) << "</td><td class=\"l\">" << (b.told_apart ? "yes" : "no")
          << "</td></tr>\n";
    }
    out << "</table>\n";
  }
  return out.str();
}

}  // namespace stepcal::report::html
