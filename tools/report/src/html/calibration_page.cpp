// The calibration report (htmlReport): the paper's figures, the error's distribution, where in
// the workspace it lives, what the model covers, and the tables.
#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include "stepcal/common/error.hpp"
#include "stepcal/report/html/charts.hpp"
#include "stepcal/report/html/page.hpp"
#include "stepcal/report/report.hpp"
#include "stepcal/report/report_html.hpp"
#include "stepcal/report/session_report.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

using namespace html;

// ------------------------------------------------------------------------------------------
// The report's content.

/// Colour and marker of each method, the same in every figure.
class MethodStyles {
 public:
  explicit MethodStyles(const trainer::CalibrationOutcome& outcome) {
    const std::map<std::string, SeriesStyle> fixed = {
        {trainer::kMethodNominal, {"#7f7f7f", MarkerShape::kCircle}},
        {trainer::kMethodFrames, {"#9467bd", MarkerShape::kSquare}},
        {trainer::kMethodPoe, {"#1f77b4", MarkerShape::kCircle}},
        {trainer::kMethodPoeStiffness, {"#ff7f0e", MarkerShape::kSquare}},
        {trainer::kMethodPoeGpr, {"#2ca02c", MarkerShape::kTriangle}},
        {trainer::kMethodPoeStiffnessGpr, {"#d62728", MarkerShape::kDiamond}}};
    const SeriesStyle others[] = {{"#8c564b", MarkerShape::kCircle}, {"#e377c2", MarkerShape::kSquare},
                                  {"#17becf", MarkerShape::kTriangle}, {"#bcbd22", MarkerShape::kDiamond}};
    size_t next_other = 0;
    for (const auto& [method, errors] : outcome.row_errors) {
      const auto it = fixed.find(method);
      styles_[method] = it != fixed.end() ? it->second : others[next_other++ % std::size(others)];
    }
  }
  /// The method's style; dark grey circles for a method the outcome has no row errors of.
  SeriesStyle of(const std::string& method) const {
    const auto it = styles_.find(method);
    return it != styles_.end() ? it->second : SeriesStyle{"#333333", MarkerShape::kCircle};
  }

 private:
  std::map<std::string, SeriesStyle> styles_;
};

/// Renders the page section by section.
class PageWriter {
 public:
  PageWriter(const Campaign& campaign, const trainer::CalibrationOutcome& outcome)
      : campaign_(campaign), outcome_(outcome), styles_(outcome) {
    for (const auto& [method, errors] : outcome.row_errors) {
      STEPCAL_INVARIANT(errors.size() == campaign.rows.size(),
                        "row_errors must be aligned with the campaign's rows");
    }
    for (size_t i = 0; i < campaign.rows.size(); ++i) {
      if (campaign.rows[i].set == RowSet::kValidation) validation_by_load_[campaign.rows[i].load_kg].push_back(i);
      has_orientation_ = has_orientation_ || campaign.rows[i].has_orientation;
    }
  }

  std::string write() {
    writeHead();
    writeOverview();
    writeCampaigns();
    writeConvergence();
    writeGeometricValidation();
    writeLoadedValidation();
    writeErrorAgainstLoad();
    writeErrorDistribution();
    writeWorkspaceMap();
    writeCoverage();
    writeStiffness();
    writeGpr();
    writeAccuracyTable();
    out_ << pageEnd();
    return out_.str();
  }

 private:
  const std::vector<trainer::RowError>* errorsOf(const std::string& method) const {
    for (const auto& [name, errors] : outcome_.row_errors) {
      if (name == method) return &errors;
    }
    return nullptr;
  }

  const trainer::AccuracySummary* summaryOf(const std::string& method, RowSet set, double load_kg) const {
    for (const auto& s : outcome_.accuracy) {
      if (s.method == method && s.set == set && s.load_kg == load_kg) return &s;
    }
    return nullptr;
  }

  /// Methods of row_errors except the uncalibrated ones (nominal, frames): those of Fig. 9/10.
  std::vector<std::string> calibratedMethods() const {
    std::vector<std::string> methods;
    for (const auto& [method, errors] : outcome_.row_errors) {
      if (method != trainer::kMethodNominal && method != trainer::kMethodFrames) methods.push_back(method);
    }
    return methods;
  }

  /// Per-point error of each method on the given rows, in mm (position) or degrees (orientation).
  std::vector<Series> perPointSeries(const std::vector<std::string>& methods,
                                     const std::vector<size_t>& rows, bool orientation) const {
    std::vector<Series> series;
    for (const std::string& method : methods) {
      const std::vector<trainer::RowError>* errors = errorsOf(method);
      if (!errors) continue;
      Series s{method, styles_.of(method), {}, {}};
      for (size_t k = 0; k < rows.size(); ++k) {
        const trainer::RowError& e = (*errors)[rows[k]];
        s.x.push_back(static_cast<double>(k + 1));
        s.y.push_back(orientation ? (campaign_.rows[rows[k]].has_orientation ? e.orientation_rad * kDegPerRad : NAN)
                                  : e.position_m * kMmPerM);
      }
      series.push_back(std::move(s));
    }
    return series;
  }

  std::vector<ReferenceLine> positionFloor() const {
    return {{format("noise floor %.4f mm", outcome_.floor_position_m * kMmPerM), outcome_.floor_position_m * kMmPerM}};
  }
  std::vector<ReferenceLine> orientationFloor() const {
    return {{format("noise floor %.4f°", outcome_.floor_orientation_rad * kDegPerRad),
             outcome_.floor_orientation_rad * kDegPerRad}};
  }

