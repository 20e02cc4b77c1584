// tolerance.hpp — internal: the integrator step a session chooses for an error tolerance.
#pragma once
#include "session/session.hpp"

namespace ivr {

// The integrator step chosen for a tolerance by pilot renders of `s`'s scene at a quarter of the
// resolution.
StepChoice choose_session_step(Session::Impl& s, double tolerance);

}  // namespace ivr
