#include "report_html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <map>
#include <sstream>
#include <string_view>
#include <vector>

#include "stepcal/common/error.hpp"
#include "text_format.hpp"

namespace stepcal::cli {
namespace {

constexpr double kMm = 1e3;
constexpr double kDeg = 180.0 / 3.14159265358979323846;

/// Text made safe for HTML element content and attribute values.
std::string escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

/// A number for a table cell; "–" when it is not finite (no orientation measured).
std::string cell(const char* fmt, double value) {
  return std::isfinite(value) ? format(fmt, value) : "&#8211;";
}

std::string loadLabel(double load_kg) { return format("%g kg", load_kg); }

// ------------------------------------------------------------------------------------------
// Plotting: hand-written SVG panels (line/marker plots and grouped bars) with axes, ticks,
// grid and a legend. Coordinates are SVG pixels; one panel is kPanelWidth wide.

constexpr double kPanelWidth = 660.0;  ///< px
constexpr double kPlotHeight = 250.0;  ///< height of the data area, px
constexpr double kMarginLeft = 64.0, kMarginRight = 18.0, kMarginBottom = 42.0;  ///< px
constexpr double kTitleHeight = 22.0, kLegendLineHeight = 16.0;                  ///< px

enum class Scale { kLinear, kLog };

/// The marker drawn at every point of a series, so that series that overlap stay apart.
enum class MarkerShape { kCircle, kSquare, kTriangle, kDiamond };

/// How a series looks: the same for a method in every figure.
struct SeriesStyle {
  std::string colour;
  MarkerShape marker = MarkerShape::kCircle;
};

/// A polyline through (x, y) with a marker at every point; points the axes cannot show (not
/// finite, or ≤ 0 on a log axis) break the line.
struct Series {
  std::string label;
  SeriesStyle style;
  std::vector<double> x, y;
  bool connected = true;  ///< false: markers only (a scatter plot)
};

/// A dashed horizontal line across the panel, e.g. the noise floor.
struct ReferenceLine {
  std::string label;
  double y = 0.0;
};

/// A line/marker plot: linear x, linear or log y.
struct Panel {
  std::string title;
  std::string x_label, y_label;
  Scale y_scale = Scale::kLinear;
  bool integer_x = false;  ///< x ticks at whole numbers only (point index, iteration)
  std::vector<Series> series;
  std::vector<ReferenceLine> references;
};

/// One bar per category, in one colour.
struct BarSeries {
  std::string label;
  std::string colour;
  std::vector<double> values;
};

/// Bars grouped by category on a linear axis from zero.
struct BarChart {
  std::string title, x_label, y_label;
  std::vector<std::string> categories;
  std::vector<BarSeries> bars;
};

/// Whether an axis of this scale can show v.
bool showable(Scale scale, double v) { return std::isfinite(v) && (scale == Scale::kLinear || v > 0.0); }

/// A data range mapped onto pixels, with its labelled and unlabelled tick values.
struct Axis {
  Scale scale = Scale::kLinear;
  double lo = 0.0, hi = 1.0;        ///< data units
  std::vector<double> ticks;        ///< labelled, with a grid line
  std::vector<double> minor_ticks;  ///< grid line only (2..9 × 10^k on a log axis)
  double pixel_lo = 0.0, pixel_hi = 1.0;  ///< px where lo and hi go

  bool shows(double v) const { return showable(scale, v); }
  double toPixel(double v) const {
    const double t = scale == Scale::kLog
                         ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo))
                         : (v - lo) / (hi - lo);
    return pixel_lo + t * (pixel_hi - pixel_lo);
  }
};

/// 1, 2 or 5 × 10^k nearest above raw.
double niceStep(double raw) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / magnitude;
  return (f <= 1.0 ? 1.0 : f <= 2.0 ? 2.0 : f <= 5.0 ? 5.0 : 10.0) * magnitude;
}