  /// A figure of the two per-point panels (position, orientation) of some methods on some rows.
  void writePerPointFigure(const std::string& figure_attributes, const std::string& title,
                           const std::vector<std::string>& methods, const std::vector<size_t>& rows,
                           const std::string& caption) {
    Panel position{title + ": position error", "validation point", "position error (mm)",
                   Scale::kLog, true, perPointSeries(methods, rows, false), positionFloor()};
    out_ << "<figure " << figure_attributes << "><div class=\"panels\">\n"
         << renderPanel(position, marker_ids_.next());
    const bool any_orientation = std::any_of(rows.begin(), rows.end(),
                                             [&](size_t i) { return campaign_.rows[i].has_orientation; });
    if (any_orientation) {
      Panel orientation{title + ": orientation error", "validation point", "orientation error (°)",
                        Scale::kLog, true, perPointSeries(methods, rows, true), orientationFloor()};
      out_ << renderPanel(orientation, marker_ids_.next());
    }
    out_ << "</div><figcaption>" << caption << (any_orientation ? "" : " Position-only rows: no orientation error.")
         << "</figcaption></figure>\n";
  }

  /// "poe 0.4300 mm / 0.0160°, …": mean validation errors of methods at one load.
  std::string meansAt(const std::vector<std::string>& methods, double load_kg) const {
    std::string text;
    for (const std::string& method : methods) {
      const trainer::AccuracySummary* s = summaryOf(method, RowSet::kValidation, load_kg);
      if (!s) continue;
      text += (text.empty() ? "<span class=\"item\">" : ", <span class=\"item\">") + swatch(method) + "<b>" +
              escape(method) + "</b> " + format("%.4f mm", s->mean_position_m * kMmPerM);
      if (s->rows_with_orientation > 0) text += format(" / %.4f°", s->mean_orientation_rad * kDegPerRad);
      text += "</span>";
    }
    return text;
  }

  std::string swatch(const std::string& method) const {
    return "<span class=\"sw\" style=\"background:" + escape(styles_.of(method).colour) + "\"></span>";
  }

  void writeHead() {
    const std::string name = campaign_.directory.empty() ? "(campaign built in memory)" : campaign_.directory;
    out_ << pageHead("stepcal report: " + name);
    out_ << "<h1>stepcal calibration report</h1>\n<nav><a href=\"#overview\">overview</a>"
         << (campaign_.sessions.empty() ? "" : "<a href=\"#campaigns\">campaigns</a>")
         << "<a href=\"#convergence\">step 1 convergence</a><a href=\"#geometry\">geometric errors</a>"
            "<a href=\"#loads\">errors per load</a><a href=\"#against-load\">error vs load</a>"
            "<a href=\"#distribution\">error distribution</a><a href=\"#workspace\">error in the workspace</a>"
            "<a href=\"#coverage\">coverage</a>"
            "<a href=\"#stiffness\">stiffness</a><a href=\"#gpr\">GPR</a>"
            "<a href=\"#accuracy\">accuracy table</a></nav>\n";
  }

  void writeOverview() {
    out_ << "<h2 id=\"overview\">Overview</h2>\n<table>\n";
    const std::string name = campaign_.directory.empty() ? "(campaign built in memory)" : campaign_.directory;
    out_ << "<tr><th class=\"l\">campaign</th><td class=\"l\">" << escape(name) << "</td></tr>\n";
    out_ << "<tr><th class=\"l\">robot</th><td class=\"l\">" << escape(campaign_.robot_file) << ": "
         << outcome_.nominal_Base.dof() << " joints, " << escape(campaign_.base_link) << " &#8594; "
         << escape(campaign_.tip_link) << ", F/T sensor "
         << (campaign_.sensor_link.empty() ? "none" : escape(campaign_.sensor_link)) << "</td></tr>\n";
    out_ << "<tr><th class=\"l\">tracker noise</th><td class=\"l\">"
         << format("%.4f mm, %.4f° per axis (1&#963;)", campaign_.tracker.position_sigma_m * kMmPerM,
                   campaign_.tracker.orientation_sigma_rad * kDegPerRad)
         << (campaign_.tracker.stated ? "" : ", not stated in campaign.yaml: assumed") << "</td></tr>\n";
    out_ << "<tr><th class=\"l\">noise floor</th><td class=\"l\">"
         << format("mean %.4f mm, %.4f°", outcome_.floor_position_m * kMmPerM,
                   outcome_.floor_orientation_rad * kDegPerRad)
         << ": the mean error the tracker noise alone gives (dashed line in the figures)</td></tr>\n";
    out_ << "<tr><th class=\"l\">fit time</th><td class=\"l\">"
         << format("geometry %.3f s, stiffness %.3f s, GPR %.3f s", outcome_.seconds_geometry,
                   outcome_.seconds_stiffness, outcome_.seconds_gpr)
         << "</td></tr>\n</table>\n";

    std::map<double, int> all_loads;
    std::map<RowSet, std::map<double, int>> counts;
    for (const Measurement& m : campaign_.rows) {
      ++counts[m.set][m.load_kg];
      all_loads[m.load_kg] = 0;
    }
    out_ << "<table>\n<tr><th class=\"l\">rows</th>";
    for (const auto& [load, unused] : all_loads) out_ << "<th>" << loadLabel(load) << "</th>";
    out_ << "<th>total</th></tr>\n";
    for (const auto& [set, per_load] : counts) {
      int total = 0;
      out_ << "<tr><td class=\"l\">" << toString(set) << "</td>";
      for (const auto& [load, unused] : all_loads) {
        const auto it = per_load.find(load);
        out_ << "<td>" << (it == per_load.end() ? "<span class=\"muted\">&#8211;</span>" : std::to_string(it->second))
             << "</td>";
        if (it != per_load.end()) total += it->second;
      }
      out_ << "<td>" << total << "</td></tr>\n";
    }
    out_ << "<tr><td class=\"l\"><b>all</b></td>";
    for (const auto& [load, unused] : all_loads) {
      int total = 0;
      for (const auto& [set, per_load] : counts) {
        const auto it = per_load.find(load);
        if (it != per_load.end()) total += it->second;
      }
      out_ << "<td>" << total << "</td>";
    }
    out_ << "<td><b>" << campaign_.rows.size() << "</b></td></tr>\n</table>\n";
  }

