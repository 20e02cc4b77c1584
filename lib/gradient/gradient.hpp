// gradient.hpp — internal: a session's loss gradient by parameter group, in the mode the planner
// picks (lib/adjoint or lib/jacobian).
#pragma once
#include "ivr/session.hpp"
#include "session/session.hpp"

namespace ivr {

SessionGradient session_gradient(Session::Impl& s, const DeviceArray& target,
                                 const GradientRequest& request);

}  // namespace ivr
