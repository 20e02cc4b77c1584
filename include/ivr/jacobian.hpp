// ivr/jacobian.hpp — forward-mode differentiation: the derivative of every pixel (a Jacobian) and
// of an image loss with respect to a few scene parameters, carried as P tangent lanes through one
// march (kernels/jacobian.cl). The right mode for transfer functions, cameras and global scalars.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/adjoint.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// One differentiable scalar of a scene.
//   tf:         row `index`, `column` of the TF layout (tf_gradient_shape): [r, g, b, extinction]
//               (Gaussians: + [mean, width]; identity: [extinction_scale, color_scale]); column 4
//               of a piecewise-linear TF is the control point's density.
//   background: channel `index` (absorption: 0, the incoming intensity).
//   camera:     view `index`, `column` 0..6 = [eye x, y, z, target x, y, z, fov_y (degrees)].
//   step:       the integrator step (voxel units).
//   voxel:      density of voxel `index` (x fastest).
//   ray:        ray `index` of a ray list, `column` 0..7 = [origin x, y, z, direction x, y, z,
//               t_start, t_end] (world units). Each ray's pixel depends on its own ray only, so
//               every ray's parameters share 8 tangent lanes: a loss gradient over all of them
//               costs one pass. The direction's gradient is that of the normalised direction
//               (tangent to the unit sphere: ivr normalises the directions it is given); an
//               infinite end (the box's entry or exit) has gradient 0. Not with `jacobian`.
enum class ParameterGroup { tf, background, camera, step, voxel, ray };
struct Parameter {
  ParameterGroup group = ParameterGroup::tf;
  std::int64_t index = 0;
  int column = 0;
};

// The parameters of one named group, in the layout its outputs use: "tf" (rows x columns of
// tf_gradient_shape), "tf_points" (control-point densities of a piecewise-linear TF), "scales"
// (the identity TF's two scales), "background", "camera" (7 per view), "step", "density" (every
// voxel), "voxels:LIST" (comma-separated indices and ranges a-b, x fastest). Throws
// ivr::Error(invalid_argument) naming the group when the scene has no such parameters.
IVR_API std::vector<Parameter> parameters_of(const Scene& scene, const std::string& group);

struct JacobianOptions {
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step and tolerance (voxel units)
  Loss loss = Loss::mse;
  bool jacobian = false;  // also return d pixel / d parameter for every pixel
  // Empty-space skipping (as RenderOptions), where it leaves every lane exact: not with TF
  // lanes, and with camera or voxel lanes only for piecewise-linear and table TFs.
  EmptySpace empty_space = EmptySpace::automatic;
  int brick_size = 0;
};

struct Jacobian {
  double loss = 0;                 // of the render against the target (0 without a target)
  std::vector<double> gradient;    // d loss / d parameter, one per parameter (with a target)
  std::vector<float> jacobian;     // (views, H, W, C, P) when asked for
  std::vector<double> jacobian_f64;  // the same unrounded, from a float64 run (else empty)
  Image image;                     // the render the derivatives are of
  double kernel_seconds = 0;       // all passes
  int passes = 0, lanes = 0;       // kernel launches, and tangent lanes per launch
  std::uint64_t device_bytes = 0;  // peak device memory of one pass
  bool skipped_empty = false;      // empty-space skipping ran
  std::string variant;             // the kernel configuration of the last pass (as RenderStats)
  double step = 0;                 // the integrator step used (voxel units)
};

// Forward-mode derivatives of the render of `scene` with respect to `parameters`: the Jacobian
// (options.jacobian) and, when `target` is given, the loss and its gradient, reduced on the device
// without writing the Jacobian. Parameters run in passes of up to 32 lanes.
IVR_API Jacobian jacobian(Device& device, const Scene& scene,
                          const std::vector<Parameter>& parameters, const Image* target,
                          const JacobianOptions& options = {});

}  // namespace ivr