  // A merged campaign's sessions: their frames, fits and validation errors, and whether a joint
  // frame differs between them.
  void writeCampaigns() {
    if (campaign_.sessions.empty()) return;
    out_ << "<h2 id=\"campaigns\">Campaigns fitted together</h2>\n<p>One geometry of the joint "
            "frames and one compliance for the robot; each campaign its own tracker registration "
            "and tool (target).</p>\n<table>\n<tr><th class=\"l\">campaign</th><th>rows</th>"
            "<th>fit rows</th><th>fit rms mm</th><th class=\"l\">base in its tracker (m)</th>"
            "<th>tool from 1st, mm / °</th>";
    const std::vector<std::string> methods = calibratedMethods();
    for (const std::string& m : methods) out_ << "<th>" << swatch(m) << escape(m) << ", validation mm</th>";
    out_ << "</tr>\n";
    for (size_t k = 0; k < campaign_.sessions.size(); ++k) {
      const SessionSummary summary = sessionSummary(outcome_, k);
      const Vec3 p = summary.X_TrackerBase.translation();
      out_ << "<tr><td class=\"l\">" << k + 1 << " " << escape(campaign_.sessions[k].directory)
           << "</td><td>" << campaign_.sessions[k].row_count << "</td><td>"
           << outcome_.poe.sessions[k].fit_rows << "</td><td>"
           << cell("%.4f", outcome_.poe.sessions[k].rms_position_m * kMmPerM) << "</td><td class=\"l\">"
           << format("(%.4f, %.4f, %.4f)", p.x(), p.y(), p.z()) << "</td><td>"
           << (k == 0 ? std::string("&#8211;")
                      : format("%.3f / %.4f", summary.tool_offset_m * kMmPerM, summary.tool_angle_rad * kDegPerRad))
           << "</td>";
      for (const std::string& m : methods) {
        const double mean =
            trainer::pooledMeanPosition(outcome_.session_accuracy[k], m, RowSet::kValidation);
        out_ << "<td>" << cell("%.4f", mean * kMmPerM) << "</td>";
      }
      out_ << "</tr>\n";
    }
    out_ << "</table>\n<p>Per joint frame, whether one value serves every campaign: held out (5 "
            "folds of each campaign's poses), every frame shared against this one each campaign's "
            "own; named above z = 2.326, kept per campaign in the fit only when it also removes at "
            "least " << format("%.0f", 100.0 * trainer::kSessionDifferenceLeastShare)
         << " % of the held-out error with every frame shared (a change of the robot removes most "
            "of it). Each campaign against the first, fitted on every row with "
            "this frame each campaign's own, ± 1-σ: the rotation about the joint's axis is its "
            "zero.</p>\n<table>\n<tr><th class=\"l\">frame</th><th>own frames remove, mm</th>"
            "<th>z</th><th class=\"l\"></th><th class=\"l\">each campaign against the first</th></tr>\n";
    for (const trainer::SessionDifference& d : outcome_.session_differences) {
      std::vector<std::string> against_first;
      for (size_t s = 1; s < d.against_first.size(); ++s) {
        against_first.push_back(frameDifferenceText(campaign_, d, s));
      }
      writeDifferenceRow(d.name, d.held_out_gain_m, d.z_statistic, frameVerdictText(d), against_first);
    }
    out_ << "</table>\n<p>" << escape(ownFramesText(outcome_)) << ".</p>\n";
    writeCompliances();
  }

  // Whether one compliance of each joint serves every campaign.
  void writeCompliances() {
    const trainer::ComplianceDifferences& all = outcome_.compliance_differences;
    out_ << "<p>Per joint compliance, whether one value serves every campaign: held out (5 folds "
            "of each campaign's loaded poses), every compliance shared against this one each "
            "campaign's own; named above z = 2.326. Step 2 keeps one compliance per joint.</p>\n";
    for (const std::string& line : untestedComplianceLines(campaign_, all)) {
      out_ << "<p>" << escape(line) << ".</p>\n";
    }
    if (all.joints.empty()) return;
    out_ << "<table>\n<tr><th class=\"l\">joint</th><th>own compliances remove, mm</th><th>z</th>"
            "<th class=\"l\"></th><th class=\"l\">each campaign against the first</th></tr>\n";
    for (const trainer::ComplianceDifference& d : all.joints) {
      std::vector<std::string> against_first;
      for (size_t s = 1; s < d.difference_rad_per_nm.size(); ++s) {
        against_first.push_back(complianceDifferenceText(campaign_, all, d, s));
      }
      writeDifferenceRow(d.joint, d.held_out_gain_m, d.z_statistic,
                         d.significant ? "differs" : "one serves all", against_first);
    }
    out_ << "</table>\n";
  }

