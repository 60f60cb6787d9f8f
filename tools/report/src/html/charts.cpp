#include "stepcal/report/html/charts.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <set>
#include <sstream>

#include "stepcal/report/html/page.hpp"
#include "stepcal/report/text_format.hpp"
#include "svg_frame.hpp"

namespace stepcal::report::html {
namespace {

/// The value at fraction p of sorted values, interpolated linearly.
double quantile(const std::vector<double>& sorted, double p) {
  const double at = p * static_cast<double>(sorted.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(at));
  const size_t above = std::min(below + 1, sorted.size() - 1);
  return sorted[below] + (at - static_cast<double>(below)) * (sorted[above] - sorted[below]);
}

/// Blue (t = 0) through pale yellow to red (t = 1).
std::string colourAt(double t) {
  static const double stops[][3] = {{44, 123, 182}, {171, 217, 233}, {255, 230, 140}, {253, 174, 97}, {215, 25, 28}};
  constexpr int kIntervals = static_cast<int>(std::size(stops)) - 1;
  t = std::clamp(t, 0.0, 1.0) * kIntervals;
  const int i = std::min(static_cast<int>(t), kIntervals - 1);
  const double f = t - i;
  int rgb[3];
  for (int c = 0; c < 3; ++c) rgb[c] = static_cast<int>(std::lround(stops[i][c] + f * (stops[i + 1][c] - stops[i][c])));
  return format("#%02x%02x%02x", rgb[0], rgb[1], rgb[2]);
}

}  // namespace

std::string renderPanel(const Panel& panel, const std::string& marker_id) {
  double x_min = NAN, x_max = NAN, y_min = NAN, y_max = NAN;
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
    const LegendSymbol symbol = !s.markers ? LegendSymbol::kLine
                                : s.connected ? LegendSymbol::kLineAndMarker
                                              : LegendSymbol::kMarker;
    legend.push_back({s.label, s.style.colour, symbol, marker_id + std::to_string(k)});
  }
  const std::vector<LegendEntry> references = referenceEntries(panel.y_scale, panel.references);
  legend.insert(legend.end(), references.begin(), references.end());
  for (const ReferenceLine& r : panel.references) {
    if (has_data && showable(panel.y_scale, r.value)) extend(y_min, y_max, r.value);
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

  for (const ReferenceLine& r : panel.references) {
    if (!y.shows(r.value)) continue;
    out << format("<path class=\"ref\" d=\"M%.1f %.1fH%.1f\"/>\n", frame.left(), y.toPixel(r.value),
                  frame.right());
  }
  for (size_t k = 0; k < panel.series.size(); ++k) {
    const Series& s = panel.series[k];
    out << "<g class=\"" << (s.markers ? "series" : "curve") << "\" stroke=\"" << escape(s.style.colour) << "\"";
    if (s.markers) {
      const std::string marker = "url(#" + marker_id + std::to_string(k) + ")";
      out << " marker-start=\"" << marker << "\" marker-mid=\"" << marker << "\" marker-end=\"" << marker << "\"";
    }
    out << ">";
    if (!s.connected) {
      // A scatter is one polyline with an invisible line and a marker at every point: a few bytes
      // per point for thousands of rows.
      out << "<polyline class=\"mark\" stroke=\"none\" points=\"";
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (std::isfinite(s.x[i]) && y.shows(s.y[i])) out << format(" %.1f,%.1f", x.toPixel(s.x[i]), y.toPixel(s.y[i]));
      }
      out << "\"/></g>\n";
      continue;
    }
    bool open = false;
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !y.shows(s.y[i])) {
        if (open) out << "\"/>";
        open = false;
        continue;
      }
      out << (open ? " " : "<polyline class=\"mark\" points=\"")
          << format("%.1f,%.1f", x.toPixel(s.x[i]), y.toPixel(s.y[i]));
      open = true;
    }
    if (open) out << "\"/>";
    out << "</g>\n";
  }
  frame.end();
  return out.str();
}

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
        << escape(fitted(chart.categories[c], group_width - 4.0)) << "</text>\n";
    for (size_t b = 0; b < chart.bars.size(); ++b) {
      const double v = chart.bars[b].values[c];
      if (!std::isfinite(v)) continue;
      const double x = centre + (b - 0.5 * chart.bars.size()) * bar_width;
      const double top = y.toPixel(v);
      out << format("<rect class=\"mark\" x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"", x + 1.0,
                    top, bar_width - 2.0, frame.bottom() - top)
          << escape(chart.bars[b].colour) << "\"/>"
          << format("<text class=\"tx\" x=\"%.1f\" y=\"%.1f\">%.1f</text>\n", x + 0.5 * bar_width,
                    top - 4.0, v);
    }
  }
  frame.end();
  return out.str();
}

