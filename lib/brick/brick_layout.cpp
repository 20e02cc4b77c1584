// brick_layout.cpp — bricks of a volume, the device-memory budget, and bricks' host copies.
#include "brick/brick_layout.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "ivr/error.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

namespace {
// Bricks along an axis of n voxels: n − 1 cells in runs of `edge`; one for a single voxel.
int bricks_along(int n, int edge) { return std::max(1, (n - 1 + edge - 1) / edge); }
}  // namespace

BrickLayout brick_layout(int nx, int ny, int nz, int edge, int z_first, int z_last, int halo) {
  if (halo < 0)
    throw Error(Status::invalid_argument, "brick halo: " + std::to_string(halo) + " voxels");
  if (edge < 1)
    throw Error(Status::invalid_argument,
                "brick edge: " + std::to_string(edge) + " cells, must be at least 1");
  if (z_last < 0) z_last = nz - 1;
  if (z_first < 0 || z_last >= nz || z_first > z_last)
    throw Error(Status::invalid_argument, "bricks: planes " + std::to_string(z_first) + ".." +
                                              std::to_string(z_last) + " of a volume of " +
                                              std::to_string(nz) + " planes");
  BrickLayout l;
  l.edge = edge;
  l.dims = {nx, ny, nz};
  l.z_first = z_first, l.z_last = z_last;
  l.data_first = z_first, l.data_last = z_last;
  l.halo = halo;
  l.count[0] = bricks_along(nx, edge);
  l.count[1] = bricks_along(ny, edge);
  l.count[2] = bricks_along(z_last - z_first + 1, edge);
  return l;
}

std::array<int, 3> BrickLayout::index(int b) const {
  return {b % count[0], (b / count[0]) % count[1], b / (count[0] * count[1])};
}

std::array<int, 3> BrickLayout::corner(int b) const {
  const std::array<int, 3> i = index(b);
  return {i[0] * edge, i[1] * edge, z_first + i[2] * edge};
}

std::array<int, 3> BrickLayout::origin(int b) const {
  const std::array<int, 3> c = corner(b), first{0, 0, data_first};
  return {std::max(c[0] - halo, first[0]), std::max(c[1] - halo, first[1]),
          std::max(c[2] - halo, first[2])};
}

std::array<int, 3> BrickLayout::extent(int b) const {
  const std::array<int, 3> c = corner(b), o = origin(b);
  const std::array<int, 3> last{dims[0] - 1, dims[1] - 1, data_last};
  std::array<int, 3> e{};
  for (int a = 0; a < 3; ++a) e[a] = std::min(c[a] + edge + halo, last[a]) - o[a] + 1;
  return e;
}

std::size_t BrickLayout::voxels(int b) const {
  const std::array<int, 3> e = extent(b);
  return std::size_t(e[0]) * e[1] * e[2];
}

std::size_t BrickLayout::largest_voxels() const {
  const std::array<int, 3> cells{dims[0] - 1, dims[1] - 1, data_last - data_first};
  std::size_t n = 1;
  for (int a = 0; a < 3; ++a) n *= std::size_t(std::min(edge + 2 * halo, cells[a]) + 1);
  return n;
}

int brick_halo(const Scene& scene, double step, bool deterministic) {
  if (scene.integrator.scheme != Scheme::trapezoid &&
      scene.integrator.scheme != Scheme::preintegrated)
    return deterministic ? 1 : 0;
  const glm::dvec3 h = scene.voxel_size();
  const double finest = std::min({h.x, h.y, h.z});
  // (+1: the near sample's cell starts at floor(u), and the float32 sample count may round a
  // segment a hair past the step.)
  const double reach = std::ceil(step / finest);
  return std::isfinite(reach) && reach < 1e6 ? int(reach) + 1 : 1 << 20;
}

void check_brick_halo(const Scene& scene, double step, const BrickLayout& layout) {
  const int halo = brick_halo(scene, step);
  if (halo > layout.halo)
    throw Error(Status::unsupported,
                std::string("out-of-core gradient: the ") + scheme_name(scene.integrator.scheme) +
                    " scheme's step " + std::to_string(step) + " needs bricks with a halo of " +
                    std::to_string(halo) + " voxels, the plan's hold " +
                    std::to_string(layout.halo) + " (a step chosen to a tolerance: give a step)");
}