  // A row of a held-out test between the campaigns: what was tested, the held-out gain (m), z,
  // the verdict and each campaign against the first.
  void writeDifferenceRow(const std::string& name, double gain_m, double z, const std::string& verdict,
                          const std::vector<std::string>& against_first) {
    out_ << "<tr><td class=\"l\">" << escape(name) << "</td><td>" << cell("%.4f", gain_m * kMmPerM)
         << "</td><td>" << format("%.1f", z) << "</td><td class=\"l\">" << escape(verdict)
         << "</td><td class=\"l\">";
    for (size_t s = 0; s < against_first.size(); ++s) {
      out_ << (s > 0 ? "<br>" : "") << escape(against_first[s]);
    }
    out_ << "</td></tr>\n";
  }

  void writeConvergence() {
    const trainer::GeometricResult& poe = outcome_.poe;
    out_ << "<h2 id=\"convergence\">Step 1: convergence of the geometric calibration (cf. Fig. 5)</h2>\n";
    out_ << "<p>Local POE on " << poe.fit_rows << " geometry rows: "
         << (poe.converged ? "converged" : "<b>not converged</b>") << " after " << poe.iterations
         << " iterations; identification matrix rank " << poe.observability.rank << " of "
         << poe.observability.parameter_count
         << format(", condition number %.3g.", poe.observability.condition_number) << "</p>\n";
    Series position{"rms position error (fit rows)", styles_.of(trainer::kMethodPoe), {}, {}};
    Series orientation{"rms orientation error (fit rows)", styles_.of(trainer::kMethodPoe), {}, {}};
    for (const trainer::IterationRecord& h : poe.history) {
      position.x.push_back(h.iteration);
      position.y.push_back(h.rms_position_m * kMmPerM);
      orientation.x.push_back(h.iteration);
      orientation.y.push_back(h.rms_orientation_rad * kDegPerRad);
    }
    const Panel position_panel{"Step 1: rms position error per iteration", "iteration",
                               "rms position error (mm)", Scale::kLog, true, {position}, {}};
    const Panel orientation_panel{"Step 1: rms orientation error per iteration", "iteration",
                                  "rms orientation error (°)", Scale::kLog, true, {orientation}, {}};
    out_ << "<figure><div class=\"panels\">\n" << renderPanel(position_panel, marker_ids_.next())
         << (has_orientation_ ? renderPanel(orientation_panel, marker_ids_.next()) : "")
         << "</div><figcaption>Iteration 0 is the nominal chain with the tracker registered; the "
            "last point is the final state.</figcaption></figure>\n";
    if (!poe.observability.unobservable.empty()) {
      out_ << "<details><summary>" << poe.observability.unobservable.size()
           << " parameter combinations the data cannot observe (kept at their nominal values)"
              "</summary><ul>\n";
      for (const trainer::UnobservableCombination& u : poe.observability.unobservable) {
        out_ << "<li>" << escape(u.description) << (u.structural ? " <span class=\"muted\">(structural)</span>" : "")
             << "</li>\n";
      }
      out_ << "</ul></details>\n";
    }
  }

  void writeGeometricValidation() {
    out_ << "<h2 id=\"geometry\">Geometric calibration on the unloaded validation rows (cf. Fig. 6)</h2>\n";
    const auto unloaded = validation_by_load_.find(0.0);
    if (unloaded == validation_by_load_.end()) {
      out_ << "<p class=\"muted\">The campaign has no unloaded validation rows.</p>\n";
      return;
    }
    std::string caption = format("Each point is one of the %zu unloaded validation rows, in campaign order "
                                 "(log scale). Mean: ", unloaded->second.size());
    caption += meansAt({trainer::kMethodNominal, trainer::kMethodFrames, trainer::kMethodPoe}, 0.0);
    const trainer::AccuracySummary* nominal = summaryOf(trainer::kMethodNominal, RowSet::kValidation, 0.0);
    const trainer::AccuracySummary* poe = summaryOf(trainer::kMethodPoe, RowSet::kValidation, 0.0);
    if (nominal && poe && nominal->mean_position_m > 0.0) {
      caption += format(". Step 1 removes %.2f %% of the mean position error",
                         100.0 * (1.0 - poe->mean_position_m / nominal->mean_position_m));
      if (nominal->mean_orientation_rad > 0.0) {
        caption += format(" and %.2f %% of the orientation error",
                          100.0 * (1.0 - poe->mean_orientation_rad / nominal->mean_orientation_rad));
      }
      caption += " (paper: 91.87 % and 98.75 %)";
    }
    caption += ". nominal: nominal URDF, tracker registered; frames: tracker and tool frames fitted; "
               "poe: every initial pose fitted.";
    writePerPointFigure("class=\"geometry\"", "Unloaded",
                        {trainer::kMethodNominal, trainer::kMethodFrames, trainer::kMethodPoe},
                        unloaded->second, caption);
  }

