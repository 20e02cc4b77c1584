// priors.hpp — the density priors of a reconstruction on the device (kernels/priors.cl):
// smoothed total variation and L2 smoothness, value and gradient in one pass.
#pragma once
#include "runtime/runtime.hpp"

namespace ivr {

class DensityPrior {
 public:
  DensityPrior(Device::Impl& dev, bool f64);
  // grad += ∇R(x) for R = tv·mean(φ − ε) + smooth·mean|∇x|² on an nx × ny × nz grid (x, grad:
  // device vectors of the chosen precision); returns R(x), summed on the host in a fixed order.
  // A slab of a volume split in z (reconstruct_domain.cpp): the gradient and terms of planes
  // [first, end) only (end < 0: nz) — the slab without the plane below it that it holds (first 1)
  // and without the plane it shares with the next slab (the next one's) — the means over the whole
  // volume's `voxels`; its part of R.
  double add_gradient(int nx, int ny, int nz, double tv, double smooth, double epsilon,
                      const cl::Buffer& x, const cl::Buffer& grad, int first = 0, int end = -1,
                      double voxels = 0);

 private:
  Device::Impl& dev_;
  bool f64_;
  cl::Kernel kernel_;
  cl::Buffer partial_;
};

}  // namespace ivr
