// native_marcher.hpp — the native CPU baseline: a plain C++/OpenMP ray marcher of the same scene,
// algorithm and arithmetic (float32) as ivr's forward render kernel, and its hand-written adjoint.
#pragma once
#include <cstddef>
#include <vector>

#include "ivr/scene.hpp"

namespace ivr::bench {

// Renders (views, H, W, 4) emission–absorption, or (views, H, W, 1) absorption, with a
// piecewise_linear or identity TF, midpoint rule with `step` voxel units, early termination at
// scene.integrator.min_transmittance; returns the number of samples taken.
std::size_t native_render(const Scene& scene, double step, std::vector<float>& image);

// d loss / d voxel density, shape (nz, ny, nx), of loss = the mean over every element of
// (image − target)², image = native_render(scene, step); target has the image's layout. As ivr's
// adjoint (kernels/adjoint_midpoint.cl): per ray a primal march gives the pixel and dL/dpixel, a
// second front-to-back march recovers each sample's remaining radiance as C minus the prefix (no
// division by 1 − α, no per-sample storage) and scatters dL/d density into the 8 voxels of its
// cell. Sets `loss`; returns the samples of the adjoint march.
std::size_t native_gradient(const Scene& scene, double step, const std::vector<float>& target,
                            std::vector<float>& grad, double& loss);

}  // namespace ivr::bench