  void writeLoadedValidation() {
    out_ << "<h2 id=\"loads\">Every method on the validation rows of each load (cf. Fig. 9 and 10)</h2>\n";
    const std::vector<std::string> methods = calibratedMethods();
    for (const auto& [load, rows] : validation_by_load_) {
      const std::string caption =
          format("%s: %zu validation rows, each point one row in campaign order (log scale). Mean: ",
                 loadLabel(load).c_str(), rows.size()) +
          meansAt(methods, load) + ".";
      writePerPointFigure(format("class=\"per-load\" id=\"load-%gkg\"", load), loadLabel(load), methods,
                          rows, caption);
    }
  }

  void writeErrorAgainstLoad() {
    out_ << "<h2 id=\"against-load\">Mean validation error against load</h2>\n";
    if (validation_by_load_.size() < 2) {
      out_ << "<p class=\"muted\">The validation rows have fewer than two loads: nothing to plot "
              "against load.</p>\n";
      return;
    }
    std::vector<Series> position, orientation;
    for (const std::string& method : calibratedMethods()) {
      Series p{method, styles_.of(method), {}, {}}, o = p;
      for (const auto& [load, rows] : validation_by_load_) {
        const trainer::AccuracySummary* s = summaryOf(method, RowSet::kValidation, load);
        if (!s) continue;
        p.x.push_back(load);
        p.y.push_back(s->mean_position_m * kMmPerM);
        o.x.push_back(load);
        o.y.push_back(s->rows_with_orientation > 0 ? s->mean_orientation_rad * kDegPerRad : NAN);
      }
      position.push_back(std::move(p));
      orientation.push_back(std::move(o));
    }
    const Panel position_panel{"Mean position error vs load", "payload (kg)", "mean position error (mm)",
                               Scale::kLog, false, position, positionFloor()};
    const Panel orientation_panel{"Mean orientation error vs load", "payload (kg)",
                                  "mean orientation error (°)", Scale::kLog, false, orientation,
                                  orientationFloor()};
    out_ << "<figure><div class=\"panels\">\n" << renderPanel(position_panel, marker_ids_.next())
         << (has_orientation_ ? renderPanel(orientation_panel, marker_ids_.next()) : "")
         << "</div><figcaption>The paper's claim: poe+gpr degrades as the load grows, while taking the "
            "deflection out with the stiffness model first (poe+stiffness+gpr) keeps the error flat. "
            "Loads outside the training range (e.g. 55 kg) test extrapolation.</figcaption></figure>\n";
  }

  /// Box plots of the validation rows' errors, a group per load and a row per calibrated method.
  BoxPlot errorDistribution(bool orientation) const {
    BoxPlot plot{orientation ? "Orientation error of the validation rows" : "Position error of the validation rows",
                 orientation ? "orientation error (°, log scale)" : "position error (mm, log scale)",
                 Scale::kLog, {}, {}, orientation ? orientationFloor() : positionFloor()};
    for (const auto& [load, rows] : validation_by_load_) {
      BoxGroup group{format("%s: %zu rows", loadLabel(load).c_str(), rows.size()), {}};
      for (const Series& s : perPointSeries(calibratedMethods(), rows, orientation)) {
        group.rows.push_back({s.label, s.style.colour, s.y});
      }
      plot.groups.push_back(std::move(group));
    }
    return plot;
  }

  void writeErrorDistribution() {
    out_ << "<h2 id=\"distribution\">Distribution of the error per load and method</h2>\n";
    if (validation_by_load_.empty()) {
      out_ << "<p class=\"muted\">The campaign has no validation rows.</p>\n";
      return;
    }
    out_ << "<figure><div class=\"panels\">\n" << renderBoxPlot(errorDistribution(false))
         << (has_orientation_ ? renderBoxPlot(errorDistribution(true)) : "")
         << "</div><figcaption>Every validation row (never fitted) of each load. Box: the middle half of the "
            "rows; black bar: the median; whiskers: 5th to 95th percentile; dot: the largest error; dashed: "
            "the noise floor.</figcaption></figure>\n";
  }

  /// The last calibrated method with row errors: the whole hierarchy where the campaign has all steps.
  std::string finalMethod() const {
    const std::vector<std::string> methods = calibratedMethods();
    for (const char* method : {trainer::kMethodPoeStiffnessGpr, trainer::kMethodPoeGpr, trainer::kMethodPoeStiffness}) {
      if (std::find(methods.begin(), methods.end(), method) != methods.end()) return method;
    }
    return methods.empty() ? "" : methods.back();
  }

