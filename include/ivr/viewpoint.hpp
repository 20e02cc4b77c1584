// ivr/viewpoint.hpp — best-viewpoint selection: gradient ascent of a differentiable image entropy
// over a camera's orbit (azimuth and elevation about its target), in forward mode. What `ivr
// viewpoint` runs (after DiffDVR's best-viewpoint experiment).
#pragma once
#include <functional>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/optimize.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// Entropy of view 0 of an image: with q_i a pixel's brightness (emission–absorption: the mean of
// R, G, B; absorption: 1 − I/I_in, the attenuation) plus 1e-6, p_i = q_i / Σ q, H = −Σ p_i ln p_i,
// divided by ln(pixels) so that it lies in [0, 1] (1: the brightness spread evenly).
// `gradient` (optional) receives dH/d pixel value for every element of view 0 (H, W, C).
IVR_API double image_entropy(const Image& image, std::vector<double>* gradient = nullptr,
                             double background = 1.0);

struct ViewpointOptions {
  int view = 0;  // the scene's camera to start from (its distance to the target is kept)
  int iterations = 40;
  OptimizerOptions optimizer;  // lr in radians per step (0: 0.05); adam, sgd or lbfgs
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step (voxel units)
};

struct ViewpointStep {
  int iteration = 0;                  // 0: the start
  double entropy = 0;                 // at the angles below
  double azimuth = 0, elevation = 0;  // degrees, about the camera's up axis through its target
};

struct Viewpoint {
  Camera camera;  // the best camera found (highest entropy seen)
  double entropy = 0;
  std::vector<ViewpointStep> history;
};

// Throws ivr::Error(invalid_argument) for a bad view index, iteration count or optimiser.
// `progress` (optional) is called after every iteration; returning false stops early.
IVR_API Viewpoint select_viewpoint(Device& device, const Scene& scene,
                                   const ViewpointOptions& options = {},
                                   const std::function<bool(const ViewpointStep&)>& progress = {});

}  // namespace ivr