/// An axis covering [min, max] (NaN when there are no data) with rounded ends.
Axis makeAxis(Scale scale, double min, double max, bool integer_step) {
  Axis axis;
  axis.scale = scale;
  if (scale == Scale::kLog) {
    if (!(min > 0.0 && max >= min)) min = max = 1.0;
    const int lo_exp = static_cast<int>(std::floor(std::log10(min) + 1e-9));
    int hi_exp = static_cast<int>(std::ceil(std::log10(max) - 1e-9));
    if (hi_exp <= lo_exp) hi_exp = lo_exp + 1;
    axis.lo = std::pow(10.0, lo_exp);
    axis.hi = std::pow(10.0, hi_exp);
    for (int e = lo_exp; e <= hi_exp; ++e) {
      const double decade = std::pow(10.0, e);
      axis.ticks.push_back(decade);
      if (e == hi_exp) break;
      for (int k = 2; k <= 9; ++k) {
        const bool labelled = hi_exp - lo_exp == 1 && (k == 2 || k == 5);
        (labelled ? axis.ticks : axis.minor_ticks).push_back(k * decade);
      }
    }
    std::sort(axis.ticks.begin(), axis.ticks.end());
    return axis;
  }
  if (!(max >= min)) min = 0.0, max = 1.0;
  if (max == min) {
    const double pad = min == 0.0 ? 1.0 : 0.1 * std::abs(min);
    max += pad;
    if (min != 0.0) min -= pad;
  }
  double step = niceStep((max - min) / 5.0);
  if (integer_step) step = std::max(step, 1.0);
  axis.lo = std::floor(min / step + 1e-9) * step;
  axis.hi = std::ceil(max / step - 1e-9) * step;
  const int intervals = static_cast<int>(std::lround((axis.hi - axis.lo) / step));
  for (int i = 0; i <= intervals; ++i) {
    const double v = axis.lo + i * step;
    axis.ticks.push_back(std::abs(v) < 1e-9 * step ? 0.0 : v);
  }
  return axis;
}

