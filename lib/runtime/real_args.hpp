// real_args.hpp — kernel arguments and device vectors of the `real` type chosen at run time
// (float32 or float64), for operations whose precision is a run-time option rather than a
// template parameter (the projector, the solvers, the optimisers).
#pragma once
#include <CL/opencl.hpp>
#include <algorithm>
#include <vector>

#include "runtime/runtime.hpp"

namespace ivr {

inline void set_real(cl::Kernel& k, cl_uint index, bool f64, double value) {
  if (f64)
    k.setArg(index, cl_double(value));
  else
    k.setArg(index, cl_float(value));
}

inline void set_real4(cl::Kernel& k, cl_uint index, bool f64, double x, double y, double z,
                      double w = 0) {
  if (f64)
    k.setArg(index, cl_double4{{x, y, z, w}});
  else
    k.setArg(index, cl_float4{{float(x), float(y), float(z), float(w)}});
}

// A device vector of the values (at least one element: buffers cannot be empty).
inline cl::Buffer upload_reals(Device::Impl& dev, bool f64, const std::vector<double>& values,
                               const char* what) {
  const cl_mem_flags flags = CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR;
  if (values.empty()) return dev.buffer(CL_MEM_READ_WRITE, f64 ? 8 : 4, nullptr, what);
  if (f64) return dev.buffer(flags, values.size() * 8, values.data(), what);
  const std::vector<float> converted(values.begin(), values.end());
  return dev.buffer(flags, converted.size() * 4, converted.data(), what);
}

// The values into the device vector `buffer` (at least as long), as the kernels' reals.
inline void write_reals(Device::Impl& dev, bool f64, const cl::Buffer& buffer,
                        const std::vector<double>& values) {
  if (values.empty()) return;
  cl_call("writing a vector to the device", [&] {
    if (f64) {
      dev.queue.enqueueWriteBuffer(buffer, CL_TRUE, 0, values.size() * 8, values.data());
    } else {
      const std::vector<float> converted(values.begin(), values.end());
      dev.queue.enqueueWriteBuffer(buffer, CL_TRUE, 0, converted.size() * 4, converted.data());
    }
  });
}

inline std::vector<double> download_reals(Device::Impl& dev, bool f64, const cl::Buffer& buffer,
                                          std::size_t n) {
  std::vector<double> out(n);
  if (n == 0) return out;
  cl_call("reading a vector back from the device", [&] {
    if (f64) {
      dev.queue.enqueueReadBuffer(buffer, CL_TRUE, 0, n * 8, out.data());
    } else {
      std::vector<float> values(n);
      dev.queue.enqueueReadBuffer(buffer, CL_TRUE, 0, n * 4, values.data());
      std::copy(values.begin(), values.end(), out.begin());
    }
  });
  return out;
}

}  // namespace ivr
