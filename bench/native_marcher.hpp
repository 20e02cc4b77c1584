// native_marcher.hpp — the native CPU baseline: a plain C++/OpenMP ray marcher of the same scene,
// algorithm and arithmetic (float32) as ivr's forward render kernel.
#pragma once
#include <vector>

#include "ivr/scene.hpp"

namespace ivr::bench {

// Renders (views, H, W, 4) emission–absorption with a piecewise_linear TF, midpoint rule with
// `step` voxel units, early termination at scene.integrator.min_transmittance; returns the
// number of samples taken.
std::size_t native_render(const Scene& scene, double step, std::vector<float>& image);

}  // namespace ivr::bench
