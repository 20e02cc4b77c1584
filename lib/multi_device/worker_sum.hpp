// worker_sum.hpp — internal: the workers' sum for workers on threads of one process (several
// devices: lib/multi_device/; the tests' workers): what MPI_Allreduce is to ranks.
#pragma once
#include <condition_variable>
#include <functional>
#include <mutex>
#include <vector>

#include "ivr/error.hpp"

namespace ivr {

// What a worker's sum throws once another worker has failed (WorkerSum::abort): the other
// worker's own error is the one to report.
struct WorkerSumStopped : Error {
  WorkerSumStopped() : Error(Status::invalid_argument, "the workers' sum: another worker failed") {}
};

// Every worker calls sum() the same number of times, in the same order, with vectors of one size:
// each gets the elementwise sum over the workers, added in worker order (the same bits on every
// worker and every run). A worker that fails calls abort(): the others' waiting and later calls
// then throw WorkerSumStopped rather than wait for it forever.
class WorkerSum {
 public:
  explicit WorkerSum(int workers);
  void sum(int worker, std::vector<double>& values);
  void abort();
  // The sum of worker `worker`, as GradientOptions::sum and ReconstructOptions::sum take it.
  std::function<void(std::vector<double>&)> of(int worker);

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  int arrived_ = 0;
  long round_ = 0;
  bool aborted_ = false;
  std::vector<std::vector<double>> parts_;
  std::vector<double> total_;
};

}  // namespace ivr
