// ivr/gradient.hpp — the gradient of an image loss with respect to named parameter groups,
// in forward or adjoint mode, chosen by the planner unless asked for: what `ivr gradient` runs.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/adjoint.hpp"
#include "ivr/planner.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// Groups: "density" (every voxel), "tf" (tf_gradient_shape), "tf_points" (control-point
// densities, forward only), "scales" (identity TF), "background", "camera" (views x 7:
// [eye xyz, target xyz, fov_y]), "step" (the integrator step: the render depends on
// it only through the sample count, so its derivative is 0), "voxels:LIST" (the listed voxel
// indices, x fastest; LIST is comma-separated indices and ranges a-b).
struct GroupGradient {
  std::string name;                // as asked for ("voxels" for a voxel list)
  std::vector<std::size_t> shape;  // of the output array
  std::vector<double> values;
};

struct GradientOptions {
  Mode mode = Mode::automatic;
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step and tolerance (voxel units)
  Loss loss = Loss::mse;
  // The density gradient summed in fixed point where the device has 64-bit integer atomics
  // (AdjointOptions::deterministic; adjoint mode): the same bits on every run, and the one
  // process's in-core bits over several devices or data-parallel workers, out of core (any
  // bricks) and over slabs with the rays' states passed (gradient_domain, SlabMarch::states) —
  // every scheme; independent segments (SlabMarch::segments) repeat bit for bit and lie within
  // the fixed-point rounding of the in-core gradient. Data-parallel workers, in core or out of
  // core over bricks of any edge (there asking for the adjoint's groups alone: density, tf,
  // background), give the one process's bits (docs/scaling.md).
  bool deterministic = false;
  // Data-parallel over views (docs/scaling.md): this call is worker `worker` of `workers` (> 1),
  // every worker passing the whole scene and target and calling together; each differentiates its
  // share of the views (view_shares; a ray list: rays) and `sum` — the workers' elementwise sum of
  // doubles, every worker getting it (an MPI_Allreduce; every worker calls it alike) — combines
  // them: every worker gets the whole loss and gradient, per-view rows included. With
  // `deterministic` (and every worker in core, in adjoint mode, with 64-bit integer atomics, and a
  // view for every worker) the density gradient is the one process's bit for bit.
  int worker = 0, workers = 1;
  std::function<void(std::vector<double>&)> sum;
  // Each share's weight, its share of the views in proportion (view_shares): over several devices
  // one a device (empty: share_weights(), their speeds; gradient_domain over devices: their
  // slabs' planes, domain_slab); as worker of `workers`, one a worker, every worker passing the
  // same (empty: equal shares).
  std::vector<double> shares{};
};

struct Gradient {
  double loss = 0;
  Plan plan;  // the mode used, and both modes' predicted seconds
  std::vector<GroupGradient> groups;
  std::size_t parameters = 0;      // values computed, over all groups
  double kernel_seconds = 0;       // device time of every kernel run
  std::uint64_t device_bytes = 0;  // peak device memory
  std::string atomics;             // adjoint mode: the scatter's atomics
  double step = 0;                 // the integrator step used (voxel units)
  int bricks = 1;                  // the volume's out-of-core bricks (1: in core)
  int devices = 1;                 // the devices the views were spread over
  bool deterministic = false;      // the density gradient was summed in fixed point
};

// Splits a --wrt list ("tf,voxels:3,17,40-45,background") into group names; voxel lists take the
// integers and ranges that follow them. Throws ivr::Error(invalid_argument) naming a bad item.
IVR_API std::vector<std::string> parse_groups(const std::string& list);

IVR_API Gradient gradient(Device& device, const Scene& scene, const Image& target,
                                      const std::vector<std::string>& groups,
                                      const GradientOptions& options = {});

// The target of views (a ray list: rays) [first, first + count) of `scene` (scene_share()).
IVR_API Image target_share(const Scene& scene, const Image& target, std::size_t first,
                           std::size_t count);
// Groups with a row per view or ray (camera, rays): data-parallel shares join them in order
// rather than summing them.
IVR_API bool per_view_group(const std::string& group);

// The same on several devices (docs/scaling.md): each device differentiates the loss of its
// share of the views (a ray list's rays), as a worker of options' kind on a thread of its own;
// the loss and the gradients are the shares' weighted by their sizes (the mean losses; `dot`:
// summed), added in device order; the rays' own gradients are joined in ray order. With
// `deterministic` the density gradient is one device's bit for bit. One device where
// options.workers > 1 (a worker's devices are not split further).
IVR_API Gradient gradient(const std::vector<Device*>& devices, const Scene& scene,
                          const Image& target, const std::vector<std::string>& groups,
                          const GradientOptions& options = {});

}  // namespace ivr
