// capi_split_support.hpp — what the C API's split-operation tests share: each worker's sum through
// a WorkerSum rendezvous, as the ivr_sum_fn a binding passes (an MPI_Allreduce's stand-in), and
// the comparison of the workers' results with one process's.
#pragma once
#include <algorithm>
#include <cmath>
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

// The largest |a − b| over the largest |b| (b: one process's values); infinite where the sizes
// differ.
inline double worst_relative(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return INFINITY;
  double worst = 0, scale = 0;
  for (std::size_t i = 0; i < b.size(); ++i) {
    worst = std::max(worst, std::abs(a[i] - b[i]));
    scale = std::max(scale, std::abs(b[i]));
  }
  return worst / std::max(scale, 1e-300);
}

}  // namespace ivr::test