  /// Top and side view of the tips of some rows, coloured by a method's position error; the colour
  /// scale's top (mm) is appended to `scales`.
  void writeWorkspaceViews(const std::string& method, const std::string& rows_label,
                           const std::vector<size_t>& rows, std::string& scales) {
    const std::vector<trainer::RowError>* errors = errorsOf(method);
    if (!errors || rows.empty()) return;
    // Tip positions from the nominal chain: the robot's own base frame, good to millimetres.
    std::vector<double> x_mm, y_mm, z_mm, radius_mm, error_mm;
    ChainWorkspace ws;
    for (const size_t i : rows) {
      forwardKinematics(outcome_.nominal_Base, campaign_.rows[i].q_rad, ws);
      const Vec3 p = tipPose(ws).translation() * kMmPerM;
      x_mm.push_back(p.x());
      y_mm.push_back(p.y());
      z_mm.push_back(p.z());
      radius_mm.push_back(std::hypot(p.x(), p.y()));
      error_mm.push_back((*errors)[i].position_m * kMmPerM);
    }
    // The colour scale tops out at the 95th percentile, so that a few large errors do not wash out
    // where the rest lie.
    std::vector<double> sorted = error_mm;
    std::sort(sorted.begin(), sorted.end());
    const double top = sorted[static_cast<size_t>(0.95 * static_cast<double>(sorted.size() - 1))];
    const double value_max = top > 0.0 ? top : 1.0;
    scales += format("%s<b>%s</b> %.3f mm", scales.empty() ? "" : ", ", escape(method).c_str(), value_max);
    const std::string title = method + ", " + rows_label;
    out_ << renderColourScatter({title + ": top view", "x (mm), base frame", "y (mm), base frame",
                                 "position error (mm)", x_mm, y_mm, error_mm, value_max})
         << renderColourScatter({title + ": side view", "distance from the base's z axis (mm)", "z (mm), base frame",
                                 "position error (mm)", radius_mm, z_mm, error_mm, value_max});
  }

  void writeWorkspaceMap() {
    out_ << "<h2 id=\"workspace\">Where in the workspace the error lives</h2>\n";
    std::vector<size_t> rows;
    for (const auto& [load, at_load] : validation_by_load_) rows.insert(rows.end(), at_load.begin(), at_load.end());
    if (rows.empty()) {
      out_ << "<p class=\"muted\">The campaign has no validation rows.</p>\n";
      return;
    }
    // The geometric model on the unloaded rows only: under load its error is the deflection,
    // which would hide where the geometry is wrong.
    const auto unloaded = validation_by_load_.find(0.0);
    std::string scales;
    out_ << "<figure><div class=\"panels\">\n";
    if (finalMethod() != trainer::kMethodPoe) {
      const std::string loads =
          validation_by_load_.size() > 1 ? "every load" : loadLabel(validation_by_load_.begin()->first);
      writeWorkspaceViews(finalMethod(), loads, rows, scales);
    }
    if (unloaded != validation_by_load_.end()) {
      writeWorkspaceViews(trainer::kMethodPoe, loadLabel(0.0), unloaded->second, scales);
    }
    out_ << "</div><figcaption>Each dot is a validation row at its tip position, coloured by its position error; "
            "the largest are drawn on top. The colour scale tops out at the 95th percentile of each map ("
         << scales << "); larger errors get the top colour. Tip positions from the nominal chain in the robot's "
            "base frame, on axes of equal scale.</figcaption></figure>\n";
  }

  void writeCoverage() {
    out_ << "<h2 id=\"coverage\">What the model covers</h2>\n";
    constexpr double kCoveredWithinDeg = 5.0;
    StripChart chart{"Joint angles of the fit rows and of the validation rows", "joint angle (deg)", 2, {}};
    const int joints = outcome_.nominal_Base.dof();
    std::set<double> fit_loads, uncovered_loads;
    int uncovered_rows = 0, validation_rows = 0;
    std::vector<bool> uncovered(campaign_.rows.size(), false);
    for (const Measurement& m : campaign_.rows) {
      if (m.set != RowSet::kValidation) fit_loads.insert(m.load_kg);
    }
    for (int j = 0; j < joints; ++j) {
      StripSeries fit{"fit rows", "#7f7f7f", 0, {}}, inside{"validation rows", "#1f77b4", 1, {}},
          outside{format("validation rows farther than %g° from every fit row", kCoveredWithinDeg), "#d62728", 1, {}};
      for (const Measurement& m : campaign_.rows) {
        if (m.set != RowSet::kValidation) fit.values.push_back(m.q_rad(j) * kDegPerRad);
      }
      std::sort(fit.values.begin(), fit.values.end());
      for (size_t i = 0; i < campaign_.rows.size(); ++i) {
        const Measurement& m = campaign_.rows[i];
        if (m.set != RowSet::kValidation) continue;
        const double q_deg = m.q_rad(j) * kDegPerRad;
        const auto above = std::lower_bound(fit.values.begin(), fit.values.end(), q_deg);
        const bool covered = (above != fit.values.end() && *above - q_deg <= kCoveredWithinDeg) ||
                             (above != fit.values.begin() && q_deg - *std::prev(above) <= kCoveredWithinDeg);
        (covered ? inside : outside).values.push_back(q_deg);
        uncovered[i] = uncovered[i] || !covered;
      }
      chart.rows.push_back({format("joint %d", j + 1), {fit, inside, outside}});
    }
    for (size_t i = 0; i < campaign_.rows.size(); ++i) {
      const Measurement& m = campaign_.rows[i];
      if (m.set != RowSet::kValidation) continue;
      ++validation_rows;
      uncovered_rows += uncovered[i];
      if (!fit_loads.count(m.load_kg)) uncovered_loads.insert(m.load_kg);
    }
    std::string loads;
    for (const double load : uncovered_loads) loads += (loads.empty() ? "" : ", ") + loadLabel(load);
    out_ << "<figure>" << renderStrips(chart)
         << format("<figcaption>Each tick is one row's angle: top lane the rows the model was fitted on (every "
                   "set but validation), bottom lane the validation rows, red where no fit row lies within %g°. "
                   "%d of %d validation rows have a joint outside the fit rows' angles",
                   kCoveredWithinDeg, uncovered_rows, validation_rows)
         << (loads.empty() ? std::string("; every validation load was fitted.")
                           : "; validation loads no fit row has (extrapolation): " + loads + ".")
         << "</figcaption></figure>\n";
  }

