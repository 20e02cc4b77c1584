// bricked_gradient.hpp — internal: the gradient of a volume that does not fit the device, brick by
// brick (kernels/bricked_adjoint.cl): the forward sweeps of the out-of-core render, then the
// adjoint sweeps from each ray's composited prefix and pixel adjoint; forward lanes beside them.
#pragma once
#include <string>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "brick/bricked_render.hpp"
#include "ivr/gradient.hpp"

namespace ivr {

// Runs gradient() out of core: density, TF and background by the adjoint's sweeps (unless forward
// mode is asked for), the other groups (camera, tf_points, scales, voxels, rays) by forward lanes
// (lib/brick/bricked_tangent.cpp); throws Error(unsupported) for what it does not cover yet
// (schemes other than midpoint, density in forward mode, forward groups over slabs). `domain`: this worker's slab alone (as
// render_bricked); the gradient of its planes. `densities`: BrickedMarch::densities_f64. `share`:
// a data-parallel worker's share of a batch summed in fixed point (gradient_shared): the mean's
// normaliser, the scale and the second-pass decision the batch's, the density the whole batch's
// (the shares' integer sums added), the loss, TF and background this share's part of the batch's.
Gradient gradient_bricked(Device& device, const Scene& scene, const Image& target,
                          const std::vector<std::string>& groups, const GradientOptions& options,
                          const BrickPlan& plan, const DomainPart* domain = nullptr,
                          DomainStats* domain_stats = nullptr,
                          const std::vector<double>* densities = nullptr,
                          const FixedShare* share = nullptr);

}  // namespace ivr
