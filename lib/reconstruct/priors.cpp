// priors.cpp — runs kernels/priors.cl's density_prior and sums its partial values.
#include "reconstruct/priors.hpp"

#include "runtime/launch.hpp"
#include "runtime/real_args.hpp"

namespace ivr {

namespace {
constexpr std::size_t kItems = 4096;  // work-items of the grid-stride loop (each a partial sum)
}

DensityPrior::DensityPrior(Device::Impl& dev, bool f64) : dev_(dev), f64_(f64) {
  KernelConfig config("priors.cl", "density_prior");
  config.set(Switch::f64, f64);
  const cl::Program program = program_for(dev, config);
  cl_call("setting up the density prior", [&] { kernel_ = cl::Kernel(program, "density_prior"); });
  partial_ =
      dev.buffer(CL_MEM_READ_WRITE, kItems * (f64 ? 8 : 4), nullptr, "the prior's partial sums");
}

double DensityPrior::add_gradient(int nx, int ny, int nz, double tv, double smooth, double epsilon,
                                  const cl::Buffer& x, const cl::Buffer& grad, int first, int end,
                                  double voxels) {
  if (voxels <= 0) voxels = double(nx) * double(ny) * double(nz);
  cl_call("running the density prior on " + dev_.info.name, [&] {
    cl_uint a = 0;
    kernel_.setArg(a++, cl_int4{{nx, ny, nz, end < 0 ? nz : end}});
    kernel_.setArg(a++, cl_int(first));
    set_real(kernel_, a++, f64_, tv);
    set_real(kernel_, a++, f64_, smooth);
    set_real(kernel_, a++, f64_, epsilon);
    set_real(kernel_, a++, f64_, 1 / voxels);
    kernel_.setArg(a++, x);
    kernel_.setArg(a++, grad);
    kernel_.setArg(a++, partial_);
    dev_.queue.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(kItems), cl::NullRange);
  });
  double sum = 0;
  for (double v : download_reals(dev_, f64_, partial_, kItems)) sum += v;
  return sum;
}

}  // namespace ivr