// A brick's planes are those it starts and ends at; at the outer bricks, ±∞ where the bricks
// reach the box face (a slab's inner face stays a plane: the next process's bricks start there).
std::array<double, 3> BrickLayout::lo(int b) const {
  const std::array<int, 3> o = corner(b);
  std::array<double, 3> p{};
  for (int a = 0; a < 3; ++a)
    p[a] = o[a] == 0 ? -std::numeric_limits<double>::infinity() : double(o[a]);
  return p;
}

std::array<double, 3> BrickLayout::hi(int b) const {
  const std::array<int, 3> c = corner(b);
  const std::array<int, 3> last{dims[0] - 1, dims[1] - 1, z_last};
  std::array<double, 3> p{};
  for (int a = 0; a < 3; ++a) {
    const int end = std::min(c[a] + edge, last[a]);
    p[a] = end == dims[a] - 1 ? std::numeric_limits<double>::infinity() : double(end);
  }
  return p;
}

std::uint64_t brick_budget(Device& device) {
  const std::uint64_t budget = device_memory_budget(device.info());
  // A buffer is counted out when the driver frees it, which may wait for the commands that use
  // it: with the queue drained, what an earlier call released no longer counts against this plan
  // (under load, a just-finished render's volume could otherwise make a plan go in core).
  if (budget) device.impl().queue.finish();
  // Under a cap set by IVR_DEVICE_MEMORY_LIMIT (where a few KiB decide the plan) let the
  // driver's callbacks count out what was released first.
  const auto& live = device.impl().live;
  if (budget && device_memory_limit_from_env()) live->settle();
  const std::uint64_t in_use = std::uint64_t(std::max<std::int64_t>(live->bytes.load(), 0));
  return budget ? (budget > in_use ? budget - in_use : 1) : 0;
}

namespace {
template <typename T>
void extract(const T* values, const BrickLayout& l, int b, bool f64, std::vector<unsigned char>& out) {
  const std::array<int, 3> o = l.origin(b), e = l.extent(b);
  out.resize(l.voxels(b) * (f64 ? sizeof(double) : sizeof(float)));
  std::size_t at = 0;
  for (int z = 0; z < e[2]; ++z)
    for (int y = 0; y < e[1]; ++y) {
      const T* row =
          values + (std::size_t(o[2] - l.data_first + z) * l.dims[1] + (o[1] + y)) * l.dims[0] + o[0];
      if (f64) {
        double* dst = reinterpret_cast<double*>(out.data()) + at;
        for (int x = 0; x < e[0]; ++x) dst[x] = double(row[x]);
      } else {
        float* dst = reinterpret_cast<float*>(out.data()) + at;
        for (int x = 0; x < e[0]; ++x) dst[x] = float(row[x]);
      }
      at += std::size_t(e[0]);
    }
}
}  // namespace

void extract_brick(const float* values, const BrickLayout& layout, int b, bool f64,
                   std::vector<unsigned char>& out) {
  extract(values, layout, b, f64, out);
}

void extract_brick(const double* values, const BrickLayout& layout, int b, bool f64,
                   std::vector<unsigned char>& out) {
  extract(values, layout, b, f64, out);
}

namespace {
template <typename T>
void add(const std::vector<unsigned char>& brick, const BrickLayout& l, int b, bool f64, T* values) {
  const std::array<int, 3> o = l.origin(b), e = l.extent(b);
  std::size_t at = 0;
  for (int z = 0; z < e[2]; ++z)
    for (int y = 0; y < e[1]; ++y) {
      T* row =
          values + (std::size_t(o[2] - l.data_first + z) * l.dims[1] + (o[1] + y)) * l.dims[0] + o[0];
      for (int x = 0; x < e[0]; ++x, ++at)
        row[x] += f64 ? T(reinterpret_cast<const double*>(brick.data())[at])
                      : T(reinterpret_cast<const float*>(brick.data())[at]);
    }
}
}  // namespace

void add_brick(const std::vector<unsigned char>& brick, const BrickLayout& l, int b, bool f64,
               double* values) {
  add(brick, l, b, f64, values);
}

void add_brick(const std::vector<unsigned char>& brick, const BrickLayout& l, int b, bool f64,
               float* values) {
  add(brick, l, b, f64, values);
}

}  // namespace ivr