std::string renderHorizontalBars(const HorizontalBarChart& chart) {
  std::vector<std::string> labels;
  double lo = 0.0, hi = 0.0;
  for (const Bar& b : chart.bars) {
    labels.push_back(b.label);
    if (std::isfinite(b.value)) lo = std::min(lo, b.value), hi = std::max(hi, b.value);
  }
  for (const ReferenceLine& r : chart.references) lo = std::min(lo, r.value), hi = std::max(hi, r.value);
  std::vector<LegendEntry> legend = boxEntries(chart.legend);
  const std::vector<LegendEntry> references = referenceEntries(Scale::kLinear, chart.references);
  legend.insert(legend.end(), references.begin(), references.end());

  FrameLayout layout;
  layout.left = labelColumnWidth(labels);
  layout.plot_height = kBarRowHeight * static_cast<double>(std::max<size_t>(chart.bars.size(), 1));
  std::ostringstream out;
  SvgFrame frame(out, chart.title, legend, layout);
  // Room right of the longest bar for its value and note.
  Axis x = makeAxis(Scale::kLinear, lo, hi + 0.3 * (hi - lo), false);
  x.pixel_lo = frame.left();
  x.pixel_hi = frame.right();
  frame.drawXAxis(x, chart.value_label);
  frame.drawXReferences(x, chart.references);
  const double zero = x.toPixel(0.0);
  for (size_t i = 0; i < chart.bars.size(); ++i) {
    const Bar& b = chart.bars[i];
    const double row_top = frame.top() + kBarRowHeight * static_cast<double>(i);
    const double text_y = row_top + 0.5 * kBarRowHeight + 4.0;
    const std::string weight = b.emphasised ? " font-weight=\"bold\"" : "";
    out << "<g" << weight << ">" << categoryLabel(b.label, frame.left() - 6.0, text_y, frame.left());
    if (std::isfinite(b.value)) {
      const double end = x.toPixel(b.value);
      out << format("<rect class=\"mark\" x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"",
                    std::min(zero, end), row_top + 3.0, std::max(std::abs(end - zero), 1.0), kBarRowHeight - 6.0)
          << escape(b.colour) << "\"/>"
          << format("<text x=\"%.1f\" y=\"%.1f\">", std::max(zero, end) + 4.0, text_y)
          << format(chart.value_format, b.value) << (b.note.empty() ? "" : "  " + escape(b.note)) << "</text>";
    }
    out << "</g>\n";
  }
  frame.end();
  return out.str();
}

