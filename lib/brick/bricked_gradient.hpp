// bricked_gradient.hpp — internal: the density gradient of a volume that does not fit the device,
// brick by brick (kernels/bricked.cl bricked_adjoint): the forward sweeps of the out-of-core
// render, then the adjoint sweeps from each ray's composited prefix and pixel adjoint.
#pragma once
#include <string>
#include <vector>

#include "brick/bricked_render.hpp"
#include "ivr/gradient.hpp"

namespace ivr {

// Runs gradient() out of core; throws Error(unsupported) for what it does not cover yet (groups
// other than density, schemes other than midpoint). `domain`: this worker's slab alone (as
// render_bricked); the gradient of its planes.
Gradient gradient_bricked(Device& device, const Scene& scene, const Image& target,
                          const std::vector<std::string>& groups, const GradientOptions& options,
                          const BrickPlan& plan, const DomainPart* domain = nullptr,
                          DomainStats* domain_stats = nullptr);

}  // namespace ivr
