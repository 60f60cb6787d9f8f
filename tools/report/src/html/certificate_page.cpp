// The ISO 9283 certificate as one self-contained HTML page (certificate.hpp).
#include <sstream>

#include "stepcal/common/units.hpp"
#include "stepcal/report/certificate.hpp"
#include "stepcal/report/html/charts.hpp"
#include "stepcal/report/html/page.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

constexpr double kMmPerM = 1e3;
/// Poses drawn in the per-pose charts (those measured most often first would need a sort: the
/// first in row order).
constexpr size_t kPosesCharted = 30;
const char* const kMethodColours[] = {"#d62728", "#1f77b4"};

std::string figureCell(const trainer::IsoFigure& f) {
  return f.value ? format("%.3f", *f.value * kMmPerM)
                 : "<span class=\"muted\">not measurable: " + html::escape(f.not_measurable) +
                       "</span>";
}

/// The poses measured more than once (or all, when none is), at most kPosesCharted.
std::vector<size_t> chartedPoses(const trainer::IsoMethodFigures& m) {
  std::vector<size_t> repeated, all;
  for (size_t p = 0; p < m.poses.size(); ++p) {
    if (m.poses[p].cycles > 1 && repeated.size() < kPosesCharted) repeated.push_back(p);
    if (all.size() < kPosesCharted) all.push_back(p);
  }
  return repeated.empty() ? all : repeated;
}

std::string perPoseBars(const trainer::IsoLoadFigures& load, bool repeatability) {
  html::BarChart chart;
  // RP in micrometres: a few tens of them, where AP is millimetres.
  const double scale = repeatability ? 1e6 : kMmPerM;
  chart.title = format("%s per pose at %g kg", repeatability ? "RP_l" : "AP_P", load.load_kg);
  chart.x_label = "pose";
  chart.y_label = repeatability ? "µm" : "mm";
  const std::vector<size_t> poses = chartedPoses(load.methods.front());
  for (const size_t p : poses) {
    // "pose 12" as "12": the axis says pose, and long labels do not fit thirty bars.
    const std::string& label = load.methods.front().poses[p].label;
    chart.categories.push_back(label.rfind("pose ", 0) == 0 ? label.substr(5) : label);
  }
  for (size_t m = 0; m < load.methods.size(); ++m) {
    html::BarSeries bars{load.methods[m].method, kMethodColours[m % 2], {}};
    for (const size_t p : poses) {
      const trainer::IsoFigure& f = repeatability ? load.methods[m].poses[p].rp_position
                                                  : load.methods[m].poses[p].ap_position;
      bars.values.push_back(f.value.value_or(0.0) * scale);
    }
    chart.bars.push_back(bars);
  }
  return html::renderBars(chart);
}

/// Each cycle's deviation in base x and z (the test plane's spread), per method.
std::string cyclesScatter(const trainer::IsoLoadFigures& load, html::MarkerIds& ids) {
  html::Panel panel;
  panel.title = format("Every cycle's deviation at %g kg, base x against z", load.load_kg);
  panel.x_label = "x deviation, mm";
  panel.y_label = "z deviation, mm";
  const html::MarkerShape shapes[] = {html::MarkerShape::kCircle, html::MarkerShape::kSquare};
  for (size_t m = 0; m < load.methods.size(); ++m) {
    html::Series series{load.methods[m].method, {kMethodColours[m % 2], shapes[m % 2]}, {}, {},
                        false, true};
    for (const trainer::IsoPoseFigures& pose : load.methods[m].poses) {
      for (const Vec3& e : pose.deviations_Base_m) {
        series.x.push_back(e.x() * kMmPerM);
        series.y.push_back(e.z() * kMmPerM);
      }
    }
    panel.series.push_back(series);
  }
  return html::renderPanel(panel, ids.next());
}

