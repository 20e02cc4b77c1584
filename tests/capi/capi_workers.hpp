// capi_workers.hpp — workers of the C API's split operations in tests: each worker's sum through a
// WorkerSum rendezvous, as the ivr_sum_fn a binding passes (an MPI_Allreduce's stand-in).
#pragma once
#include <algorithm>
#include <cstddef>
#include <vector>

#include "multi_device/worker_sum.hpp"

namespace ivr::test {

// Worker `rank`'s side of the rendezvous `sum`, and how often its sum was called.
struct CapiWorker {
  WorkerSum* sum;
  int rank;
  int calls = 0;
};

// ivr_sum_fn (user: a CapiWorker): `values` replaced by their sum over the workers, added in rank
// order.
inline int capi_summed(double* values, std::size_t count, void* user) {
  CapiWorker* w = static_cast<CapiWorker*>(user);
  ++w->calls;
  std::vector<double> v(values, values + count);
  w->sum->sum(w->rank, v);
  std::copy(v.begin(), v.end(), values);
  return 1;
}

}  // namespace ivr::test