/// Rough width of 11 px sans-serif text (UTF-8 continuation bytes do not count).
double textWidth(std::string_view text) {
  double characters = 0.0;
  for (const char c : text) characters += (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  return 6.2 * characters;
}

enum class LegendSymbol { kLineAndMarker, kDashedLine, kBox };

struct LegendEntry {
  std::string label;
  std::string colour;
  LegendSymbol symbol = LegendSymbol::kLineAndMarker;
  std::string marker_id;  ///< kLineAndMarker: the series' marker
};

/// An SVG marker of the given shape in the style's colour, about 6 px across; squares are hollow so
/// that a marker drawn over one leaves its outline visible.
std::string markerDefinition(const std::string& id, const SeriesStyle& style) {
  const std::string fill = " fill=\"" + escape(style.colour) + "\"/>";
  std::string shape;
  switch (style.marker) {
    case MarkerShape::kCircle: shape = "<circle r=\"2.5\"" + fill; break;
    case MarkerShape::kSquare:
      shape = "<rect x=\"-3\" y=\"-3\" width=\"6\" height=\"6\" fill=\"none\" stroke-width=\"1.2\" stroke=\"" +
              escape(style.colour) + "\"/>";
      break;
    case MarkerShape::kTriangle: shape = "<path d=\"M0 -3.2L3 2.2H-3Z\"" + fill; break;
    case MarkerShape::kDiamond: shape = "<path d=\"M0 -3.3L3 0L0 3.3L-3 0Z\"" + fill; break;
  }
  return "<marker id=\"" + id +
         "\" viewBox=\"-4 -4 8 8\" markerWidth=\"8\" markerHeight=\"8\" "
         "markerUnits=\"userSpaceOnUse\">" + shape + "</marker>";
}

/// Legend entries placed left to right, wrapping before kPanelWidth.
struct LegendLayout {
  std::vector<std::pair<double, int>> x_and_line;  ///< per entry: left edge and line number
  int lines = 0;
};

LegendLayout layoutLegend(const std::vector<LegendEntry>& entries) {
  LegendLayout layout;
  double x = kMarginLeft;
  int line = 0;
  for (const LegendEntry& e : entries) {
    const double width = 22.0 + textWidth(e.label) + 12.0;
    if (x + width > kPanelWidth - kMarginRight && x > kMarginLeft) {
      x = kMarginLeft;
      ++line;
    }
    layout.x_and_line.emplace_back(x, line);
    x += width;
  }
  layout.lines = entries.empty() ? 0 : line + 1;
  return layout;
}

/// The frame of a panel: svg element, title, legend, grid, ticks and axis labels. Data are
/// drawn between construction and end(), in the rectangle [left, right] × [top, bottom] (px).
class SvgFrame {
 public:
  SvgFrame(std::ostringstream& out, const std::string& title, const std::vector<LegendEntry>& legend)
      : out_(out) {
    const LegendLayout layout = layoutLegend(legend);
    top_ = kTitleHeight + layout.lines * kLegendLineHeight + 10.0;
    bottom_ = top_ + kPlotHeight;
    height_ = bottom_ + kMarginBottom;
    out_ << format("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
                   "viewBox=\"0 0 %.0f %.0f\" role=\"img\" aria-label=\"",
                   kPanelWidth, height_, kPanelWidth, height_)
         << escape(title) << "\">\n";
    out_ << format("<text class=\"title\" x=\"%.1f\" y=\"15\">", kMarginLeft) << escape(title)
         << "</text>\n";
    for (size_t i = 0; i < legend.size(); ++i) {
      const LegendEntry& e = legend[i];
      const double x = layout.x_and_line[i].first;
      const double y = kTitleHeight + 8.0 + layout.x_and_line[i].second * kLegendLineHeight;
      const std::string colour = escape(e.colour);
      switch (e.symbol) {
        case LegendSymbol::kLineAndMarker:
          out_ << format("<path d=\"M%.1f %.1fh9h9\" stroke=\"", x, y) << colour
               << "\" stroke-width=\"1.5\" marker-mid=\"url(#" << e.marker_id << ")\"/>";
          break;
        case LegendSymbol::kDashedLine:
          out_ << format("<path class=\"ref\" d=\"M%.1f %.1fh18\"/>", x, y);
          break;
        case LegendSymbol::kBox:
          out_ << format("<rect x=\"%.1f\" y=\"%.1f\" width=\"14\" height=\"10\" fill=\"", x + 2.0,
                         y - 5.0)
               << colour << "\"/>";
          break;
      }
      out_ << format("<text x=\"%.1f\" y=\"%.1f\">", x + 22.0, y + 4.0) << escape(e.label)
           << "</text>\n";
    }
  }

  double left() const { return kMarginLeft; }
  double right() const { return kPanelWidth - kMarginRight; }
  double top() const { return top_; }
  double bottom() const { return bottom_; }

  /// Grid lines, tick labels and the y axis title for a value axis along y.
  void drawYAxis(const Axis& y, const std::string& label) {
    out_ << "<path class=\"minor\" d=\"";
    for (const double v : y.minor_ticks) out_ << format("M%.1f %.1fH%.1f", left(), y.toPixel(v), right());
    out_ << "\"/>\n<path class=\"grid\" d=\"";
    for (const double v : y.ticks) out_ << format("M%.1f %.1fH%.1f", left(), y.toPixel(v), right());
    out_ << "\"/>\n<g class=\"ty\">";
    for (const double v : y.ticks) {
      out_ << format("<text x=\"%.1f\" y=\"%.1f\">%g</text>", left() - 5.0, y.toPixel(v) + 4.0, v);
    }
    out_ << "</g>\n";
    out_ << format("<text class=\"axis\" transform=\"translate(14 %.1f) rotate(-90)\">",
                   0.5 * (top() + bottom()))
         << escape(label) << "</text>\n";
  }

  /// Grid lines, tick labels and the x axis title for a value axis along x.
  void drawXAxis(const Axis& x, const std::string& label) {
    out_ << "<path class=\"grid\" d=\"";
    for (const double v : x.ticks) out_ << format("M%.1f %.1fV%.1f", x.toPixel(v), top(), bottom());
    out_ << "\"/>\n<g class=\"tx\">";
    for (const double v : x.ticks) {
      out_ << format("<text x=\"%.1f\" y=\"%.1f\">%g</text>", x.toPixel(v), bottom() + 15.0, v);
    }
    out_ << "</g>\n";
    drawXTitle(label);
  }

  void drawXTitle(const std::string& label) {
    out_ << format("<text class=\"axis\" x=\"%.1f\" y=\"%.1f\">", 0.5 * (left() + right()),
                   height_ - 8.0)
         << escape(label) << "</text>\n";
  }

  /// The plot area's border and the closing tag.
  void end() {
    out_ << format("<rect class=\"frame\" x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\"/>\n",
                   left(), top(), right() - left(), bottom() - top());
    out_ << "</svg>\n";
  }

  /// A note in the middle of an empty plot area.
  void drawNote(const std::string& note) {
    out_ << format("<text class=\"note\" x=\"%.1f\" y=\"%.1f\">", 0.5 * (left() + right()),
                   0.5 * (top() + bottom()))
         << escape(note) << "</text>\n";
  }

 private:
  std::ostringstream& out_;
  double top_ = 0.0, bottom_ = 0.0, height_ = 0.0;
};

/// The page's head and the opening of its body, with the report's style sheet.
std::string pageHead(const std::string& title) {
  std::ostringstream out;
  out << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>"
      << escape(title) << "</title>\n<style>\n"
      << "body{font:14px/1.45 system-ui,-apple-system,'Segoe UI',sans-serif;color:#222;max-width:1360px;"
            "margin:20px auto;padding:0 16px}\n"
            "h1{font-size:22px;margin:0 0 8px}h2{font-size:18px;margin:30px 0 8px;padding-bottom:3px;"
            "border-bottom:1px solid #ddd}\n"
            "nav a{margin-right:12px}p{max-width:1000px}\n"
            "table{border-collapse:collapse;font-variant-numeric:tabular-nums;margin:6px 0}\n"
            "th,td{padding:3px 9px;border-bottom:1px solid #eee;text-align:right}"
            "th{background:#f5f5f5;font-weight:600}.l{text-align:left}\n"
            "table.dense{font-size:12.5px}.dense th,.dense td{padding:2px 5px}.dense td{white-space:nowrap}"
            ".dense .g{border-left:1px solid #ddd}"
            ".dense tr.validation td{background:#f4f8fc}\n"
            ".muted{color:#999}.item{white-space:nowrap}.sw{display:inline-block;width:10px;height:10px;border-radius:2px;"
            "margin-right:4px}\n"
            "figure{margin:10px 0 18px}figcaption{color:#555;font-size:13px;max-width:1320px}\n"
            ".panels{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start}.bars{margin:0;max-width:660px}\n"
            "svg{font:11px sans-serif;background:#fff}svg .title{font-size:13px;font-weight:600}\n"
            "svg .grid{stroke:#e2e2e2;fill:none}svg .minor{stroke:#f3f3f3;fill:none}"
            "svg .frame{fill:none;stroke:#444}\n"
            "svg .ty text{text-anchor:end}svg .tx,svg .tx text,svg .axis,svg .note{text-anchor:middle}"
            "svg .axis{font-size:12px}svg .note{fill:#999}\n"
            "svg .ref{stroke:#333;stroke-width:1.2;stroke-dasharray:5 4;fill:none}"
            "svg .series{fill:none;stroke-width:1.1;stroke-opacity:.85}\n"
      << "</style>\n</head>\n<body>\n";
  return out.str();
}

/// Renders a line/marker panel. Its markers get ids marker_id + series index: marker_id must
/// be a prefix unique in the page.
std::string renderPanel(const Panel& panel, const std::string& marker_id) {
  double x_min = NAN, x_max = NAN, y_min = NAN, y_max = NAN;
  auto extend = [](double& lo, double& hi, double v) {
    lo = std::isnan(lo) ? v : std::min(lo, v);
    hi = std::isnan(hi) ? v : std::max(hi, v);
  };
  bool has_data = false;
  for (const Series& s : panel.series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !showable(panel.y_scale, s.y[i])) continue;
      extend(x_min, x_max, s.x[i]);
      extend(y_min, y_max, s.y[i]);
      has_data = true;
    }
  }
  std::vector<LegendEntry> legend;
  for (size_t k = 0; k < panel.series.size(); ++k) {
    const Series& s = panel.series[k];
    legend.push_back({s.label, s.style.colour, LegendSymbol::kLineAndMarker, marker_id + std::to_string(k)});
  }
  std::vector<const ReferenceLine*> references;
  for (const ReferenceLine& r : panel.references) {
    if (!showable(panel.y_scale, r.y)) continue;
    references.push_back(&r);
    legend.push_back({r.label, "", LegendSymbol::kDashedLine, ""});
    if (has_data) extend(y_min, y_max, r.y);
  }

  std::ostringstream out;
  SvgFrame frame(out, panel.title, legend);
  out << "<defs>";
  for (size_t k = 0; k < panel.series.size(); ++k) {
    out << markerDefinition(marker_id + std::to_string(k), panel.series[k].style);
  }
  out << "</defs>\n";
  if (!has_data) {
    frame.drawXTitle(panel.x_label);
    frame.drawNote("no data");
    frame.end();
    return out.str();
  }
  Axis x = makeAxis(Scale::kLinear, x_min, x_max, panel.integer_x);
  x.pixel_lo = frame.left();
  x.pixel_hi = frame.right();
  Axis y = makeAxis(panel.y_scale, y_min, y_max, false);
  y.pixel_lo = frame.bottom();
  y.pixel_hi = frame.top();
  frame.drawYAxis(y, panel.y_label);
  frame.drawXAxis(x, panel.x_label);

  for (const ReferenceLine* r : references) {
    out << format("<path class=\"ref\" d=\"M%.1f %.1fH%.1f\"/>\n", frame.left(), y.toPixel(r->y),
                  frame.right());
  }
  for (size_t k = 0; k < panel.series.size(); ++k) {
    const Series& s = panel.series[k];
    const std::string marker = "url(#" + marker_id + std::to_string(k) + ")";
    out << "<g class=\"series\" stroke=\"" << escape(s.style.colour) << "\" marker-start=\"" << marker
        << "\" marker-mid=\"" << marker << "\" marker-end=\"" << marker << "\">";
    bool open = false;
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !y.shows(s.y[i])) {
        if (open) out << "\"/>";
        open = false;
        continue;
      }
      out << (open ? " " : "<polyline points=\"")
          << format("%.1f,%.1f", x.toPixel(s.x[i]), y.toPixel(s.y[i]));
      open = s.connected;
      if (!open) out << "\"/>";
    }
    if (open) out << "\"/>";
    out << "</g>\n";
  }
  frame.end();
  return out.str();
}

