// The frame every chart draws in (internal to stepcal::report): value axes with round ticks, the
// svg element with title, legend, grid, tick labels and axis titles, and text measures for
// laying out labels. Coordinates are SVG pixels.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "stepcal/report/html/charts.hpp"
#include "stepcal/report/html/page.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report::html {

inline constexpr double kPlotHeight = 250.0;  ///< height of a line plot's data area, px
inline constexpr double kMarginLeft = 64.0, kMarginRight = 18.0, kMarginBottom = 42.0;  ///< px
inline constexpr double kTitleHeight = 22.0, kLegendLineHeight = 16.0;                  ///< px
inline constexpr double kBarRowHeight = 18.0, kBoxRowHeight = 15.0, kGroupRowHeight = 18.0;  ///< px
inline constexpr double kLaneHeight = 9.0, kStripRowGap = 7.0;                           ///< px
inline constexpr double kMaxLabelWidth = 330.0;  ///< widest category label column, px
inline constexpr double kColourBarWidth = 74.0;  ///< right margin holding a colour scale, px

/// Whether an axis of this scale can show v.
bool showable(Scale scale, double v);

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

/// An axis covering [min, max] (NaN when there are no data) with rounded ends.
Axis makeAxis(Scale scale, double min, double max, bool integer_step);

/// A linear axis with exactly these ends (equal-scale plots), ticks at round values inside.
Axis exactAxis(double lo, double hi);

/// Rough width of 11 px sans-serif text (UTF-8 continuation bytes do not count).
double textWidth(std::string_view text);

/// The text cut at a character boundary with "…" so that it fits width px.
std::string fitted(const std::string& text, double width);

/// A category label column wide enough for the labels, within kMaxLabelWidth.
double labelColumnWidth(const std::vector<std::string>& labels);

/// A category label right-aligned before x; the full text as its tooltip when cut.
std::string categoryLabel(const std::string& label, double x, double y, double width);

enum class LegendSymbol { kLineAndMarker, kMarker, kLine, kDashedLine, kBox };

struct LegendEntry {
  std::string label;
  std::string colour;
  LegendSymbol symbol = LegendSymbol::kLineAndMarker;
  std::string marker_id;  ///< kLineAndMarker: the series' marker
};

/// A legend entry with a box for each key.
std::vector<LegendEntry> boxEntries(const std::vector<LegendKey>& keys);

/// An SVG marker of the given shape in the style's colour, about 6 px across; squares are hollow so
/// that a marker drawn over one leaves its outline visible.
std::string markerDefinition(const std::string& id, const SeriesStyle& style);

/// Where a panel's data area goes.
struct FrameLayout {
  double left = kMarginLeft;
  double right_margin = kMarginRight;
  double plot_height = kPlotHeight;
};

/// The frame of a panel: svg element, title, legend, grid, ticks and axis labels. Data are
/// drawn between construction and end(), in the rectangle [left, right] × [top, bottom] (px).
class SvgFrame {
 public:
  /// Writes the svg element, title and legend; the data area's height and left edge from layout.
  SvgFrame(std::ostringstream& out, const std::string& title, const std::vector<LegendEntry>& legend,
           const FrameLayout& layout = {});

  double left() const { return left_; }
  double right() const { return right_; }
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
    out_ << "<path class=\"minor\" d=\"";
    for (const double v : x.minor_ticks) out_ << format("M%.1f %.1fV%.1f", x.toPixel(v), top(), bottom());
    out_ << "\"/>\n<path class=\"grid\" d=\"";
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

  /// Vertical dashed lines at reference values of an x value axis.
  void drawXReferences(const Axis& x, const std::vector<ReferenceLine>& references) {
    for (const ReferenceLine& r : references) {
      if (!x.shows(r.value) || r.value < x.lo || r.value > x.hi) continue;
      out_ << format("<path class=\"ref\" d=\"M%.1f %.1fV%.1f\"/>\n", x.toPixel(r.value), top(), bottom());
    }
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
  double left_, right_;
  double top_ = 0.0, bottom_ = 0.0, height_ = 0.0;
};

/// Widens [lo, hi] (NaN: empty) to hold v.
void extend(double& lo, double& hi, double v);

/// Legend entries of the reference lines an axis of this scale can show.
std::vector<LegendEntry> referenceEntries(Scale scale, const std::vector<ReferenceLine>& references);

}  // namespace stepcal::report::html
