// bricked_project.hpp — internal: the projector pair N, Nᵀ brick by brick (kernels/project.cl's
// project_brick and backproject_brick) for volumes that do not fit the device: N v = Σ_b N_b v_b
// (the lines summed on the device), Nᵀ y = Σ_b E_bᵀ N_bᵀ y (each brick's back-projection added into
// the host volume; the planes bricks share get both parts), the exact transpose of the bricked N.
#pragma once
#include <vector>

#include "brick/brick_layout.hpp"
#include "ivr/tomo.hpp"

namespace ivr {

// Bricks for the projector of `scene`'s grid and rays in `precision`: forced_edge (or
// $IVR_VOLUME_BRICK) where > 0, else none (edge 0) where the volume and the lines fit the budget,
// else the largest power-of-two edge whose two bricks and the lines fit. Throws
// Error(out_of_memory) where nothing fits.
BrickLayout plan_projector(Device& device, const Scene& scene, Precision precision,
                           int forced_edge = 0);

// N volume, the volume's `voxels` values on the host as float or double (the out-of-core CGLS keeps
// float32 iterates where the precision is float32: half the host memory).
template <typename T>
std::vector<double> project_bricked(Projector::Impl& p, const BrickLayout& layout, const T* volume);
// out = Nᵀ lines (out: the layout's voxels — the grid's, or a slab's planes — overwritten).
template <typename T>
void backproject_bricked(Projector::Impl& p, const BrickLayout& layout,
                         const std::vector<double>& lines, T* out);

}  // namespace ivr
