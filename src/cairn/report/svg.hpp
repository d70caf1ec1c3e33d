#pragma once
// Small SVG charts for the report (standalone files that also inline into HTML): line/scatter
// charts, bar charts and Fig. 9's strip charts. Axes get "nice" ticks (1, 2, 5 x 10^k).
#include <optional>
#include <string>
#include <vector>

namespace cairn::report {

struct ChartSpec {
  std::string title, x_label, y_label;
  int width = 560, height = 320;  // [px]
  std::optional<double> y_min, y_max;  // default: from the data (y_min 0 when all values >= 0)
  std::optional<double> x_min, x_max;
  /// A dashed horizontal line (a target or a median), with its label.
  std::optional<double> reference;
  std::string reference_label;
  bool integer_x = false;  // x ticks at whole numbers only (rounds, attempts)
};

struct Series {
  std::string name;
  std::vector<double> x, y;
  std::string color = "#1f77b4";
  bool lines = true;
  /// Per point: drawn filled (true) or hollow; empty: all filled.
  std::vector<bool> filled;
};

struct Bar {
  std::string label;
  double value = 0.0;
};

/// Fig. 9: per criterion, every force-closure grasp (grey) beside the selected ones (red).
struct Strip {
  std::string label;
  std::vector<double> all, selected;
};

/// Ticks covering [lo, hi] with about `count` steps of 1, 2 or 5 x 10^k.
[[nodiscard]] std::vector<double> nice_ticks(double lo, double hi, int count = 5);
/// Text with &, <, >, " escaped for XML.
[[nodiscard]] std::string xml_escape(const std::string& text);

/// Points (and lines) of every series, a legend when more than one; values outside the axis
/// range are drawn at its edge (clipped) and counted in the title's note. A line series of more
/// than 80 points without per-point fill is drawn without markers.
[[nodiscard]] std::string line_chart(const ChartSpec& spec, const std::vector<Series>& series);
[[nodiscard]] std::string bar_chart(const ChartSpec& spec, const std::vector<Bar>& bars, const std::string& color = "#4c72b0");
[[nodiscard]] std::string strip_chart(const ChartSpec& spec, const std::vector<Strip>& strips);

}  // namespace cairn::report
