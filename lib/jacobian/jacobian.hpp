// jacobian.hpp — internal: the forward-mode (tangent-lane) operation of a session: the Jacobian
// of every pixel and the loss's derivatives with respect to a list of parameters.
#pragma once
#include <vector>

#include "ivr/jacobian.hpp"
#include "session/session.hpp"

namespace ivr {

struct JacobianResult {
  DeviceArray loss, gradient, jacobian, image;
};
// Lanes as kernels/jacobian.cl's int4s (lanes_of); the Jacobian where `jacobian`, the loss and
// its gradient where `target` is given.
JacobianResult enqueue_jacobian(Session::Impl& s, const std::vector<cl_int4>& lanes,
                                const DeviceArray* target, bool jacobian, Loss loss,
                                OperationRecord& op);
std::vector<cl_int4> lanes_of(const Scene& scene, const std::vector<Parameter>& parameters);
// IVR_LANES for `count` parameters in one pass: the power of two at or above it.
int lanes_for(std::size_t count);

}  // namespace ivr
