#include "svg_frame.hpp"

#include <algorithm>
#include <cmath>

#include "stepcal/report/html/page.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report::html {
namespace {

/// 1, 2 or 5 × 10^k nearest above raw.
double niceStep(double raw) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / magnitude;
  return (f <= 1.0 ? 1.0 : f <= 2.0 ? 2.0 : f <= 5.0 ? 5.0 : 10.0) * magnitude;
}

/// Ticks at the multiples of a round step inside [lo, hi].
std::vector<double> linearTicks(double lo, double hi, double step) {
  std::vector<double> ticks;
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) {
    ticks.push_back(std::abs(v) < 1e-9 * step ? 0.0 : v);
  }
  return ticks;
}

/// Legend entries placed left to right, wrapping before kPanelWidth.
struct LegendLayout {
  std::vector<std::pair<double, int>> x_and_line;  ///< per entry: left edge and line number
  int lines = 0;
};

LegendLayout layoutLegend(const std::vector<LegendEntry>& entries, double left) {
  LegendLayout layout;
  double x = left;
  int line = 0;
  for (const LegendEntry& e : entries) {
    const double width = 22.0 + textWidth(e.label) + 12.0;
    if (x + width > kPanelWidth - kMarginRight && x > left) {
      x = left;
      ++line;
    }
    layout.x_and_line.emplace_back(x, line);
    x += width;
  }
  layout.lines = entries.empty() ? 0 : line + 1;
  return layout;
}

}  // namespace

bool showable(Scale scale, double v) { return std::isfinite(v) && (scale == Scale::kLinear || v > 0.0); }

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
  axis.ticks = linearTicks(axis.lo, axis.hi, step);
  return axis;
}

Axis exactAxis(double lo, double hi) {
  Axis axis;
  axis.lo = lo;
  axis.hi = hi;
  axis.ticks = linearTicks(lo, hi, niceStep((hi - lo) / 5.0));
  return axis;
}

double textWidth(std::string_view text) {
  double characters = 0.0;
  for (const char c : text) characters += (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  return 6.2 * characters;
}

std::string fitted(const std::string& text, double width) {
  if (textWidth(text) <= width) return text;
  std::string out;
  for (const char c : text) {
    if (textWidth(out) + 2 * 6.2 > width && (static_cast<unsigned char>(c) & 0xC0) != 0x80) break;
    out += c;
  }
  return out + "\u2026";
}

double labelColumnWidth(const std::vector<std::string>& labels) {
  double widest = 0.0;
  for (const std::string& label : labels) widest = std::max(widest, textWidth(label));
  return std::min(kMaxLabelWidth, widest + 14.0);
}

std::string categoryLabel(const std::string& label, double x, double y, double width) {
  const std::string shown = fitted(label, width - 10.0);
  std::string out = format("<text class=\"cat\" x=\"%.1f\" y=\"%.1f\">", x, y) + escape(shown);
  if (shown != label) out += "<title>" + escape(label) + "</title>";
  return out + "</text>";
}

std::vector<LegendEntry> boxEntries(const std::vector<LegendKey>& keys) {
  std::vector<LegendEntry> entries;
  for (const LegendKey& k : keys) entries.push_back({k.label, k.colour, LegendSymbol::kBox, ""});
  return entries;
}

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

void extend(double& lo, double& hi, double v) {
  lo = std::isnan(lo) ? v : std::min(lo, v);
  hi = std::isnan(hi) ? v : std::max(hi, v);
}

std::vector<LegendEntry> referenceEntries(Scale scale, const std::vector<ReferenceLine>& references) {
  std::vector<LegendEntry> entries;
  for (const ReferenceLine& r : references) {
    if (showable(scale, r.value)) entries.push_back({r.label, "", LegendSymbol::kDashedLine, ""});
  }
  return entries;
}

SvgFrame::SvgFrame(std::ostringstream& out, const std::string& title, const std::vector<LegendEntry>& legend,
                 const FrameLayout& layout)
  : out_(out), left_(layout.left), right_(kPanelWidth - layout.right_margin) {
  const LegendLayout legend_layout = layoutLegend(legend, std::min(left_, kMarginLeft));
  top_ = kTitleHeight + legend_layout.lines * kLegendLineHeight + 10.0;
  bottom_ = top_ + layout.plot_height;
  height_ = bottom_ + kMarginBottom;
  out_ << format("<svg class=\"chart\" xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
                 "viewBox=\"0 0 %.0f %.0f\" role=\"img\" aria-label=\"",
                 kPanelWidth, height_, kPanelWidth, height_)
       << escape(title) << "\">\n";
  out_ << format("<text class=\"title\" x=\"%.1f\" y=\"15\">", std::min(left_, kMarginLeft))
       << escape(title) << "</text>\n";
  for (size_t i = 0; i < legend.size(); ++i) {
    const LegendEntry& e = legend[i];
    const double x = legend_layout.x_and_line[i].first;
    const double y = kTitleHeight + 8.0 + legend_layout.x_and_line[i].second * kLegendLineHeight;
    const std::string colour = escape(e.colour);
    switch (e.symbol) {
      case LegendSymbol::kLineAndMarker:
        out_ << format("<path d=\"M%.1f %.1fh9h9\" stroke=\"", x, y) << colour
             << "\" stroke-width=\"1.5\" marker-mid=\"url(#" << e.marker_id << ")\"/>";
        break;
      case LegendSymbol::kMarker:
        out_ << format("<path d=\"M%.1f %.1fh9h9\" stroke=\"none\" marker-mid=\"url(#", x, y) << e.marker_id
             << ")\"/>";
        break;
      case LegendSymbol::kLine:
        out_ << format("<path d=\"M%.1f %.1fh18\" stroke-width=\"2\" stroke=\"", x, y) << colour << "\"/>";
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

}  // namespace stepcal::report::html
