// adjoint.hpp — internal: the adjoint (reverse-mode) operation of a session: the loss and its
// gradients with respect to the densities, the TF, the background and the cameras in one march.
#pragma once
#include <string>

#include "session/session.hpp"

namespace ivr {

struct AdjointRequest {
  bool density = true, tf = false, background = false, camera = false;
  Loss loss = Loss::mse;
  bool deterministic = false;
};
struct AdjointResult {
  DeviceArray loss, density, tf, background, camera, image;
  std::string atomics;
};
AdjointResult enqueue_adjoint(Session::Impl& s, const DeviceArray& target, const AdjointRequest& r,
                              OperationRecord& op);

}  // namespace ivr