/// Renders grouped bars (one group per category) on a linear axis from zero, values on top.
std::string renderBars(const BarChart& chart) {
  std::vector<LegendEntry> legend;
  double y_max = 0.0;
  for (const BarSeries& b : chart.bars) {
    legend.push_back({b.label, b.colour, LegendSymbol::kBox, ""});
    for (const double v : b.values) {
      if (std::isfinite(v)) y_max = std::max(y_max, v);
    }
  }
  std::ostringstream out;
  SvgFrame frame(out, chart.title, legend);
  Axis y = makeAxis(Scale::kLinear, 0.0, y_max * 1.12, false);
  y.pixel_lo = frame.bottom();
  y.pixel_hi = frame.top();
  frame.drawYAxis(y, chart.y_label);
  frame.drawXTitle(chart.x_label);
  const double group_width = (frame.right() - frame.left()) / std::max<size_t>(chart.categories.size(), 1);
  const double bar_width =
      std::min(36.0, 0.7 * group_width / std::max<size_t>(chart.bars.size(), 1));
  for (size_t c = 0; c < chart.categories.size(); ++c) {
    const double centre = frame.left() + (c + 0.5) * group_width;
    out << format("<text class=\"tx\" x=\"%.1f\" y=\"%.1f\">", centre, frame.bottom() + 15.0)
        << escape(chart.categories[c]) << "</text>\n";
    for (size_t b = 0; b < chart.bars.size(); ++b) {
      const double v = chart.bars[b].values[c];
      if (!std::isfinite(v)) continue;
      const double x = centre + (b - 0.5 * chart.bars.size()) * bar_width;
      const double top = y.toPixel(v);
      out << format("<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"", x + 1.0,
                    top, bar_width - 2.0, frame.bottom() - top)
          << escape(chart.bars[b].colour) << "\"/>"
          << format("<text class=\"tx\" x=\"%.1f\" y=\"%.1f\">%.1f</text>\n", x + 0.5 * bar_width,
                    top - 4.0, v);
    }
  }
  frame.end();
  return out.str();
}

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
    }
  }

  std::string write() {
    writeHead();
    writeOverview();
    writeConvergence();
    writeGeometricValidation();
    writeLoadedValidation();
    writeErrorAgainstLoad();
    writeStiffness();
    writeGpr();
    writeAccuracyTable();
    out_ << "</body>\n</html>\n";
    return out_.str();
  }

 private:
  std::string nextMarkerId() { return "m" + std::to_string(marker_ids_++) + "-"; }

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
        s.y.push_back(orientation ? (campaign_.rows[rows[k]].has_orientation ? e.orientation_rad * kDeg : NAN)
                                  : e.position_m * kMm);
      }
      series.push_back(std::move(s));
    }
    return series;
  }

  std::vector<ReferenceLine> positionFloor() const {
    return {{format("noise floor %.4f mm", outcome_.floor_position_m * kMm), outcome_.floor_position_m * kMm}};
  }
  std::vector<ReferenceLine> orientationFloor() const {
    return {{format("noise floor %.4f°", outcome_.floor_orientation_rad * kDeg),
             outcome_.floor_orientation_rad * kDeg}};
  }

  /// A figure of the two per-point panels (position, orientation) of some methods on some rows.
  void writePerPointFigure(const std::string& figure_attributes, const std::string& title,
                           const std::vector<std::string>& methods, const std::vector<size_t>& rows,
                           const std::string& caption) {
    Panel position{title + ": position error", "validation point", "position error (mm)",
                   Scale::kLog, true, perPointSeries(methods, rows, false), positionFloor()};
    Panel orientation{title + ": orientation error", "validation point", "orientation error (°)",
                      Scale::kLog, true, perPointSeries(methods, rows, true), orientationFloor()};
    out_ << "<figure " << figure_attributes << "><div class=\"panels\">\n"
         << renderPanel(position, nextMarkerId()) << renderPanel(orientation, nextMarkerId())
         << "</div><figcaption>" << caption << "</figcaption></figure>\n";
  }

  /// "poe 0.4300 mm / 0.0160°, …": mean validation errors of methods at one load.
  std::string meansAt(const std::vector<std::string>& methods, double load_kg) const {
    std::string text;
    for (const std::string& method : methods) {
      const trainer::AccuracySummary* s = summaryOf(method, RowSet::kValidation, load_kg);
      if (!s) continue;
      text += (text.empty() ? "<span class=\"item\">" : ", <span class=\"item\">") + swatch(method) + "<b>" +
              escape(method) + "</b> " + format("%.4f mm", s->mean_position_m * kMm);
      if (s->rows_with_orientation > 0) text += format(" / %.4f°", s->mean_orientation_rad * kDeg);
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
            "<a href=\"#convergence\">step 1 convergence</a><a href=\"#geometry\">geometric errors</a>"
            "<a href=\"#loads\">errors per load</a><a href=\"#against-load\">error vs load</a>"
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
         << format("%.4f mm, %.4f° per axis (1&#963;)", campaign_.tracker.position_sigma_m * kMm,
                   campaign_.tracker.orientation_sigma_rad * kDeg)
         << (campaign_.tracker.stated ? "" : ", not stated in campaign.yaml: assumed") << "</td></tr>\n";
    out_ << "<tr><th class=\"l\">noise floor</th><td class=\"l\">"
         << format("mean %.4f mm, %.4f°", outcome_.floor_position_m * kMm,
                   outcome_.floor_orientation_rad * kDeg)
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
      position.y.push_back(h.rms_position_m * kMm);
      orientation.x.push_back(h.iteration);
      orientation.y.push_back(h.rms_orientation_rad * kDeg);
    }
    const Panel position_panel{"Step 1: rms position error per iteration", "iteration",
                               "rms position error (mm)", Scale::kLog, true, {position}, {}};
    const Panel orientation_panel{"Step 1: rms orientation error per iteration", "iteration",
                                  "rms orientation error (°)", Scale::kLog, true, {orientation}, {}};
    out_ << "<figure><div class=\"panels\">\n" << renderPanel(position_panel, nextMarkerId())
         << renderPanel(orientation_panel, nextMarkerId())
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
        p.y.push_back(s->mean_position_m * kMm);
        o.x.push_back(load);
        o.y.push_back(s->rows_with_orientation > 0 ? s->mean_orientation_rad * kDeg : NAN);
      }
      position.push_back(std::move(p));
      orientation.push_back(std::move(o));
    }
    const Panel position_panel{"Mean position error vs load", "payload (kg)", "mean position error (mm)",
                               Scale::kLog, false, position, positionFloor()};
    const Panel orientation_panel{"Mean orientation error vs load", "payload (kg)",
                                  "mean orientation error (°)", Scale::kLog, false, orientation,
                                  orientationFloor()};
    out_ << "<figure><div class=\"panels\">\n" << renderPanel(position_panel, nextMarkerId())
         << renderPanel(orientation_panel, nextMarkerId())
         << "</div><figcaption>The paper's claim: poe+gpr degrades as the load grows, while taking the "
            "deflection out with the stiffness model first (poe+stiffness+gpr) keeps the error flat. "
            "Loads outside the training range (e.g. 55 kg) test extrapolation.</figcaption></figure>\n";
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
                   "%.4f mm.</p>\n", k.pairs, k.rms_position_residual_m * kMm);
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
           << format("<td>%.3f</td><td>%.1f %%</td><td>%.1f %%</td></tr>\n", v.mean_deflection_m * kMm,
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
        out_ << "<td>" << (o < mse.size() ? cell("%.4f", std::sqrt(mse(o)) * (o < 3 ? kMm : kDeg)) : "&#8211;")
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
        out_ << "<td class=\"g\">" << cell("%.4f", s.mean_position_m * kMm) << "</td><td>"
             << cell("%.4f", s.max_position_m * kMm) << "</td><td>"
             << cell("%.4f", s.mean_orientation_rad * kDeg) << "</td>";
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
  std::ostringstream out_;
  int marker_ids_ = 0;
};

}  // namespace

