// resident.hpp — how ivr-bench times an operation on a session whose data is already on the
// device (records of implementation "ivr-resident"): the call enqueues, the clock stops once its
// result is ready on the device (nothing read back); the device time is the operation's kernels'.
#pragma once
#include "ivr/session.hpp"
#include "measure.hpp"

namespace ivr::bench {

// `run()` enqueues the operation and waits for its result array; `valid()` checks the warm-up's
// result as measure() does.
template <class Run, class Valid>
Measurement measure_resident(const Budget& budget, Session& session, Run&& run, Valid&& valid) {
  return measure(
      budget,
      [&] {
        run();
        return session.last_kernel_seconds();
      },
      valid);
}

}  // namespace ivr::bench
