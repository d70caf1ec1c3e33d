#include "cairn/report/svg.hpp"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <limits>
#include <sstream>

namespace cairn::report {
namespace {

constexpr int kLeft = 64, kRight = 18, kTop = 34, kBottom = 46, kLegend = 150;  // [px] margins
constexpr std::size_t kMaxMarkers = 80;  // a longer line series is drawn without markers
constexpr double kPad = 0.05;  // share of the data range added above the largest value
constexpr const char* kFont = "font-family=\"sans-serif\" font-size=\"12\"";

std::string num(double v) {
  std::ostringstream s;
  if (std::abs(v) >= 1000.0) {  // counts and milliseconds: whole numbers, never 3e+05
    s.setf(std::ios::fixed);
    s.precision(0);
  } else {
    s.precision(4);
  }
  s << (std::abs(v) < 1e-12 ? 0.0 : v);
  return s.str();
}

struct Range {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  /// Finite, non-empty, from 0 when all values are >= 0 (unless forced).
  void settle(const std::optional<double>& min, const std::optional<double>& max, bool from_zero) {
    if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
    if (from_zero && lo >= 0) lo = 0.0;
    if (hi - lo < 1e-12) hi = lo + 1.0;
    else if (!max) hi += kPad * (hi - lo);
    if (min) lo = *min;
    if (max) hi = *max;
  }
};

/// The plot area, its axes, ticks, grid, title and labels.
class Frame {
 public:
  Frame(const ChartSpec& s, Range x, Range y, bool legend)
      : s_(s), x_(x), y_(y), right_(s.width - kRight - (legend ? kLegend : 0)) {}
  [[nodiscard]] double X(double v) const { return kLeft + (v - x_.lo) / (x_.hi - x_.lo) * (right_ - kLeft); }
  [[nodiscard]] double Y(double v) const {
    const double bottom = s_.height - kBottom;
    return bottom - (std::clamp(v, y_.lo, y_.hi) - y_.lo) / (y_.hi - y_.lo) * (bottom - kTop);
  }
  [[nodiscard]] bool clipped(double v) const { return v < y_.lo - 1e-12 || v > y_.hi + 1e-12; }
  [[nodiscard]] int right() const { return right_; }
  void open(std::ostringstream& o, const std::string& note, bool x_ticks = true) const {
    const int bottom = s_.height - kBottom;
    o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << s_.width << "\" height=\"" << s_.height
      << "\" viewBox=\"0 0 " << s_.width << ' ' << s_.height << "\" " << kFont << ">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<text x=\"" << kLeft << "\" y=\"20\" font-size=\"14\" font-weight=\"bold\">" << xml_escape(s_.title)
      << (note.empty() ? "" : " ") << "<tspan font-weight=\"normal\" font-size=\"11\" fill=\"#666\">"
      << xml_escape(note) << "</tspan></text>\n";
    for (double t : nice_ticks(y_.lo, y_.hi))
      o << "<line x1=\"" << kLeft << "\" x2=\"" << right_ << "\" y1=\"" << num(Y(t)) << "\" y2=\"" << num(Y(t))
        << "\" stroke=\"#e4e4e4\"/><text x=\"" << kLeft - 6 << "\" y=\"" << num(Y(t) + 4)
        << "\" text-anchor=\"end\">" << num(t) << "</text>\n";
    std::vector<double> xt = nice_ticks(x_.lo, x_.hi);
    if (s_.integer_x) {
      xt.clear();
      for (double t = std::ceil(x_.lo); t <= x_.hi; t += std::max(1.0, std::ceil((x_.hi - x_.lo) / 10.0))) xt.push_back(t);
    }
    if (x_ticks)
      for (double t : xt)
        o << "<line x1=\"" << num(X(t)) << "\" x2=\"" << num(X(t)) << "\" y1=\"" << bottom << "\" y2=\"" << bottom + 4
          << "\" stroke=\"black\"/><text x=\"" << num(X(t)) << "\" y=\"" << bottom + 17
          << "\" text-anchor=\"middle\">" << num(t) << "</text>\n";
    o << "<path d=\"M" << kLeft << ' ' << kTop << "V" << bottom << "H" << right_ << "\" fill=\"none\" stroke=\"black\"/>\n"
      << "<text x=\"" << (kLeft + right_) / 2 << "\" y=\"" << s_.height - 8 << "\" text-anchor=\"middle\">"
      << xml_escape(s_.x_label) << "</text>\n"
      << "<text transform=\"translate(14 " << (kTop + bottom) / 2 << ") rotate(-90)\" text-anchor=\"middle\">"
      << xml_escape(s_.y_label) << "</text>\n";
    if (s_.reference) {
      const double y = Y(*s_.reference);
      o << "<line x1=\"" << kLeft << "\" x2=\"" << right_ << "\" y1=\"" << num(y) << "\" y2=\"" << num(y)
        << "\" stroke=\"#444\" stroke-dasharray=\"5 4\"/><text x=\"" << right_ - 4 << "\" y=\"" << num(y - 4)
        << "\" text-anchor=\"end\" fill=\"#444\">" << xml_escape(s_.reference_label) << "</text>\n";
    }
  }

