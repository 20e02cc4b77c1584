// run_shares.hpp — internal: several devices in one process, each running its share of a job on a
// thread of its own (views: multi_device.cpp; slabs: device_slabs.cpp).
#pragma once
#include <exception>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/error.hpp"
#include "multi_device/worker_sum.hpp"

namespace ivr {

// Runs job(i) for every share on its own thread; rethrows the first share's error (in order), a
// share's own rather than a collective's that another share's failure stopped (WorkerSumStopped,
// after `failed` — the collectives' abort() — was called as soon as any share failed).
template <class Job>
void run_shares(std::size_t count, Job&& job, const std::function<void()>& failed = {}) {
  std::vector<std::exception_ptr> errors(count);
  std::vector<char> stopped(count, 0);  // (not vector<bool>: the threads write their own elements)
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < count; ++i)
    threads.emplace_back([&, i] {
      try {
        job(i);
      } catch (const WorkerSumStopped&) {
        errors[i] = std::current_exception();
        stopped[i] = 1;
      } catch (...) {
        errors[i] = std::current_exception();
        if (failed) failed();
      }
    });
  for (std::thread& t : threads) t.join();
  for (std::size_t i = 0; i < count; ++i)
    if (errors[i] && !stopped[i]) std::rethrow_exception(errors[i]);
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

inline void check_devices(const std::vector<Device*>& devices) {
  if (devices.empty()) throw Error(Status::invalid_argument, "devices: none given");
  for (std::size_t i = 0; i < devices.size(); ++i)
    if (!devices[i])
      throw Error(Status::invalid_argument, "devices[" + std::to_string(i) + "]: null");
}

// Worker `worker` of `workers`' share (first, count) of n items: in proportion to `shares` (one a
// worker, as GradientOptions::shares and ReconstructOptions::shares hold them), else equal.
// Throws Error(invalid_argument) for a wrong count or a bad weight.
std::pair<std::size_t, std::size_t> worker_share(std::size_t n, int worker, int workers,
                                                 const std::vector<double>& shares);

// Each device's share of n items in proportion to share_weights(devices, given) (`parts`, one a
// device), and the devices whose share is not empty — those that run — in order, with their
// counts as weights in `weights` where asked for: what their workers split n by to get the same
// shares back (multi_device.cpp).
std::vector<std::size_t> active_shares(const std::vector<Device*>& devices, std::size_t n,
                                       const std::vector<double>& given,
                                       std::vector<std::pair<std::size_t, std::size_t>>& parts,
                                       std::vector<double>* weights);

}  // namespace ivr
