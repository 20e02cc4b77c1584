// worker_sum.cpp — the workers' sum for workers on threads of one process (worker_sum.hpp).
#include "multi_device/worker_sum.hpp"

#include <string>

namespace ivr {

void WorkerSum::sum(int worker, std::vector<double>& values) {
  const std::shared_ptr<const std::vector<std::vector<double>>> parts =
      meeting_.meet(worker, values);
  // Every worker adds the same parts in the same order: the same bits everywhere.
  std::vector<double> total(values.size(), 0.0);
  for (std::size_t w = 0; w < parts->size(); ++w) {
    const std::vector<double>& part = (*parts)[w];
    if (part.size() != values.size())
      throw Error(Status::invalid_argument,
                  "the workers' sum: worker " + std::to_string(w) + " gave " +
                      std::to_string(part.size()) + " values, worker " + std::to_string(worker) +
                      " " + std::to_string(values.size()));
    for (std::size_t i = 0; i < values.size(); ++i) total[i] += part[i];
  }
  values = std::move(total);
}

std::function<void(std::vector<double>&)> WorkerSum::of(int worker) {
  return [this, worker](std::vector<double>& values) { sum(worker, values); };
}

}  // namespace ivr
