// worker_sum.hpp — internal: the workers' collectives for workers on threads of one process
// (several devices: lib/multi_device/; the tests' workers): what MPI_Allreduce (a sum) and
// MPI_Allgatherv (an all-gather) are to ranks.
#pragma once
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "ivr/domain.hpp"
#include "ivr/error.hpp"

namespace ivr {

// What a worker's collective throws once another worker has failed (abort()): the other
// worker's own error is the one to report.
struct WorkerSumStopped : Error {
  WorkerSumStopped() : Error(Status::invalid_argument, "the workers' exchange: another worker failed") {}
};

// Every worker calls meet() the same number of times, in the same order; each gets every
// worker's part of that round, in worker order (shared, not copied: the round's parts stay as
// they are until every worker has returned from the next round). A worker that fails calls
// abort(): the others' waiting and later calls then throw WorkerSumStopped rather than wait for
// it forever.
template <class Part>
class WorkerMeeting {
 public:
  explicit WorkerMeeting(int workers)
      : workers_(workers < 1 ? 1 : workers),
        next_(std::make_shared<std::vector<Part>>(std::size_t(workers_))) {}

  std::shared_ptr<const std::vector<Part>> meet(int worker, Part part) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (aborted_) throw WorkerSumStopped();
    if (worker < 0 || worker >= workers_)
      throw Error(Status::invalid_argument, "the workers' exchange: worker " +
                                                std::to_string(worker) + " of " +
                                                std::to_string(workers_));
    const long round = round_;
    (*next_)[std::size_t(worker)] = std::move(part);
    if (++arrived_ == workers_) {
      done_ = std::move(next_);
      next_ = std::make_shared<std::vector<Part>>(std::size_t(workers_));
      arrived_ = 0;
      ++round_;
      ready_.notify_all();
    } else {
      ready_.wait(lock, [&] { return round_ != round || aborted_; });
      if (round_ == round) throw WorkerSumStopped();
    }
    return done_;
  }

  void abort() {
    std::lock_guard<std::mutex> lock(mutex_);
    aborted_ = true;
    ready_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  int workers_, arrived_ = 0;
  long round_ = 0;
  bool aborted_ = false;
  std::shared_ptr<std::vector<Part>> next_;
  std::shared_ptr<const std::vector<Part>> done_;
};

// Each worker gets the elementwise sum over the workers of vectors of one size, added in worker
// order (the same bits on every worker and every run).
class WorkerSum {
 public:
  explicit WorkerSum(int workers) : meeting_(workers) {}
  void sum(int worker, std::vector<double>& values);
  void abort() { meeting_.abort(); }
  // The sum of worker `worker`, as GradientOptions::sum and ReconstructOptions::sum take it.
  std::function<void(std::vector<double>&)> of(int worker);

 private:
  WorkerMeeting<std::vector<double>> meeting_;
};

// Every worker's bytes to every worker, in worker order (DomainPart::all_gather).
class WorkerGather {
 public:
  explicit WorkerGather(int workers) : meeting_(workers) {}
  std::vector<std::vector<unsigned char>> all_gather(int worker,
                                                     const std::vector<unsigned char>& mine) {
    return *meeting_.meet(worker, mine);
  }
  void abort() { meeting_.abort(); }
  AllGather of(int worker) {
    return [this, worker](const std::vector<unsigned char>& mine) {
      return all_gather(worker, mine);
    };
  }

 private:
  WorkerMeeting<std::vector<unsigned char>> meeting_;
};

}  // namespace ivr
