// empty_space.cpp — the brick occupancy grid: per-brick density ranges (on the device:
// kernels/empty_space.cl; here for tests and host use) mapped through the transfer function to
// "σ may be non-zero here".
#include "empty_space/empty_space.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

namespace ivr {

namespace {
// Densities on the device are floats interpolated in float: widen the range by their rounding
// (relative: interpolating equal values, zeros included, is exact).
void widen(double& lo, double& hi) {
  const double pad = 1e-6 * std::max(std::abs(lo), std::abs(hi));
  lo -= pad;
  hi += pad;
}
}  // namespace

bool tf_may_absorb(const TransferFunction& tf, double lo, double hi) {
  widen(lo, hi);
  switch (tf.kind) {
    case TfKind::identity:  // σ = scale·d
      return tf.extinction_scale != 0 && (hi > 0 || lo < 0);
    case TfKind::piecewise_linear: {
      const auto& p = tf.points;
      // Constant beyond the ends, linear on each segment: σ on [lo, hi] is bounded by the
      // extinctions of the points whose segments meet [lo, hi].
      if (lo <= p.front().density && p.front().extinction != 0) return true;
      if (hi >= p.back().density && p.back().extinction != 0) return true;
      for (std::size_t k = 0; k + 1 < p.size(); ++k)
        if (p[k + 1].density >= lo && p[k].density <= hi &&
            (p[k].extinction != 0 || p[k + 1].extinction != 0))
          return true;
      return false;
    }
    case TfKind::table: {
      // Entries at evenly spaced densities over the range, linear in between, constant beyond.
      const int r = int(tf.entries.size());
      auto index = [&](double d) {
        const double u = (d - tf.range.x) / (tf.range.y - tf.range.x);
        return std::clamp(u, 0.0, 1.0) * (r - 1);
      };
      const int i0 = std::max(0, int(std::floor(index(lo))) - 1);
      const int i1 = std::min(r - 1, int(std::ceil(index(hi))) + 1);
      for (int i = i0; i <= i1; ++i)
        if (tf.entries[i].w != 0) return true;
      return false;
    }
    case TfKind::gaussian:  // positive everywhere unless every extinction is 0
      return std::any_of(tf.gaussians.begin(), tf.gaussians.end(),
                         [](const TfGaussian& g) { return g.extinction != 0; });
  }
  return true;
}

bool tf_absorbs_throughout(const TransferFunction& tf, double lo, double hi) {
  widen(lo, hi);
  switch (tf.kind) {
    case TfKind::identity:
      return (tf.extinction_scale > 0 && lo > 0) || (tf.extinction_scale < 0 && hi < 0);
    case TfKind::piecewise_linear: {
      // Linear between the points and constant beyond them: σ > 0 on [lo, hi] when it is at both
      // ends and at every point in between.
      const auto sigma = [&](double d) {
        const auto& p = tf.points;
        if (d <= p.front().density) return p.front().extinction;
        if (d >= p.back().density) return p.back().extinction;
        std::size_t k = 0;
        while (p[k + 1].density <= d) ++k;
        const double w = (d - p[k].density) / (p[k + 1].density - p[k].density);
        return p[k].extinction + w * (p[k + 1].extinction - p[k].extinction);
      };
      if (!(sigma(lo) > 0) || !(sigma(hi) > 0)) return false;
      for (const TfPoint& q : tf.points)
        if (q.density > lo && q.density < hi && !(q.extinction > 0)) return false;
      return true;
    }
    default:
      return false;  // not needed for a decision: unsure
  }
}

bool tf_has_empty_range(const TransferFunction& tf) {
  switch (tf.kind) {
    case TfKind::identity:
      return true;  // σ(0) = 0, and zero densities are what empty space is
    case TfKind::piecewise_linear:
      return std::any_of(tf.points.begin(), tf.points.end(),
                         [](const TfPoint& p) { return p.extinction == 0; });
    case TfKind::table:
      return std::any_of(tf.entries.begin(), tf.entries.end(),
                         [](const glm::dvec4& e) { return e.w == 0; });
    case TfKind::gaussian:
      return !tf_may_absorb(tf, 0, 0);
  }
  return false;
}

bool gradient_may_skip(const TransferFunction& tf, bool grad_tf, bool grad_density_or_camera) {
  if (grad_tf) return false;
  if (!grad_density_or_camera) return true;
  return tf.kind == TfKind::piecewise_linear || tf.kind == TfKind::table;
}

int auto_brick_size(const Volume& v) {
  return std::max(v.nx, std::max(v.ny, v.nz)) <= 128 ? 4 : 8;
}

EmptySpaceGrid brick_layout(const Volume& v, int size) {
  EmptySpaceGrid g;
  g.size = size;
  // Cells are the intervals between voxel centres, indexed by their lower voxel. (The kernel's
  // cell index runs to n - 1 where it clamps u = n - 1, hence floor, plus one.)
  auto bricks = [&](int n) { return (std::max(n, 1) - 1) / size + 1; };
  g.nx = bricks(v.nx), g.ny = bricks(v.ny), g.nz = bricks(v.nz);
  return g;
}

void occupy_from_ranges(EmptySpaceGrid& g, const std::vector<float>& ranges,
                        const TransferFunction& tf) {
  const std::size_t count = std::size_t(g.nx) * g.ny * g.nz;
  g.occupied.resize(count);
  std::size_t empty = 0;
  for (std::size_t b = 0; b < count; ++b) {
    g.occupied[b] = tf_may_absorb(tf, ranges[2 * b], ranges[2 * b + 1]) ? 1 : 0;
    empty += g.occupied[b] ? 0 : 1;
  }
  g.empty_fraction = double(empty) / double(count);
}

std::vector<float> host_brick_ranges(const Volume& v, int size) {
  const EmptySpaceGrid g = brick_layout(v, size);
  std::vector<float> ranges(2 * std::size_t(g.nx) * g.ny * g.nz);
  auto span = [&](int b, int n, int* first, int* last) {
    *first = std::max(b * size - 1, 0);
    *last = std::min((b + 1) * size + 1, n - 1);
  };
  // Slabs of brick layers on every core (small volumes: one thread).
  auto layers = [&](int bz_begin, int bz_end) {
    for (int bz = bz_begin; bz < bz_end; ++bz)
      for (int by = 0; by < g.ny; ++by)
        for (int bx = 0; bx < g.nx; ++bx) {
          int x0, x1, y0, y1, z0, z1;
          span(bx, v.nx, &x0, &x1), span(by, v.ny, &y0, &y1), span(bz, v.nz, &z0, &z1);
          float lo = std::numeric_limits<float>::infinity(), hi = -lo;
          for (int z = z0; z <= z1; ++z)
            for (int y = y0; y <= y1; ++y) {
              const float* row = v.data.data() + (std::size_t(z) * v.ny + y) * v.nx;
              for (int x = x0; x <= x1; ++x) lo = std::min(lo, row[x]), hi = std::max(hi, row[x]);
            }
          const std::size_t b = (std::size_t(bz) * g.ny + by) * g.nx + bx;
          ranges[2 * b] = lo, ranges[2 * b + 1] = hi;
        }
  };
  const int threads = int(
      std::min<std::size_t>({std::size_t(std::max(1u, std::thread::hardware_concurrency())),
                             std::size_t(g.nz), std::max<std::size_t>(1, v.voxel_count() >> 18)}));
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t)
    pool.emplace_back(layers, g.nz * t / threads, g.nz * (t + 1) / threads);
  layers(0, g.nz / threads);
  for (std::thread& th : pool) th.join();
  return ranges;
}

EmptySpaceGrid build_brick_grid(const Volume& v, const TransferFunction& tf, int size) {
  EmptySpaceGrid g = brick_layout(v, size);
  occupy_from_ranges(g, host_brick_ranges(v, size), tf);
  return g;
}

}  // namespace ivr