  void writeStiffness() {
    out_ << "<h2 id=\"stiffness\">Step 2: joint stiffness (cf. Fig. 7)</h2>\n";
    if (!outcome_.has_stiffness) {
      out_ << "<p class=\"muted\">Skipped: the campaign has no loaded/unloaded stiffness pairs with a "
              "sensor_link.</p>\n";
      return;
    }
    const trainer::StiffnessResult& k = outcome_.stiffness;
    out_ << format("<p>Identified on %d loaded/unloaded pairs; rms residual of the fitted deflections "
                   "%.4f mm.</p>\n", k.pairs, k.rms_position_residual_m * kMmPerM);
    out_ << "<table>\n<tr><th class=\"l\">joint</th><th>K<sub>&#952;</sub> (N&#183;m/rad)</th>"
            "<th>&#177;1&#963;</th><th>&#963;/K</th><th>max |&#964;| (N&#183;m)</th>"
            "<th class=\"l\">status</th></tr>\n";
    for (const trainer::JointCompliance& j : k.joints) {
      out_ << "<tr" << (j.excited ? "" : " class=\"muted\"") << "><td class=\"l\">" << escape(j.joint)
           << "</td>";
      if (j.excited) {
        out_ << format("<td>%.0f</td><td>%.0f</td><td>%.1f %%</td>", j.stiffness_nm_per_rad,
                       j.stiffness_sigma_nm_per_rad,
                       100.0 * j.stiffness_sigma_nm_per_rad / j.stiffness_nm_per_rad);
      } else {
        out_ << "<td>&#8211;</td><td>&#8211;</td><td>&#8211;</td>";
      }
      out_ << format("<td>%.1f</td>", j.max_torque_nm) << "<td class=\"l\">"
           << (j.excited ? "identified"
                         : "not identified: too little torque from these loads, taken as rigid")
           << "</td></tr>\n";
    }
    out_ << "</table>\n";
    if (outcome_.stiffness_validation.empty()) {
      out_ << "<p class=\"muted\">No validation pairs to check the stiffness model on.</p>\n";
      return;
    }
    BarChart chart{"Modelled vs measured deflection on validation pairs", "payload", "deviation (%)", {},
                   {{"mean deviation", "#ff7f0e", {}}, {"max deviation", "#fdbf6f", {}}}};
    out_ << "<p>Check on the validation pairs: modelled against measured tip deflection (cf. Fig. 7).</p>\n"
            "<div class=\"panels\"><table>\n<tr><th>load</th><th>pairs</th><th>mean deflection (mm)</th>"
            "<th>mean deviation</th><th>max deviation</th></tr>\n";
    for (const trainer::StiffnessValidation& v : outcome_.stiffness_validation) {
      chart.categories.push_back(loadLabel(v.load_kg));
      chart.bars[0].values.push_back(v.mean_deviation_pct);
      chart.bars[1].values.push_back(v.max_deviation_pct);
      out_ << "<tr><td>" << loadLabel(v.load_kg) << "</td><td>" << v.pairs << "</td>"
           << format("<td>%.3f</td><td>%.1f %%</td><td>%.1f %%</td></tr>\n", v.mean_deflection_m * kMmPerM,
                     v.mean_deviation_pct, v.max_deviation_pct);
    }
    out_ << "</table>\n<figure class=\"bars\">" << renderBars(chart)
         << "<figcaption>|&#916;p<sub>model</sub> &#8722; &#916;p<sub>measured</sub>| / "
            "|&#916;p<sub>measured</sub>| per load (paper: mean 11.9 / 11.3 / 11.4 %, max 28.6 / 27.9 "
            "/ 28.4 % at 20 / 30 / 40 kg).</figcaption></figure></div>\n";
  }

