// The reports' charts as inline SVG (internal to stepcal::report): line/marker plots and scatter,
// grouped vertical bars, horizontal bars, horizontal box plots, a scatter coloured by a value
// and strips of ticks. Each is one <svg class="chart"> panel kPanelWidth wide with title, legend,
// axes and grid; its data elements carry class "mark" (pageEnd's check counts them).
#pragma once

#include <string>
#include <vector>

namespace stepcal::report::html {

inline constexpr double kPanelWidth = 660.0;  ///< px

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
  bool markers = true;    ///< false: the line alone (a fitted curve)
};

/// A dashed line across the panel at a value of the value axis, e.g. the noise floor.
struct ReferenceLine {
  std::string label;
  double value = 0.0;
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

/// Renders a line/marker panel. Its markers get ids marker_id + series index: marker_id must
/// be a prefix unique in the page (MarkerIds).
std::string renderPanel(const Panel& panel, const std::string& marker_id);

/// Marker id prefixes unique in one page, one per panel.
class MarkerIds {
 public:
  std::string next() { return "m" + std::to_string(next_++) + "-"; }

 private:
  int next_ = 0;
};

/// One bar per category, in one colour.
struct BarSeries {
  std::string label;
  std::string colour;
  std::vector<double> values;
};

/// Bars grouped by a few short categories (e.g. loads) on a linear axis from zero, values on top.
struct BarChart {
  std::string title, x_label, y_label;
  std::vector<std::string> categories;
  std::vector<BarSeries> bars;
};

std::string renderBars(const BarChart& chart);

/// A colour and what it means, for a legend.
struct LegendKey {
  std::string label;
  std::string colour;
};

/// One horizontal bar: its label on the left, its value (and a note) at its end.
struct Bar {
  std::string label;
  double value = 0.0;
  std::string colour;
  std::string note;  ///< after the value, e.g. "chosen"
  bool emphasised = false;  ///< label and value in bold
};

/// Horizontal bars from zero, one row each: long labels stay readable.
struct HorizontalBarChart {
  std::string title, value_label;
  std::vector<Bar> bars;
  std::vector<LegendKey> legend;
  std::vector<ReferenceLine> references;
  const char* value_format = "%.1f";
};

std::string renderHorizontalBars(const HorizontalBarChart& chart);

/// One distribution: a row of the box plot.
struct BoxRow {
  std::string label;
  std::string colour;
  std::vector<double> values;
};

/// Rows under a heading (e.g. the methods at one load).
struct BoxGroup {
  std::string label;
  std::vector<BoxRow> rows;
};

/// Horizontal box plots: per row the quartiles as a box, the median as a bar, whiskers from the
/// 5th to the 95th percentile and the largest value as a dot.
struct BoxPlot {
  std::string title, value_label;
  Scale scale = Scale::kLinear;
  std::vector<BoxGroup> groups;
  std::vector<LegendKey> legend;
  std::vector<ReferenceLine> references;
};

std::string renderBoxPlot(const BoxPlot& plot);

/// Points at (x, y) on axes of equal scale, coloured by value on a blue-to-red scale from zero to
/// value_max (larger values get the top colour; the largest are drawn last, on top).
struct ColourScatter {
  std::string title, x_label, y_label, value_label;
  std::vector<double> x, y, value;
  double value_max = 1.0;
};

std::string renderColourScatter(const ColourScatter& chart);

/// Ticks at values along a row's lane: a series is drawn in its lane of its row.
struct StripSeries {
  std::string label;
  std::string colour;
  int lane = 0;
  std::vector<double> values;
};

struct StripRow {
  std::string label;
  std::vector<StripSeries> series;
};

/// Rows of ticks on one linear axis, e.g. the joint angles a model was fitted on and those it is
/// used at.
struct StripChart {
  std::string title, x_label;
  int lanes = 1;  ///< lanes per row
  std::vector<StripRow> rows;
};

std::string renderStrips(const StripChart& chart);

}  // namespace stepcal::report::html