 private:
  const ChartSpec& s_;
  Range x_, y_;
  int right_;
};

std::string clip_note(int clipped) {
  return clipped > 0 ? "(" + std::to_string(clipped) + " clipped)" : "";
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int count) {
  if (!(hi > lo) || count < 1) return {lo};
  const double raw = (hi - lo) / count, mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = 10.0 * mag;
  for (double m : {1.0, 2.0, 5.0})
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  std::vector<double> t;
  for (auto k = std::int64_t(std::ceil(lo / step - 1e-9)); double(k) * step <= hi + 1e-9 * step; ++k)
    t.push_back(double(k) * step);  // no accumulated rounding
  return t;
}

std::string xml_escape(const std::string& text) {
  std::string o;
  for (char c : text) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string line_chart(const ChartSpec& spec, const std::vector<Series>& series) {
  Range x, y;
  for (const Series& s : series) {
    for (double v : s.x) x.add(v);
    for (double v : s.y) y.add(v);
  }
  if (spec.reference) y.add(*spec.reference);
  x.settle(spec.x_min, spec.x_max, false);
  if (!spec.x_max && x.hi > x.lo) x.hi -= kPad * (x.hi - x.lo) / (1 + kPad);  // no headroom on x
  y.settle(spec.y_min, spec.y_max, true);
  const bool legend = series.size() > 1;
  const Frame f(spec, x, y, legend);
  int clipped = 0;
  std::ostringstream body;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const Series& s = series[k];
    const std::size_t n = std::min(s.x.size(), s.y.size());
    if (s.lines && n > 1) {
      body << "<polyline fill=\"none\" stroke=\"" << s.color << "\" stroke-width=\"1.5\" points=\"";
      for (std::size_t i = 0; i < n; ++i) body << num(f.X(s.x[i])) << ',' << num(f.Y(s.y[i])) << ' ';
      body << "\"/>\n";
    }
    const bool markers = n <= kMaxMarkers || !s.filled.empty() || !s.lines;
    for (std::size_t i = 0; i < n; ++i) {
      clipped += f.clipped(s.y[i]);
      if (!markers) continue;
      const bool fill = s.filled.empty() || (i < s.filled.size() && s.filled[i]);
      body << "<circle cx=\"" << num(f.X(s.x[i])) << "\" cy=\"" << num(f.Y(s.y[i])) << "\" r=\"3.5\" fill=\""
           << (fill ? s.color : "white") << "\" stroke=\"" << s.color << "\"/>\n";
    }
    if (legend)
      body << "<rect x=\"" << f.right() + 14 << "\" y=\"" << kTop + 18 * k << "\" width=\"12\" height=\"12\" fill=\""
           << s.color << "\"/><text x=\"" << f.right() + 32 << "\" y=\"" << kTop + 18 * k + 10 << "\">"
           << xml_escape(s.name) << "</text>\n";
  }
  std::ostringstream o;
  f.open(o, clip_note(clipped));
  o << body.str() << "</svg>\n";
  return o.str();
}

std::string bar_chart(const ChartSpec& spec, const std::vector<Bar>& bars, const std::string& color) {
  Range x, y;
  x.add(0.0), x.add(double(std::max<std::size_t>(bars.size(), 1)));
  for (const Bar& b : bars) y.add(b.value);
  y.settle(spec.y_min, spec.y_max, true);
  x.settle(0.0, double(std::max<std::size_t>(bars.size(), 1)), false);
  const Frame f(spec, x, y, false);
  std::ostringstream o;
  f.open(o, "", false);
  const int bottom = spec.height - kBottom;
  for (std::size_t i = 0; i < bars.size(); ++i) {
    const double x0 = f.X(double(i) + 0.15), x1 = f.X(double(i) + 0.85), top = f.Y(bars[i].value);
    o << "<rect x=\"" << num(x0) << "\" y=\"" << num(top) << "\" width=\"" << num(x1 - x0) << "\" height=\""
      << num(bottom - top) << "\" fill=\"" << color << "\"><title>" << xml_escape(bars[i].label) << ": "
      << num(bars[i].value) << "</title></rect>\n"
      << "<text x=\"" << num(0.5 * (x0 + x1)) << "\" y=\"" << num(top - 4) << "\" text-anchor=\"middle\" font-size=\"11\">"
      << num(bars[i].value) << "</text>\n"
      << "<text x=\"" << num(0.5 * (x0 + x1)) << "\" y=\"" << bottom + 16 << "\" text-anchor=\"middle\" font-size=\"11\">"
      << xml_escape(bars[i].label) << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

std::string strip_chart(const ChartSpec& spec, const std::vector<Strip>& strips) {
  Range x, y;
  x.add(0.0), x.add(double(std::max<std::size_t>(strips.size(), 1)));
  for (const Strip& s : strips) {
    for (double v : s.all) y.add(v);
    for (double v : s.selected) y.add(v);
  }
  y.settle(spec.y_min, spec.y_max, true);
  x.settle(0.0, double(std::max<std::size_t>(strips.size(), 1)), false);
  const Frame f(spec, x, y, false);
  int clipped = 0;
  std::ostringstream body;
  const int bottom = spec.height - kBottom;
  const auto dots = [&](const std::vector<double>& v, double left, double right, const char* fill, double r) {
    for (std::size_t i = 0; i < v.size(); ++i) {
      const double u = double((i * 2654435761u) % 1000u) / 1000.0;  // deterministic jitter
      clipped += f.clipped(v[i]);
      body << "<circle cx=\"" << num(f.X(left + u * (right - left))) << "\" cy=\"" << num(f.Y(v[i])) << "\" r=\""
           << r << "\" fill=\"" << fill << "\" fill-opacity=\"0.7\"/>\n";
    }
  };
  for (std::size_t k = 0; k < strips.size(); ++k) {
    const double x0 = double(k);
    dots(strips[k].all, x0 + 0.08, x0 + 0.46, "#999", 2.0);
    dots(strips[k].selected, x0 + 0.54, x0 + 0.92, "#d62728", 3.0);
    body << "<text x=\"" << num(f.X(x0 + 0.5)) << "\" y=\"" << bottom + 16 << "\" text-anchor=\"middle\">"
         << xml_escape(strips[k].label) << "</text>\n";
  }
  std::ostringstream o;
  f.open(o, clip_note(clipped), false);
  o << body.str() << "</svg>\n";
  return o.str();
}

}  // namespace cairn::report
