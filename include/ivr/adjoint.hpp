// ivr/adjoint.hpp — reverse-mode (adjoint) gradients of an image loss with respect to every voxel,
// the transfer function's parameters and the background, in constant memory per ray.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "ivr/export.h"
#include "ivr/render.hpp"
#include "ivr/tf_parameters.hpp"

namespace ivr {

enum class Loss {
  mse,  // mean over every element of (image - target)^2
  l1,   // mean over every element of |image - target| (subgradient 0 where they are equal)
  dot,  // sum over every element of target * image: its gradient is the vector-Jacobian product
        // of the render with the target as the weights (dL/dimage = target; autograd's backward)
};

struct AdjointOptions {
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step and tolerance (voxel units)
  Loss loss = Loss::mse;
  bool density = true;      // d loss / d voxel density
  bool tf = false;          // d loss / d transfer-function parameters (layout: tf_gradient_shape)
  bool background = false;  // d loss / d background (1 value for absorption, 3 for emission)
  bool camera = false;      // d loss / d [eye xyz, target xyz, fov_y] of every view
  // Empty-space skipping (as RenderOptions), where it leaves the gradient exact: not with tf,
  // and with density or camera only for piecewise-linear and table TFs (lib/empty_space/empty_space.hpp).
  EmptySpace empty_space = EmptySpace::automatic;
  int brick_size = 0;
  // Sums the density gradient in 64-bit fixed point (where the device has
  // cl_khr_int64_base_atomics), so that it does not depend on the order in which rays add to a
  // voxel: the same inputs give the same bits on every run. Each ray's share is scaled by a
  // power of two 2^S and rounded to an integer; the integer sums are exact. S is chosen before
  // the march from an a-priori bound B on what one ray adds (from the TF's extremes over the
  // densities' range, the background, the target's largest element, the loss and the box
  // diagonal: lib/adjoint/adjoint_bound.hpp), so that B·2^S < 2^62 / (2 · rays) and no voxel's sum can
  // leave the 64-bit range: one pass. A second pass, at the scale the largest ray measured in the
  // first calls for, runs only where a ray's scaled share exceeded 2^62 / rays (the bound failed;
  // the kernel checks every ray) or the largest single contribution kept fewer than 24 bits (the
  // bound was too loose to resolve it like a float); AdjointGradient::fixed_passes says which. Every
  // step depends on the inputs alone, so the bits do too (not on earlier calls). The TF,
  // background and camera gradients keep their float atomics.
  bool deterministic = false;
};

struct AdjointGradient {
  double loss = 0;
  std::vector<float> density;      // volume shape (nz, ny, nx) when asked for, else empty
  std::vector<double> tf;          // rows x columns (tf_gradient_shape), when asked for
  std::vector<double> background;  // when asked for
  std::vector<double> camera;      // views x 7 [eye xyz, target xyz, fov_y], when asked for
  double kernel_seconds = 0;       // device time: primal render + loss + adjoint march
  std::uint64_t device_bytes = 0;  // peak device memory of the evaluation (all its buffers)
  std::uint64_t samples = 0;       // density samples of the adjoint march
  std::string atomics;             // the scatter's: "cl_ext_float_atomics" or "compare-and-swap"
  bool skipped_empty = false;      // empty-space skipping ran
  double empty_fraction = 0;       // of the bricks, when the grid was built
  double step = 0;                 // the integrator step used (voxel units)
  bool deterministic = false;      // the density gradient was summed in fixed point
  int fixed_exponent = 0;          // its scale 2^S, when it was
  int fixed_passes = 0;            // the adjoint passes that took (1; 2 where the bound failed)
};

// The TF gradient's layout: ivr/tf_parameters.hpp.

// Loss of `image` against `target` (same shape) — evaluated on the host in double precision.
IVR_API double image_loss(const Image& image, const Image& target, Loss loss);

// Renders the scene, evaluates the loss against `target` (shape (views, H, W, C) of the render)
// and marches every ray again backwards-in-effect (front to back, with the remaining radiance
// C minus the prefix: no division by (1 - alpha), no per-sample storage) to accumulate the
// gradients asked for. Throws ivr::Error: invalid_argument for a target of the wrong shape or
// with NaN/Inf.
IVR_API AdjointGradient adjoint(Device& device, const Scene& scene, const Image& target,
                          const AdjointOptions& options = {});

}  // namespace ivr
