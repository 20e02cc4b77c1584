// empty_space.cpp — the brick occupancy grid: per-brick density ranges, dilated by one brick,
// mapped through the transfer function to "σ may be non-zero here".
#include "empty_space.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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

int auto_brick_size(const Volume& v) {
  return std::max(v.nx, std::max(v.ny, v.nz)) <= 128 ? 4 : 8;
}

BrickGrid build_brick_grid(const Volume& v, const TransferFunction& tf, int size) {
  BrickGrid g;
  g.size = size;
  // Cells are the intervals between voxel centres, indexed by their lower voxel.
  // (The kernel's cell index runs to n - 1 where it clamps u = n - 1, hence floor, plus one.)
  auto bricks = [&](int n) { return (std::max(n, 1) - 1) / size + 1; };
  g.nx = bricks(v.nx), g.ny = bricks(v.ny), g.nz = bricks(v.nz);
  const std::size_t count = std::size_t(g.nx) * g.ny * g.nz;
  // Brick b reads the voxels [b·size, (b+1)·size] (corners of its cells); one more voxel on
  // each side covers samples that rounding puts a cell past the brick's face.
  g.occupied.assign(count, 0);
  std::size_t empty = 0;
  auto span = [&](int b, int n, int* first, int* last) {
    *first = std::max(b * size - 1, 0);
    *last = std::min((b + 1) * size + 1, n - 1);
  };
  for (int bz = 0; bz < g.nz; ++bz)
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
        const bool occupied = tf_may_absorb(tf, lo, hi);
        g.occupied[(std::size_t(bz) * g.ny + by) * g.nx + bx] = occupied ? 1 : 0;
        empty += occupied ? 0 : 1;
      }
  g.empty_fraction = double(empty) / double(count);
  return g;
}

}  // namespace ivr
