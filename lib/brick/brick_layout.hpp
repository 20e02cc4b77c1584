// brick_layout.hpp — internal: how a volume splits into bricks for the out-of-core operations
// (kernels/bricked.cl), how much device memory an operation may use, and the bricks' host copies.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/scene.hpp"
#include "runtime/device_memory.hpp"

namespace ivr {

// A volume of (nx, ny, nz) voxels in bricks of `edge` cells: along an axis of N voxels, brick k
// covers the voxel-centre coordinates [k·edge, (k+1)·edge] and holds voxels k·edge ..
// min((k+1)·edge, N − 1), so neighbours share one plane of voxels (the halo) and every trilinear
// lookup inside a brick reads its own voxels. The outer bricks reach the box faces.
//
// A halo of `halo` more voxels on every side (clamped at the volume's and the slab's ends) lets
// the endpoint schemes' gradients read and scatter into a segment's near sample, which lies up to
// one step before the window's start (brick_halo): origin() and extent() are then the held
// voxels', lo() and hi() still the planes at k·edge.
//
// Along z the bricks may cover only planes [z_first, z_last] of the volume (a domain-parallel
// process's slab, lib/brick/domain.cpp): cut from z_first, reaching ±∞ only where the slab reaches
// the box face. The host values they are cut from (extract_brick, add_brick) hold planes
// [data_first, data_last]: the slab's, or (a slab's gradient with a halo) the slab and `halo`
// planes of its neighbours' on each side, into which the halo reaches.
struct BrickLayout {
  int edge = 0;                // cells per brick edge (0: not bricked)
  std::array<int, 3> dims{};   // the volume's voxels per axis (x, y, z)
  std::array<int, 3> count{};  // bricks per axis
  int z_first = 0, z_last = 0;  // the planes the bricks cover (all: 0, dims[2] − 1)
  int data_first = 0, data_last = 0;  // the planes the host values hold (⊇ the bricks')
  int halo = 0;                 // voxels held beyond the shared plane on each side
  int total() const { return count[0] * count[1] * count[2]; }
  // Brick b's index per axis (x fastest), first voxel and voxels per axis.
  std::array<int, 3> index(int b) const;
  std::array<int, 3> corner(int b) const;  // its first plane (origin() less the halo)
  std::array<int, 3> origin(int b) const;
  std::array<int, 3> extent(int b) const;
  std::size_t voxels(int b) const;
  std::size_t largest_voxels() const;  // of any brick
  // The host values the bricks are cut from: planes data_first … data_last of the volume.
  std::size_t held() const { return std::size_t(dims[0]) * dims[1] * held_planes(); }
  int held_planes() const { return data_last - data_first + 1; }
  // Its planes in global voxel-centre coordinates: [lo, hi) per axis, ±infinity at the box faces.
  std::array<double, 3> lo(int b) const;
  std::array<double, 3> hi(int b) const;
};

// Bricks of `edge` cells (≥ 1) over the volume's dims; along z over planes [z_first, z_last]
// (z_last < 0: to the last plane), each holding `halo` voxels more on every side.
BrickLayout brick_layout(int nx, int ny, int nz, int edge, int z_first = 0, int z_last = -1,
                         int halo = 0);

// The halo the trapezoid and preintegrated gradients need out of core: a segment's near sample lies
// less than one step (in voxels along any axis: step × the largest inverse voxel size) before the
// window its far end lies in, and its trilinear cell starts up to one voxel lower; 0 for midpoint
// and exact (each sample or piece lies in its window's brick). `deterministic` (the fixed-point
// density gradient): at least 1, so that a sample whose point rounds a hair past its brick's plane
// reads and scatters into the voxels beyond as in core, and the integers equal the in-core ones.
int brick_halo(const Scene& scene, double step, bool deterministic = false);
// Throws Error(unsupported) where the step a gradient's march takes (the session's: a tolerance
// may have chosen it) needs a wider halo than `layout` holds.
void check_brick_halo(const Scene& scene, double step, const BrickLayout& layout);

// What the device-memory budget (device_memory_budget) leaves beside the device's buffers alive
// now: what an out-of-core plan may take (0: no budget known).
std::uint64_t brick_budget(Device& device);

// Brick b's voxels from host values of the layout's dims (x fastest; planes from data_first), converted to the kernels'
// real (float or double) into `out` (bytes, resized).
void extract_brick(const float* values, const BrickLayout& layout, int b, bool f64,
                   std::vector<unsigned char>& out);
void extract_brick(const double* values, const BrickLayout& layout, int b, bool f64,
                   std::vector<unsigned char>& out);
inline void extract_brick(const Volume& volume, const BrickLayout& layout, int b, bool f64,
                          std::vector<unsigned char>& out) {
  extract_brick(volume.data.data(), layout, b, f64, out);
}
// Adds brick b's values (the kernels' real, `f64` or not) into the host values of the layout's
// dims: the planes bricks share get every brick's part.
void add_brick(const std::vector<unsigned char>& brick, const BrickLayout& layout, int b, bool f64,
               double* values);
void add_brick(const std::vector<unsigned char>& brick, const BrickLayout& layout, int b, bool f64,
               float* values);

}  // namespace ivr