std::string renderBoxPlot(const BoxPlot& plot) {
  std::vector<std::string> labels;
  double lo = NAN, hi = NAN;
  size_t rows = 0;
  for (const BoxGroup& g : plot.groups) {
    for (const BoxRow& r : g.rows) {
      labels.push_back(r.label);
      for (const double v : r.values) {
        if (showable(plot.scale, v)) extend(lo, hi, v);
      }
    }
    rows += g.rows.size();
  }
  for (const ReferenceLine& r : plot.references) {
    if (showable(plot.scale, r.value) && !std::isnan(lo)) extend(lo, hi, r.value);
  }
  std::vector<LegendEntry> legend = boxEntries(plot.legend);
  const std::vector<LegendEntry> references = referenceEntries(plot.scale, plot.references);
  legend.insert(legend.end(), references.begin(), references.end());

  FrameLayout layout;
  layout.left = std::max(kMarginLeft, labelColumnWidth(labels));
  layout.plot_height = kGroupRowHeight * static_cast<double>(plot.groups.size()) +
                       kBoxRowHeight * static_cast<double>(rows) + 4.0;
  std::ostringstream out;
  SvgFrame frame(out, plot.title, legend, layout);
  Axis x = makeAxis(plot.scale, lo, hi, false);
  x.pixel_lo = frame.left();
  x.pixel_hi = frame.right();
  frame.drawXAxis(x, plot.value_label);
  frame.drawXReferences(x, plot.references);
  double y = frame.top();
  for (const BoxGroup& g : plot.groups) {
    out << format("<text class=\"group\" x=\"%.1f\" y=\"%.1f\">", frame.left() + 6.0, y + 13.0) << escape(g.label)
        << "</text>\n";
    y += kGroupRowHeight;
    for (const BoxRow& r : g.rows) {
      const double centre = y + 0.5 * kBoxRowHeight;
      out << categoryLabel(r.label, frame.left() - 6.0, centre + 4.0, frame.left());
      std::vector<double> sorted;
      for (const double v : r.values) {
        if (showable(plot.scale, v)) sorted.push_back(v);
      }
      y += kBoxRowHeight;
      if (sorted.empty()) continue;
      std::sort(sorted.begin(), sorted.end());
      auto px = [&](double p) { return x.toPixel(quantile(sorted, p)); };
      const std::string colour = escape(r.colour);
      out << format("<path class=\"whisker\" d=\"M%.1f %.1fH%.1fM%.1f %.1fv6M%.1f %.1fv6\"/>", px(0.05), centre,
                    px(0.95), px(0.05), centre - 3.0, px(0.95), centre - 3.0)
          << format("<rect class=\"box mark\" x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"",
                    px(0.25), centre - 5.0, std::max(px(0.75) - px(0.25), 1.0), 10.0)
          << colour << "\"/>"
          << format("<path class=\"median\" d=\"M%.1f %.1fv10\"/>", px(0.5), centre - 5.0)
          << format("<circle class=\"dot\" cx=\"%.1f\" cy=\"%.1f\" r=\"2.5\" fill=\"", x.toPixel(sorted.back()), centre)
          << colour << "\"/>\n";
    }
  }
  frame.end();
  return out.str();
}

std::string renderColourScatter(const ColourScatter& chart) {
  double x_lo = NAN, x_hi = NAN, y_lo = NAN, y_hi = NAN;
  std::vector<size_t> shown;
  for (size_t i = 0; i < chart.x.size(); ++i) {
    if (!std::isfinite(chart.x[i]) || !std::isfinite(chart.y[i]) || !std::isfinite(chart.value[i])) continue;
    extend(x_lo, x_hi, chart.x[i]);
    extend(y_lo, y_hi, chart.y[i]);
    shown.push_back(i);
  }
  FrameLayout layout;
  layout.right_margin = kColourBarWidth;
  const double width = kPanelWidth - layout.right_margin - layout.left;
  constexpr double kMinHeight = 160.0, kMaxHeight = 420.0, kMinWidth = 200.0;
  std::ostringstream out;
  if (shown.empty()) {
    SvgFrame frame(out, chart.title, {}, layout);
    frame.drawXTitle(chart.x_label);
    frame.drawNote("no data");
    frame.end();
    return out.str();
  }
  // Equal scale on both axes: the workspace's shape is not distorted.
  const double pad = 0.05 * std::max({x_hi - x_lo, y_hi - y_lo, 1e-9});
  double x_span = x_hi - x_lo + 2 * pad, y_span = y_hi - y_lo + 2 * pad;
  const double px_per_unit = std::min(width / x_span, kMaxHeight / y_span);
  // The data area shrinks to the data's shape, down to kMinWidth × kMinHeight (then a span widens).
  const double plot_width = std::max(kMinWidth, x_span * px_per_unit);
  layout.right_margin = kPanelWidth - layout.left - plot_width;
  layout.plot_height = std::max(kMinHeight, y_span * px_per_unit);
  x_span = plot_width / px_per_unit;
  y_span = layout.plot_height / px_per_unit;
  const double x_mid = 0.5 * (x_lo + x_hi), y_mid = 0.5 * (y_lo + y_hi);
  SvgFrame frame(out, chart.title, {}, layout);
  Axis x = exactAxis(x_mid - 0.5 * x_span, x_mid + 0.5 * x_span);
  x.pixel_lo = frame.left();
  x.pixel_hi = frame.right();
  Axis y = exactAxis(y_mid - 0.5 * y_span, y_mid + 0.5 * y_span);
  y.pixel_lo = frame.bottom();
  y.pixel_hi = frame.top();
  frame.drawYAxis(y, chart.y_label);
  frame.drawXAxis(x, chart.x_label);
  std::sort(shown.begin(), shown.end(), [&](size_t a, size_t b) { return chart.value[a] < chart.value[b]; });
  for (const size_t i : shown) {
    out << format("<circle class=\"dot mark\" cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"%s\"/>", x.toPixel(chart.x[i]),
                  y.toPixel(chart.y[i]), colourAt(chart.value[i] / chart.value_max).c_str());
  }
  out << "\n";
  // The colour scale, bottom (zero) to top (value_max), in the right margin.
  constexpr int kSteps = 40;
  const double bar_x = frame.right() + 14.0, bar_height = std::min(180.0, frame.bottom() - frame.top());
  const double bar_top = frame.top() + 0.5 * (frame.bottom() - frame.top() - bar_height);
  for (int s = 0; s < kSteps; ++s) {
    out << format("<rect x=\"%.1f\" y=\"%.1f\" width=\"12\" height=\"%.2f\" fill=\"%s\"/>", bar_x,
                  bar_top + bar_height * (kSteps - 1 - s) / kSteps, bar_height / kSteps + 0.3,
                  colourAt((s + 0.5) / kSteps).c_str());
  }
  Axis scale = exactAxis(0.0, chart.value_max);
  for (const double v : scale.ticks) {
    out << format("<text x=\"%.1f\" y=\"%.1f\">%g</text>", bar_x + 16.0, bar_top + bar_height * (1.0 - v / chart.value_max) + 4.0, v);
  }
  out << format("<text class=\"axis\" transform=\"translate(%.1f %.1f) rotate(-90)\">", bar_x - 4.0,
                0.5 * (frame.top() + frame.bottom()))
      << escape(chart.value_label) << "</text>\n";
  frame.end();
  return out.str();
}

