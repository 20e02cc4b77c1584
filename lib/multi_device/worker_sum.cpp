// worker_sum.cpp — the workers' sum for workers on threads of one process (worker_sum.hpp).
#include "multi_device/worker_sum.hpp"

#include <algorithm>
#include <string>

namespace ivr {

WorkerSum::WorkerSum(int workers) : parts_(std::size_t(std::max(workers, 1))) {}

void WorkerSum::sum(int worker, std::vector<double>& values) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (aborted_) throw WorkerSumStopped();
  if (worker < 0 || std::size_t(worker) >= parts_.size())
    throw Error(Status::invalid_argument, "the workers' sum: worker " + std::to_string(worker) +
                                              " of " + std::to_string(parts_.size()));
  const long round = round_;
  parts_[std::size_t(worker)] = values;
  if (++arrived_ == int(parts_.size())) {
    total_.assign(values.size(), 0.0);
    for (std::size_t w = 0; w < parts_.size(); ++w) {
      if (parts_[w].size() != values.size()) {
        aborted_ = true;
        ready_.notify_all();
        throw Error(Status::invalid_argument,
                    "the workers' sum: worker " + std::to_string(w) + " gave " +
                        std::to_string(parts_[w].size()) + " values, worker " +
                        std::to_string(worker) + " " + std::to_string(values.size()));
      }
      for (std::size_t i = 0; i < values.size(); ++i) total_[i] += parts_[w][i];
    }
    arrived_ = 0;
    ++round_;
    ready_.notify_all();
  } else {
    ready_.wait(lock, [&] { return round_ != round || aborted_; });
    if (round_ == round) throw WorkerSumStopped();
  }
  values = total_;
}

void WorkerSum::abort() {
  std::lock_guard<std::mutex> lock(mutex_);
  aborted_ = true;
  ready_.notify_all();
}

std::function<void(std::vector<double>&)> WorkerSum::of(int worker) {
  return [this, worker](std::vector<double>& values) { sum(worker, values); };
}

}  // namespace ivr
