// optimize.hpp — the optimiser's device state (kernels/optimize.cl) and its step on device
// buffers, for the reconstruction loops that keep parameters and gradients on the device.
#pragma once
#include "ivr/optimize.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

struct Optimizer::Impl {
  Device::Impl& dev;
  OptimizerOptions options;
  std::size_t count;
  bool f64;
  int iterations = 0;
  cl::Buffer first, second;  // Adam: m, v; SGD: the velocity
  cl::Kernel kernel;

  Impl(Device::Impl& device, std::size_t count, const OptimizerOptions& options,
       Precision precision);
  // x ← project(x − update(g)) with the next learning rate; enqueued, not waited for.
  cl::Event step(const cl::Buffer& x, const cl::Buffer& g);
};

}  // namespace ivr
