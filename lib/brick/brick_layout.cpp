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

BrickLayout brick_layout(int nx, int ny, int nz, int edge) {
  if (edge < 1)
    throw Error(Status::invalid_argument,
                "brick edge: " + std::to_string(edge) + " cells, must be at least 1");
  BrickLayout l;
  l.edge = edge;
  l.dims = {nx, ny, nz};
  for (int a = 0; a < 3; ++a) l.count[a] = bricks_along(l.dims[a], edge);
  return l;
}

std::array<int, 3> BrickLayout::index(int b) const {
  return {b % count[0], (b / count[0]) % count[1], b / (count[0] * count[1])};
}

std::array<int, 3> BrickLayout::origin(int b) const {
  const std::array<int, 3> i = index(b);
  return {i[0] * edge, i[1] * edge, i[2] * edge};
}

std::array<int, 3> BrickLayout::extent(int b) const {
  const std::array<int, 3> o = origin(b);
  std::array<int, 3> e{};
  for (int a = 0; a < 3; ++a) e[a] = std::min(o[a] + edge, dims[a] - 1) - o[a] + 1;
  return e;
}

std::size_t BrickLayout::voxels(int b) const {
  const std::array<int, 3> e = extent(b);
  return std::size_t(e[0]) * e[1] * e[2];
}

std::size_t BrickLayout::largest_voxels() const {
  std::size_t n = 1;
  for (int a = 0; a < 3; ++a) n *= std::size_t(std::min(edge, dims[a] - 1) + 1);
  return n;
}

std::array<double, 3> BrickLayout::lo(int b) const {
  const std::array<int, 3> i = index(b);
  std::array<double, 3> p{};
  for (int a = 0; a < 3; ++a)
    p[a] = i[a] == 0 ? -std::numeric_limits<double>::infinity() : double(i[a]) * edge;
  return p;
}

std::array<double, 3> BrickLayout::hi(int b) const {
  const std::array<int, 3> i = index(b);
  std::array<double, 3> p{};
  for (int a = 0; a < 3; ++a)
    p[a] = i[a] == count[a] - 1 ? std::numeric_limits<double>::infinity()
                                : double(i[a] + 1) * edge;
  return p;
}

std::uint64_t brick_budget(Device& device) {
  const std::uint64_t budget = device_memory_budget(device.info());
  const std::uint64_t in_use = std::uint64_t(std::max<std::int64_t>(device.impl().live->bytes, 0));
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
      const T* row = values + (std::size_t(o[2] + z) * l.dims[1] + (o[1] + y)) * l.dims[0] + o[0];
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

void add_brick(const std::vector<unsigned char>& brick, const BrickLayout& l, int b, bool f64,
               double* values) {
  const std::array<int, 3> o = l.origin(b), e = l.extent(b);
  std::size_t at = 0;
  for (int z = 0; z < e[2]; ++z)
    for (int y = 0; y < e[1]; ++y) {
      double* row = values + (std::size_t(o[2] + z) * l.dims[1] + (o[1] + y)) * l.dims[0] + o[0];
      for (int x = 0; x < e[0]; ++x, ++at)
        row[x] += f64 ? reinterpret_cast<const double*>(brick.data())[at]
                      : double(reinterpret_cast<const float*>(brick.data())[at]);
    }
}

}  // namespace ivr
