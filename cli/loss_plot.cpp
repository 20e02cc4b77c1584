// loss_plot.cpp — the SVG loss plot of loss_plot.hpp: log axis, ticks, labels, legend, title.
#include "loss_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace ivr::cli {

namespace {

const char* const kFont = "DejaVu Sans, Liberation Sans, Arial, Helvetica, sans-serif";
const char* const kLossColour = "#1f5ac8";
const char* const kPriorColour = "#2ca02c";
const char* const kLevelColour = "#e07b10";

// Coordinates with two decimals: enough for a plot, and the C locale's '.' (the CLI never sets
// another locale).
std::string num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", x);
  return buf;
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  return out;
}

// An integer exponent in Unicode superscripts ("⁻³"): plain text, so that the label needs no
// tspan positioning and reads the same in every SVG viewer.
std::string superscript(int e) {
  static const char* const digits[] = {"⁰", "¹", "²", "³", "⁴", "⁵", "⁶", "⁷", "⁸", "⁹"};
  const std::string plain = std::to_string(e);
  std::string out;
  for (char c : plain) out += c == '-' ? "⁻" : digits[c - '0'];
  return out;
}

// m × 10^e for a tick (m a small integer; m = 1 is left out): "10⁻³", "2×10⁻³".
std::string tick_text(int m, int e) {
  return (m == 1 ? std::string() : std::to_string(m) + "×") + "10" + superscript(e);
}

// A value with three significant digits in the ticks' notation: "3.12×10⁻²".
std::string value_text(double v) {
  if (!(v > 0) || !std::isfinite(v)) return "n/a";
  int e = int(std::floor(std::log10(v)));
  double m = std::pow(10.0, std::log10(v) - e);  // not v / 10^e: 10^e underflows below 1e-308
  if (m >= 9.995) m /= 10, ++e;                  // rounds up to the next decade
  char buf[16];
  std::snprintf(buf, sizeof buf, "%.2f", m);
  return std::string(buf) + "×10" + superscript(e);
}

// A round step (1, 2 or 5 times a power of ten) giving about `count` ticks over `span` > 0.
double nice_step(double span, int count) {
  const double raw = span / count, p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

bool drawable(double v) {
  return v > 0 && std::isfinite(v);
}

// Text widths are not measurable without the font; this estimate (0.6 em a character, counting
// a multi-byte UTF-8 character once) only keeps labels from being placed over each other.
double text_width(const std::string& s, double size) {
  std::size_t chars = 0;
  for (unsigned char c : s) chars += (c & 0xC0) != 0x80;
  return 0.6 * size * double(chars);
}

class Svg {
 public:
  Svg(int width, int height) {
    out_ << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\""
         << height << "\" viewBox=\"0 0 " << width << " " << height << "\" font-family=\"" << kFont
         << "\">\n"
         << "<rect width=\"" << width << "\" height=\"" << height << "\" fill=\"white\"/>\n";
  }
  void line(double x0, double y0, double x1, double y1, const std::string& stroke, double w,
            const std::string& extra = "") {
    out_ << "<line x1=\"" << num(x0) << "\" y1=\"" << num(y0) << "\" x2=\"" << num(x1) << "\" y2=\""
         << num(y1) << "\" stroke=\"" << stroke << "\" stroke-width=\"" << w << "\"" << extra
         << "/>\n";
  }
  // `anchor`: start, middle or end; `cls` names the label's role for readers and tests.
  void text(double x, double y, const std::string& s, double size, const std::string& anchor,
            const std::string& cls, const std::string& extra = "") {
    out_ << "<text class=\"" << cls << "\" x=\"" << num(x) << "\" y=\"" << num(y)
         << "\" font-size=\"" << size << "\" text-anchor=\"" << anchor << "\"" << extra << ">"
         << escape(s) << "</text>\n";
  }
  void raw(const std::string& s) { out_ << s; }
  std::string finish() {
    out_ << "</svg>\n";
    return out_.str();
  }

 private:
  std::ostringstream out_;
};

}  // namespace

