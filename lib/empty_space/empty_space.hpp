// empty_space.hpp — the brick occupancy grid behind empty-space skipping: which bricks of cells
// can hold σ > 0 under the scene's transfer function (kernels/empty_space.cl reads it).
#pragma once
#include <cstdint>
#include <vector>

#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

struct EmptySpaceGrid {
  int size = 8;                        // cells per brick edge (IVR_BRICK_SIZE)
  int nx = 0, ny = 0, nz = 0;          // bricks per axis
  std::vector<std::uint8_t> occupied;  // x fastest; 0: σ = 0 at every point the brick's rays read
  double empty_fraction = 0;           // of the bricks
};

// Whether σ(d) can be non-zero for some density d in [lo, hi] (conservative: true when unsure).
bool tf_may_absorb(const TransferFunction& tf, double lo, double hi);
// Whether σ > 0 at every density in [lo, hi] (conservative: false when unsure); then no brick of
// a volume with densities in [lo, hi] can be empty.
bool tf_absorbs_throughout(const TransferFunction& tf, double lo, double hi);
// Whether σ is exactly 0 on some density interval: without one no brick can be empty.
bool tf_has_empty_range(const TransferFunction& tf);

// Brick b along an axis covers the cells [b·size, (b+1)·size); its min/max density is taken over
// those cells' corner voxels and one more voxel on each side (so samples that rounding puts a
// cell past the brick's face are still covered). The renderer takes the ranges on the device
// (kernels/empty_space.cl, brick_ranges); build_brick_grid does the same on the host.
EmptySpaceGrid brick_layout(const Volume& volume, int size);  // sizes only, nothing occupied yet
// Sets occupied and empty_fraction from per-brick [min, max] pairs (x fastest).
void occupy_from_ranges(EmptySpaceGrid& grid, const std::vector<float>& ranges,
                        const TransferFunction& tf);
EmptySpaceGrid build_brick_grid(const Volume& volume, const TransferFunction& tf, int size = 8);

// 16 to 32 bricks along the longest edge: 4 cells up to 128 voxels, else 8. (Measured by
// bench/empty_space_bench.cpp: on neghip, 64³, bricks of 4 skip 57 % of the bricks against 39 %
// for 8 and render 1.55× faster against 1.42×; on MNI152 both sizes are within the noise.)
int auto_brick_size(const Volume& volume);

// Whether a gradient may skip empty bricks and stay exact: the skipped samples must contribute
// nothing to what is differentiated. σ = 0 there, so colours and the background are safe; the
// TF's extinction parameters are not (∂σ/∂extinction_k ≠ 0 where σ = 0), and the density and
// camera need σ' = 0 too, which holds on the zero ranges of piecewise-linear and table TFs (both
// ends of the segment at 0) but not for the identity TF (σ' = its scale).
bool gradient_may_skip(const TransferFunction& tf, bool grad_tf, bool grad_density_or_camera);

// The per-brick [min, max] pairs of build_brick_grid, on the host (threaded) or by the
// brick_ranges kernel of kernels/empty_space.cl over densities already on the device.
std::vector<float> host_brick_ranges(const Volume& volume, int size);
class KernelSet;
std::vector<float> device_brick_ranges(Device::Impl& dev, KernelSet& kernels,
                                       const cl::Buffer& volume, const Volume& dims, int size,
                                       bool f64);
// Where a session takes the ranges when it has the densities on the host too: on CPU devices
// the host (the volume is in host memory anyway; bench/empty_space_bench.cpp, MNI152 on PoCL:
// 17–21 ms threaded on the host against 52–62 ms by the kernel), elsewhere the device.
// $IVR_GRID=host|device overrides (tests run both on any device).
bool grid_on_device(const DeviceInfo& info);

}  // namespace ivr
