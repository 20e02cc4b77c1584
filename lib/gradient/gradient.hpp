// gradient.hpp — internal: a session's loss gradient by parameter group, in the mode the planner
// picks (lib/adjoint or lib/jacobian).
#pragma once
#include <functional>

#include "adjoint/adjoint.hpp"
#include "ivr/gradient.hpp"
#include "ivr/session.hpp"
#include "session/session.hpp"

namespace ivr {

// A data-parallel worker's run (gradient_shared): told the mode planned for this worker (in core
// or over bricks of any edge: the fixed-point sums are the same), returns the batch's FixedShare
// where every worker sums the density in fixed point (the density's adjoint then gives the whole
// batch's gradient, the rest the batch's parts), else nullptr (the share's own means, weighted by
// the caller).
using ShareDecision = std::function<const FixedShare*(Mode planned)>;

SessionGradient session_gradient(Session::Impl& s, const DeviceArray& target,
                                 const GradientRequest& request,
                                 const ShareDecision& share = {});

// gradient() as worker o.worker of o.workers (GradientOptions; lib/gradient/gradient_share.cpp).
Gradient gradient_shared(Device& device, const Scene& scene, const Image& target,
                         const std::vector<std::string>& groups, const GradientOptions& o);

// The one-shot gradient on this worker's own scene and target (no sharing), and, where `share`
// is given, its decision asked once the mode is planned (out of core: adjoint where only the
// adjoint's groups are asked for, the bricks' edge with it).
Gradient gradient_one(Device& device, const Scene& scene, const Image& target,
                      const std::vector<std::string>& groups, const GradientOptions& o,
                      const ShareDecision& share = {});

// The output shape of group `g` for `scene` (throws Error(invalid_argument) for a bad group).
std::vector<std::size_t> group_shape(const Scene& scene, const std::string& g);

}  // namespace ivr