std::string loss_svg(const LossCurve& curve, int width, int height) {
  width = std::max(width, 480);
  height = std::max(height, 300);
  // Margins for the tick labels and axis titles (left, bottom), the title and level names (top)
  // and the legend (right).
  const double left = 84, right = width - 230, top = 52, bottom = height - 60;
  const std::size_t n = std::min(curve.iterations.size(), curve.losses.size());
  const bool has_priors =
      curve.priors.size() >= n && std::any_of(curve.priors.begin(), curve.priors.begin() + long(n),
                                              [](double v) { return drawable(v); });

  // The ranges: x over the finite iterations, y over whole decades of every drawable value.
  double xmin = 0, xmax = 0, lo = 0, hi = 0;
  bool any_x = false, any_y = false;
  const auto widen = [&](double v) {
    if (!drawable(v)) return;
    const double l = std::log10(v);
    lo = any_y ? std::min(lo, l) : l;
    hi = any_y ? std::max(hi, l) : l;
    any_y = true;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const double x = curve.iterations[i];
    if (!std::isfinite(x)) continue;
    xmin = any_x ? std::min(xmin, x) : x;
    xmax = any_x ? std::max(xmax, x) : x;
    any_x = true;
    widen(curve.losses[i]);
    if (has_priors) widen(curve.priors[i]);
  }
  if (!any_x) xmin = 0, xmax = 1;
  if (!any_y) lo = -1, hi = 0;
  lo = std::floor(lo);
  hi = std::max(std::ceil(hi), lo + 1);
  // Iterations are whole numbers: the x step is at least 1.
  const double xstep = std::max(1.0, nice_step(std::max(xmax - xmin, 1.0), 8));
  double xlo = std::floor(xmin / xstep) * xstep, xhi = std::ceil(xmax / xstep) * xstep;
  if (xmax - xmin < 1) xlo = std::floor(xmin) - 1, xhi = std::ceil(xmax) + 1;  // one point: centred
  const auto px = [&](double x) { return left + (x - xlo) / (xhi - xlo) * (right - left); };
  const auto py = [&](double v) {
    return bottom - (std::log10(v) - lo) / (hi - lo) * (bottom - top);
  };

  Svg svg(width, height);
  const std::string axis = "#333333";
  // y: grid lines at every decade, fainter ones at 2..9 times them when there are few decades;
  // labels at every k-th decade (about 8 at most), and at 2 and 5 times them over <= 2 decades.
  const int decades = int(hi - lo);
  const int label_every = std::max(1, (decades + 7) / 8);
  for (int e = int(lo); e <= int(hi); ++e) {
    const double y = bottom - (e - lo) / (hi - lo) * (bottom - top);
    svg.line(left, y, right, y, "#d0d0d0", 1);
    if ((e - int(lo)) % label_every == 0) {
      svg.line(left - 5, y, left, y, axis, 1);
      svg.text(left - 8, y + 4, tick_text(1, e), 12, "end", "y-tick");
    }
    if (e == int(hi) || decades > 6) continue;
    for (int m = 2; m <= 9; ++m) {
      const double ym = py(m * std::pow(10.0, e));
      svg.line(left, ym, right, ym, "#efefef", 1);
      if (decades <= 2 && (m == 2 || m == 5)) {
        svg.line(left - 3, ym, left, ym, axis, 1);
        svg.text(left - 8, ym + 4, tick_text(m, e), 11, "end", "y-tick");
      }
    }
  }
  // x: ticks and grid lines at the round steps.
  for (int k = 0; k <= 1000; ++k) {
    const double t = xlo + k * xstep;
    if (t > xhi + 1e-9 * xstep) break;
    const double x = px(t);
    svg.line(x, top, x, bottom, "#efefef", 1);
    svg.line(x, bottom, x, bottom + 5, axis, 1);
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f", t);
    svg.text(x, bottom + 19, buf, 12, "middle", "x-tick");
  }

  // Level changes: dashed lines between the levels' iterations, each level named above the plot
  // area at its start (skipped where it would overlap the previous name).
  double free_from = -1e300;
  for (std::size_t l = 0; l < curve.levels.size(); ++l) {
    const double at = curve.levels[l].iteration - 0.5;
    if (!std::isfinite(at) || at < xlo - 0.5 || at > xhi) continue;
    const double x = px(std::max(at, xlo));
    if (l > 0)
      svg.line(x, top, x, bottom, kLevelColour, 1.2,
               " stroke-dasharray=\"6 4\" class=\"level-change\"");
    const std::string& name = curve.levels[l].name;
    if (!name.empty() && x + 3 >= free_from) {
      svg.text(x + 3, top - 6, name, 11, "start", "level", " fill=\"#a85400\"");
      free_from = x + 3 + text_width(name, 11) + 6;
    }
  }

  // The curves: polylines split at the gaps; a point with no drawable neighbour as a dot.
  const auto polyline = [&](const std::vector<double>& values, const char* colour, double w,
                            const std::string& cls) {
    std::vector<std::pair<double, double>> run;
    const auto flush = [&] {
      if (run.size() == 1) {
        svg.raw("<circle class=\"" + cls + "\" cx=\"" + num(run[0].first) + "\" cy=\"" +
                num(run[0].second) + "\" r=\"2.5\" fill=\"" + colour + "\"/>\n");
      } else if (run.size() > 1) {
        std::string points;
        for (const auto& [x, y] : run) points += num(x) + "," + num(y) + " ";
        points.pop_back();
        svg.raw("<polyline class=\"" + cls + "\" fill=\"none\" stroke=\"" + colour +
                "\" stroke-width=\"" + num(w) + "\" stroke-linejoin=\"round\" points=\"" + points +
                "\"/>\n");
      }
      run.clear();
    };
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(curve.iterations[i])) continue;
      if (!drawable(values[i])) {
        flush();
        continue;
      }
      run.emplace_back(px(curve.iterations[i]), py(values[i]));
    }
    flush();
  };
  if (has_priors) polyline(curve.priors, kPriorColour, 1.6, "prior");
  polyline(curve.losses, kLossColour, 2, "loss");
  if (!any_y)
    svg.text((left + right) / 2, (top + bottom) / 2, "no positive finite loss to draw", 13,
             "middle", "note", " fill=\"#888888\"");

  // Axes, axis titles and the title.
  svg.line(left, bottom, right, bottom, axis, 1.2);
  svg.line(left, top, left, bottom, axis, 1.2);
  svg.text((left + right) / 2, bottom + 44, "iteration", 14, "middle", "x-title");
  const double yc = (top + bottom) / 2;
  svg.text(22, yc, "loss (" + curve.loss_name + ", log scale)", 14, "middle", "y-title",
           " transform=\"rotate(-90 22 " + num(yc) + ")\"");
  if (!curve.title.empty())
    svg.text(width / 2.0, 22, curve.title, 15, "middle", "title", " font-weight=\"bold\"");

  // The legend: a sample of each drawn line, then the loss's first, last and lowest values.
  double y = top + 14;
  const double lx = right + 22;
  const auto entry = [&](const std::string& label, const char* colour, double w,
                         const std::string& dash) {
    svg.line(lx, y - 4, lx + 28, y - 4, colour, w, dash);
    svg.text(lx + 36, y, label, 12, "start", "legend");
    y += 20;
  };
  entry(curve.loss_label + " (" + curve.loss_name + ")", kLossColour, 2, "");
  if (has_priors) entry("prior term", kPriorColour, 1.6, "");
  if (curve.levels.size() > 1)
    entry("level change", kLevelColour, 1.2, " stroke-dasharray=\"6 4\"");
  double first = NAN, last = NAN, lowest = NAN, lowest_at = NAN;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = curve.losses[i];
    if (!drawable(v) || !std::isfinite(curve.iterations[i])) continue;
    if (std::isnan(first)) first = v;
    last = v;
    if (std::isnan(lowest) || v < lowest) lowest = v, lowest_at = curve.iterations[i];
  }
  y += 6;
  char at[48];
  std::snprintf(at, sizeof at, " (it. %.0f)", std::isnan(lowest_at) ? 0.0 : lowest_at);
  for (const std::string& s : {"first " + value_text(first), "last " + value_text(last),
                               "lowest " + value_text(lowest) + (std::isnan(lowest) ? "" : at)}) {
    svg.text(lx, y, s, 12, "start", "stat", " fill=\"#444444\"");
    y += 18;
  }
  return svg.finish();
}

}  // namespace ivr::cli