std::string renderStrips(const StripChart& chart) {
  std::vector<std::string> labels;
  std::vector<LegendEntry> legend;
  double lo = NAN, hi = NAN;
  for (const StripRow& row : chart.rows) {
    labels.push_back(row.label);
    for (const StripSeries& s : row.series) {
      for (const double v : s.values) {
        if (std::isfinite(v)) extend(lo, hi, v);
      }
      const bool listed = std::any_of(legend.begin(), legend.end(), [&](const LegendEntry& e) { return e.label == s.label; });
      if (!listed) legend.push_back({s.label, s.colour, LegendSymbol::kBox, ""});
    }
  }
  const double row_height = kLaneHeight * chart.lanes + kStripRowGap;
  FrameLayout layout;
  layout.left = std::max(kMarginLeft, labelColumnWidth(labels));
  layout.plot_height = row_height * static_cast<double>(chart.rows.size()) + kStripRowGap;
  std::ostringstream out;
  SvgFrame frame(out, chart.title, legend, layout);
  Axis x = makeAxis(Scale::kLinear, lo, hi, false);
  x.pixel_lo = frame.left();
  x.pixel_hi = frame.right();
  frame.drawXAxis(x, chart.x_label);
  for (size_t r = 0; r < chart.rows.size(); ++r) {
    const double row_top = frame.top() + kStripRowGap + row_height * static_cast<double>(r);
    out << categoryLabel(chart.rows[r].label, frame.left() - 6.0, row_top + 0.5 * kLaneHeight * chart.lanes + 4.0,
                         frame.left());
    for (const StripSeries& s : chart.rows[r].series) {
      if (s.values.empty()) continue;
      // One tick per half pixel: thousands of rows stay a few kilobytes.
      std::set<long> half_pixels;
      for (const double v : s.values) {
        if (std::isfinite(v)) half_pixels.insert(std::lround(2.0 * x.toPixel(v)));
      }
      out << "<path class=\"mark\" stroke=\"" << escape(s.colour) << "\" d=\"";
      for (const long h : half_pixels) {
        out << format("M%.1f %.1fv%.1f", 0.5 * static_cast<double>(h), row_top + kLaneHeight * s.lane + 1.0,
                      kLaneHeight - 2.0);
      }
      out << "\"/>\n";
    }
  }
  frame.end();
  return out.str();
}

}  // namespace stepcal::report::html
