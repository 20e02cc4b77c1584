// real_args.hpp — kernel arguments of the `real` type chosen at run time (float32 or float64), for
// operations whose precision is a run-time option rather than a template parameter.
#pragma once
#include <CL/opencl.hpp>

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

}  // namespace ivr