std::string loadSection(const trainer::IsoLoadFigures& load, html::MarkerIds& ids) {
  std::ostringstream out;
  out << "<h2 id=\"load-" << format("%g", load.load_kg) << "\">" << html::loadLabel(load.load_kg)
      << "</h2>\n<p>" << load.rows << " rows, " << load.poses_with_cycles
      << " poses measured more than once.</p>\n<table><tr><th class=\"l\">method</th>"
         "<th>AP_P max, mm</th><th>AP_P median, mm</th><th>RP_l max, mm</th>"
         "<th>RP_l median, mm</th><th>RP_l pooled, mm</th><th>vAP_P max, mm</th><th>AD_P, mm</th>"
         "<th>RD_P, mm</th></tr>\n";
  for (const trainer::IsoMethodFigures& m : load.methods) {
    out << "<tr><td class=\"l\">" << html::escape(m.method) << "</td><td>"
        << figureCell(m.ap_position_max) << "</td><td>" << figureCell(m.ap_position_median)
        << "</td><td>" << figureCell(m.rp_position_max)
        << "</td><td>" << figureCell(m.rp_position_median) << "</td><td>"
        << figureCell(m.rp_position_pooled) << "</td><td>" << figureCell(m.vap_position_max)
        << "</td><td>" << figureCell(m.ad_position) << "</td><td>" << figureCell(m.rd_position) << "</td></tr>\n";
  }
  out << "</table>\n<div class=\"panels\">" << perPoseBars(load, false) << perPoseBars(load, true)
      << cyclesScatter(load, ids) << "</div>\n";
  return out.str();
}

}  // namespace

std::string certificateHtml(const trainer::IsoCertificate& c) {
  std::ostringstream out;
  const std::string robot = c.robot_name.empty() ? "the robot" : c.robot_name;
  out << html::pageHead("ISO 9283 certificate: " + robot) << "<h1>ISO 9283 pose characteristics of "
      << html::escape(robot) << "</h1>\n<table>"
      << "<tr><th class=\"l\">campaign</th><td class=\"l\">" << html::escape(c.campaign_directory)
      << " (hash " << html::escape(c.campaign_hash) << "), " << c.rows_used << " rows"
      << (c.iso_plan_rows ? " of a stepcal plan --iso9283" : "") << "</td></tr>\n"
      << "<tr><th class=\"l\">model</th><td class=\"l\">" << html::escape(c.model_path)
      << " (CRC-32 " << html::escape(c.model_crc32) << "), corrected by "
      << html::escape(c.corrected_method)
      << (c.frames_refit ? "; tracker and tool frames fitted on these rows" : "") << "</td></tr>\n";
  if (c.temperature_min_c) {
    out << "<tr><th class=\"l\">temperature</th><td class=\"l\">"
        << format("%.2f – %.2f °C", *c.temperature_min_c, *c.temperature_max_c) << "</td></tr>\n";
  }
  out << "<tr><th class=\"l\">tracker noise</th><td class=\"l\">"
      << format("%.3f mm per axis, 1-σ", c.tracker_position_sigma_m * kMmPerM)
      << "</td></tr></table>\n<h2>What each figure means</h2>\n<p><b>commanded</b>: the nominal "
         "robot at the rows' joints, what the controller aims at (uncorrected). <b>corrected</b>: "
         "the attained pose minus the model's prediction, where the corrected robot lands about "
         "its target. <b>AP_P</b>: distance of the barycentre of a pose's cycles from the "
         "commanded position. <b>RP_l</b> = l̄ + 3 S_l, l the distances of the cycles' attained "
         "positions from their barycentre (the same for both methods). <b>vAP_P</b>: largest "
         "distance between the barycentres of one pose approached from different directions. <b>AD_P</b>: mean attained distance P2–P4 minus "
         "the commanded one; <b>RD_P</b>: 3 S of it. A figure the rows cannot give says why.</p>\n";
  html::MarkerIds ids;
  for (const trainer::IsoLoadFigures& load : c.loads) out << loadSection(load, ids);
  out << html::pageEnd();
  return out.str();
}

}  // namespace stepcal::report