std::string htmlReport(const Campaign& campaign, const trainer::CalibrationOutcome& outcome) {
  return PageWriter(campaign, outcome).write();
}

std::string diagnosisHtml(const Campaign& campaign, const trainer::Diagnosis& d) {
  const std::string name =
      campaign.directory.empty() ? "(campaign built in memory)" : campaign.directory;
  std::ostringstream out;
  out << pageHead("stepcal diagnosis: " + name);
  out << "<h1>stepcal diagnosis</h1>\n<p>" << escape(name) << ": " << d.fit_rows
      << " fit rows, " << d.validation_rows << " validation rows. Verdict: <b>"
      << toString(d.verdict) << "</b>";
  for (const trainer::FoundEffect& e : d.effects) out << "; " << escape(describe(e.mechanism));
  out << ".</p>\n";
  if (!d.unexplained_trend.empty()) {
    out << "<p>Structure no catalogued mechanism explains: " << escape(d.unexplained_trend)
        << "</p>\n";
  }

  // The telling variables: significant trends before the extension, else the strongest three.
  std::vector<std::string> telling;
  for (const trainer::TrendScore& t : d.before.trends) {
    if (t.significant || telling.size() < 3) telling.push_back(t.variable);
    if (telling.size() == 4) break;
  }
  out << "<h2>Residual of the physical model against the telling variables</h2>\n"
         "<p>Position error of every fit row (mm) before and after the extension; the trends are "
         "ranked by their cross-validated t statistic.</p>\n<div class=\"panels\">";
  const SeriesStyle before{"#d62728", MarkerShape::kCircle}, after{"#1f77b4", MarkerShape::kSquare};
  for (const std::string& variable : telling) {
    const auto it = std::find(d.variable_names.begin(), d.variable_names.end(), variable);
    if (it == d.variable_names.end()) continue;
    const std::vector<double>& x = d.variable_values[static_cast<size_t>(it - d.variable_names.begin())];
    Panel panel;
    panel.title = "position error against " + variable;
    panel.x_label = variable;
    panel.y_label = "mm";
    auto mm = [](const std::vector<double>& v) {
      std::vector<double> out;
      for (double e : v) out.push_back(e * kMm);
      return out;
    };
    panel.series.push_back({"physical model", before, x, mm(d.before.position_error_m), false});
    if (!d.effects.empty()) {
      panel.series.push_back({"extended", after, x, mm(d.after.position_error_m), false});
    }
    panel.references.push_back({"noise floor", d.floor_position_m * kMm});
    out << "<figure>" << renderPanel(panel, "m" + std::to_string(&variable - telling.data()))
        << "</figure>";
  }
  out << "</div>\n";

  out << "<h2>Candidates</h2>\n<div class=\"panels\">";
  int rounds = 0;
  for (const trainer::CandidateScore& c : d.candidates) rounds = std::max(rounds, c.round);
  for (int round = 1; round <= rounds; ++round) {
    std::vector<const trainer::CandidateScore*> in_round;
    for (const trainer::CandidateScore& c : d.candidates) {
      if (c.round == round) in_round.push_back(&c);
    }
    std::sort(in_round.begin(), in_round.end(),
              [](const auto* a, const auto* b) { return a->z_statistic > b->z_statistic; });
    BarChart chart;
    chart.title = format("round %d: the ten best of %zu candidates", round, in_round.size());
    chart.x_label = "candidate";
    chart.y_label = "held-out signed-rank z";
    BarSeries bars{"z (chosen one first among equals)", "#1f77b4", {}};
    for (size_t i = 0; i < in_round.size() && i < 10; ++i) {
      chart.categories.push_back(describe(in_round[i]->mechanism) +
                                 (in_round[i]->chosen ? " *" : ""));
      bars.values.push_back(in_round[i]->z_statistic);
    }
    chart.bars.push_back(bars);
    out << "<figure class=\"bars\">" << renderBars(chart) << "</figure>";
  }
  out << "</div>\n<p class=\"muted\">* chosen in that round.</p>\n";

  if (!d.gain.empty()) {
    out << "<h2>Gain on validation rows</h2>\n<table><tr><th>load</th><th>rows</th>"
           "<th>before mean mm</th><th>after mean mm</th><th>"
        << escape(d.gpr_method.empty() ? "(no GPR)" : d.gpr_method)
        << " mean mm</th><th>extended+gpr mean mm</th></tr>\n";
    for (const trainer::GainRow& g : d.gain) {
      out << "<tr><td>" << loadLabel(g.load_kg) << "</td><td>" << g.rows << "</td><td>"
          << cell("%.4f", g.before.mean_position_m * kMm) << "</td><td>"
          << cell("%.4f", g.after.mean_position_m * kMm) << "</td><td>"
          << (g.gpr.rows > 0 ? cell("%.4f", g.gpr.mean_position_m * kMm) : "&#8211;")
          << "</td><td>" << cell("%.4f", g.after_gpr.mean_position_m * kMm) << "</td></tr>\n";
    }
    out << "</table>\n";
  }
  out << "</body>\n</html>\n";
  return out.str();
}

}  // namespace stepcal::cli
