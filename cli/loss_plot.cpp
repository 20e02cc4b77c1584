// loss_plot.cpp — the loss-curve plotter of loss_plot.hpp: axes, decade grid, anti-aliased curve.
#include "loss_plot.hpp"

#include <algorithm>
#include <cmath>

namespace ivr::cli {

namespace {

struct Rgb {
  float r, g, b;
};

// Colours are chosen as sRGB bytes; the image holds linear values because the PNG writer applies
// the sRGB curve (tone_map_8bit), so they come out as chosen.
Rgb srgb(int r, int g, int b) {
  const auto linear = [](int c) {
    const double s = c / 255.0;
    return float(s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4));
  };
  return {linear(r), linear(g), linear(b)};
}

class Canvas {
 public:
  Canvas(int width, int height) {
    image_.views = 1;
    image_.width = width;
    image_.height = height;
    image_.channels = 4;
    image_.pixels.assign(std::size_t(width) * height * 4, 1.0f);  // white, opaque
  }

  // Blends `c` over pixel (x, y) with coverage `a` in [0, 1]; outside the canvas: nothing.
  void blend(int x, int y, Rgb c, double a) {
    if (x < 0 || y < 0 || x >= image_.width || y >= image_.height || a <= 0) return;
    float* p = image_.pixels.data() + (std::size_t(y) * image_.width + x) * 4;
    const float w = float(std::min(a, 1.0));
    p[0] += (c.r - p[0]) * w;
    p[1] += (c.g - p[1]) * w;
    p[2] += (c.b - p[2]) * w;
  }

  void hline(int x0, int x1, int y, Rgb c) {
    for (int x = x0; x <= x1; ++x) blend(x, y, c, 1);
  }
  // Every `dash` pixels on, `gap` off (gap 0: solid).
  void vline(int x, int y0, int y1, Rgb c, int dash = 1, int gap = 0) {
    for (int y = y0; y <= y1; ++y)
      if (gap == 0 || (y - y0) % (dash + gap) < dash) blend(x, y, c, 1);
  }

  // A round-capped segment of the given half-width: each pixel near it is covered by how far it
  // lies inside (one pixel of soft edge), keeping the larger of that and what is drawn already
  // from this stroke, so joints do not darken.
  void segment(double ax, double ay, double bx, double by, double half, Rgb c) {
    const int x0 = int(std::floor(std::min(ax, bx) - half - 1));
    const int x1 = int(std::ceil(std::max(ax, bx) + half + 1));
    const int y0 = int(std::floor(std::min(ay, by) - half - 1));
    const int y1 = int(std::ceil(std::max(ay, by) + half + 1));
    const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5 - ax, py = y + 0.5 - ay;
        const double t = len2 > 0 ? std::clamp((px * dx + py * dy) / len2, 0.0, 1.0) : 0.0;
        const double d = std::hypot(px - t * dx, py - t * dy);
        const double cover = std::clamp(half + 0.5 - d, 0.0, 1.0);
        if (cover <= 0 || x < 0 || y < 0 || x >= image_.width || y >= image_.height) continue;
        float& done = coverage(x, y);
        if (cover <= done) continue;
        // Blend only the extra coverage: (1 − done) of the pixel is still background-like.
        blend(x, y, c, (cover - done) / (1 - done + 1e-9));
        done = float(cover);
      }
  }
  void clear_coverage() { coverage_.assign(image_.pixels.size() / 4, 0.0f); }

  Image take() { return std::move(image_); }

 private:
  float& coverage(int x, int y) {
    if (coverage_.empty()) clear_coverage();
    return coverage_[std::size_t(y) * image_.width + x];
  }
  Image image_;
  std::vector<float> coverage_;
};

// A round step (1, 2 or 5 times a power of ten) giving about `count` ticks over `span`.
double nice_step(double span, int count) {
  const double raw = span / count, p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

}  // namespace

Image plot_loss(const LossCurve& curve, int width, int height) {
  width = std::max(width, 64);
  height = std::max(height, 48);
  Canvas canvas(width, height);
  const Rgb axis = srgb(40, 40, 40), grid = srgb(225, 225, 225), line = srgb(25, 90, 200),
            marker = srgb(235, 130, 20);
  // The plot area, with margins where a reader would expect labels.
  const int left = std::min(56, width / 8), right = width - 16, top = 16,
            bottom = height - std::min(40, height / 8);

  // x: the iterations' range; y: whole decades around the positive finite losses.
  double xmin = 0, xmax = 1, lo = 0, hi = 1;
  bool any = false;
  for (std::size_t i = 0; i < curve.losses.size() && i < curve.iterations.size(); ++i) {
    const double x = curve.iterations[i], y = curve.losses[i];
    xmin = i == 0 ? x : std::min(xmin, x);
    xmax = i == 0 ? x : std::max(xmax, x);
    if (!(y > 0) || !std::isfinite(y)) continue;
    const double l = std::log10(y);
    lo = any ? std::min(lo, l) : l;
    hi = any ? std::max(hi, l) : l;
    any = true;
  }
  lo = std::floor(lo);
  hi = std::max(std::ceil(hi), lo + 1);
  if (xmax <= xmin) xmin -= 1, xmax += 1;  // one point: in the middle
  const auto px = [&](double x) { return left + (x - xmin) / (xmax - xmin) * (right - left); };
  const auto py = [&](double log_y) { return bottom - (log_y - lo) / (hi - lo) * (bottom - top); };

  // Grid lines at the decades, tick marks at round iteration counts.
  for (double d = lo; d <= hi; ++d) canvas.hline(left, right, int(std::lround(py(d))), grid);
  const double tick = nice_step(xmax - xmin, 8);
  for (double t = std::ceil(xmin / tick) * tick; t <= xmax + 1e-9; t += tick)
    canvas.vline(int(std::lround(px(t))), bottom + 1, bottom + 5, axis);
  for (double m : curve.markers)
    if (m >= xmin && m <= xmax) canvas.vline(int(std::lround(px(m))), top, bottom, marker, 6, 4);
  canvas.hline(left, right, bottom, axis);
  canvas.vline(left, top, bottom, axis);

  // The curve: segments between consecutive drawable points (a gap where one is not).
  canvas.clear_coverage();
  bool have_previous = false;
  double ax = 0, ay = 0;
  for (std::size_t i = 0; i < curve.losses.size() && i < curve.iterations.size(); ++i) {
    const double y = curve.losses[i];
    if (!(y > 0) || !std::isfinite(y)) {
      have_previous = false;
      continue;
    }
    const double bx = px(curve.iterations[i]), by = py(std::log10(y));
    canvas.segment(have_previous ? ax : bx, have_previous ? ay : by, bx, by, 1.1, line);
    ax = bx;
    ay = by;
    have_previous = true;
  }
  return canvas.take();
}

}  // namespace ivr::cli
