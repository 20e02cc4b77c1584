// bricked_tangent.hpp — internal: forward mode (tangent lanes) of a volume that does not fit the
// device, brick by brick (kernels/bricked_tangent.cl): the out-of-core render's sweeps carrying
// each ray's tangents, in passes of up to 32 lanes.
#pragma once
#include <vector>

#include "brick/bricked_render.hpp"
#include "ivr/gradient.hpp"

namespace ivr {

struct BrickedTangent {
  double loss = 0;
  std::vector<double> gradient;  // d loss / d parameter, in the order of the lanes given
  std::size_t passes = 0, lanes = 0;
  double kernel_seconds = 0;
  std::uint64_t device_bytes = 0;
};

// The loss and its derivatives with respect to `lanes` (lanes_of(): TF, background, camera,
// voxel, step and ray-list lanes) out of core, as `plan` splits the volume; equal to the in-core
// forward mode to rounding. Throws Error(out_of_memory) where not even one lane's per-ray
// tangents fit beside the plan.
// `domain` (lib/brick/domain.cpp): this worker marches its slab's bricks alone, the rays' states
// and tangents passed between the workers, so that every worker ends with every ray's tangents
// and returns the whole loss and gradient. `densities`: BrickedMarch::densities_f64.
BrickedTangent tangent_bricked(Device& device, const Scene& scene, const Image& target,
                               const std::vector<cl_int4>& lanes, const GradientOptions& options,
                               const BrickPlan& plan, const DomainPart* domain = nullptr,
                               DomainStats* domain_stats = nullptr,
                               const std::vector<double>* densities = nullptr);

}  // namespace ivr