  void writeGpr() {
    out_ << "<h2 id=\"gpr\">Step 3: Gaussian process regression of the residual</h2>\n";
    struct Fitted {
      std::string method;
      const trainer::ResidualModel* model;
    };
    std::vector<Fitted> fitted;
    if (outcome_.gpr) {
      fitted.push_back({outcome_.has_stiffness ? trainer::kMethodPoeStiffnessGpr : trainer::kMethodPoeGpr,
                        &*outcome_.gpr});
    }
    if (outcome_.gpr_baseline) fitted.push_back({trainer::kMethodPoeGpr, &*outcome_.gpr_baseline});
    if (fitted.empty()) {
      out_ << "<p class=\"muted\">Skipped: no GP was fitted.</p>\n";
      return;
    }
    out_ << "<p>Hyperparameters in normalised input and standardised output units. A short length "
            "scale &#8467; means the residual varies quickly along that input; one near the upper "
            "bound means the input is irrelevant.</p>\n";
    const Eigen::Index inputs = fitted.front().model->gp.inputDim();
    const int joints = outcome_.nominal_Base.dof();
    const char* const wrench_names[] = {"F<sub>x</sub>", "F<sub>y</sub>", "F<sub>z</sub>",
                                        "M<sub>x</sub>", "M<sub>y</sub>", "M<sub>z</sub>"};
    out_ << "<table>\n<tr><th class=\"l\">GP of</th><th>training rows</th><th>log ML</th>"
            "<th>&#963;<sub>n</sub></th><th>&#963;<sub>f</sub></th>";
    for (Eigen::Index d = 0; d < inputs; ++d) {
      out_ << "<th>&#8467; ";
      if (d < joints) {
        out_ << "q<sub>" << d + 1 << "</sub>";
      } else if (d - joints < 6) {
        out_ << wrench_names[d - joints];
      } else {
        out_ << "x<sub>" << d + 1 << "</sub>";
      }
      out_ << "</th>";
    }
    out_ << "</tr>\n";
    for (const Fitted& f : fitted) {
      const trainer::GprHyperparameters& h = f.model->gp.hyperparameters();
      out_ << "<tr><td class=\"l\">" << swatch(f.method) << escape(f.method) << "</td><td>"
           << f.model->training_rows << " " << escape(f.model->training_set) << "</td>"
           << format("<td>%.1f</td><td>%.4g</td><td>%.4g</td>", f.model->gp.logMarginalLikelihood(),
                     h.noise_sigma, h.signal_sigma);
      for (Eigen::Index d = 0; d < h.length_scales.size(); ++d) out_ << format("<td>%.3g</td>", h.length_scales(d));
      out_ << "</tr>\n";
    }
    out_ << "</table>\n";

    out_ << "<p>10-fold cross-validation rms error per output of the residual twist &#958; = (v, &#969;)"
            " (v in mm, &#969; in degrees):</p>\n<table>\n<tr><th class=\"l\">GP of</th>"
            "<th>v<sub>x</sub></th><th>v<sub>y</sub></th><th>v<sub>z</sub></th><th>&#969;<sub>x</sub></th>"
            "<th>&#969;<sub>y</sub></th><th>&#969;<sub>z</sub></th></tr>\n";
    for (const Fitted& f : fitted) {
      const Eigen::VectorXd& mse = f.model->report.cv_mse;
      out_ << "<tr><td class=\"l\">" << swatch(f.method) << escape(f.method) << "</td>";
      for (Eigen::Index o = 0; o < 6; ++o) {
        out_ << "<td>" << (o < mse.size() ? cell("%.4f", std::sqrt(mse(o)) * (o < 3 ? kMmPerM : kDegPerRad)) : "&#8211;")
             << "</td>";
      }
      out_ << "</tr>\n";
    }
    out_ << "</table>\n";
  }

  void writeAccuracyTable() {
    out_ << "<h2 id=\"accuracy\">Accuracy of every method</h2>\n<p>Mean and max position error (mm), mean "
            "orientation error (°) per set and load; validation rows (shaded) are never fitted.</p>\n";
    std::vector<std::string> methods;
    for (const trainer::AccuracySummary& s : outcome_.accuracy) {
      if (std::find(methods.begin(), methods.end(), s.method) == methods.end()) methods.push_back(s.method);
    }
    std::map<std::pair<int, double>, std::map<std::string, const trainer::AccuracySummary*>> table;
    for (const trainer::AccuracySummary& s : outcome_.accuracy) {
      table[{static_cast<int>(s.set), s.load_kg}][s.method] = &s;
    }
    out_ << "<table class=\"dense\">\n<tr><th class=\"l\" rowspan=\"2\">set</th><th rowspan=\"2\">load</th>"
            "<th rowspan=\"2\">rows</th>";
    for (const std::string& m : methods) {
      out_ << "<th class=\"g\" colspan=\"3\">" << swatch(m) << escape(m) << "</th>";
    }
    out_ << "</tr>\n<tr>";
    for (size_t i = 0; i < methods.size(); ++i) out_ << "<th class=\"g\">mean mm</th><th>max mm</th><th>mean °</th>";
    out_ << "</tr>\n";
    for (const auto& [key, by_method] : table) {
      const trainer::AccuracySummary& any = *by_method.begin()->second;
      out_ << "<tr class=\"" << toString(any.set) << "\"><td class=\"l\">" << toString(any.set) << "</td><td>"
           << loadLabel(any.load_kg)
           << "</td><td>" << any.rows << "</td>";
      for (const std::string& m : methods) {
        const auto it = by_method.find(m);
        if (it == by_method.end()) {
          out_ << "<td class=\"g\">&#8211;</td><td>&#8211;</td><td>&#8211;</td>";
          continue;
        }
        const trainer::AccuracySummary& s = *it->second;
        out_ << "<td class=\"g\">" << cell("%.4f", s.mean_position_m * kMmPerM) << "</td><td>"
             << cell("%.4f", s.max_position_m * kMmPerM) << "</td><td>"
             << cell("%.4f", s.mean_orientation_rad * kDegPerRad) << "</td>";
      }
      out_ << "</tr>\n";
    }
    out_ << "</table>\n<p class=\"muted\">nominal: nominal URDF, tracker registered (closed form); frames: "
            "tracker and tool frames fitted; poe: every initial pose fitted (step 1); +stiffness: joint "
            "compliance (step 2); +gpr: Gaussian process on the residual (step 3).</p>\n";
  }

  const Campaign& campaign_;
  const trainer::CalibrationOutcome& outcome_;
  MethodStyles styles_;
  std::map<double, std::vector<size_t>> validation_by_load_;  ///< indices into campaign.rows
  bool has_orientation_ = false;  ///< some row measured the tip's orientation
  std::ostringstream out_;
  MarkerIds marker_ids_;
};

}  // namespace

std::string htmlReport(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  return PageWriter(campaign, outcome).write();
}

}  // namespace stepcal::report
