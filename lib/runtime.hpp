// runtime.hpp — the OpenCL layer: error translation, device discovery and the Device internals.
#pragma once
#include <CL/opencl.hpp>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/error.hpp"
#include "program_cache.hpp"

namespace ivr {

// "CL_OUT_OF_RESOURCES" for -5, "CL_UNKNOWN_ERROR" for codes it does not know.
const char* cl_error_name(int code);

// Turns an OpenCL failure into ivr::Error: "<call> failed with CL_NAME (code) while <doing>".
[[noreturn]] void throw_cl(const cl::Error& e, const std::string& doing);

// Runs f(), translating cl::Error into ivr::Error with the context `doing`.
template <class F>
auto cl_call(const std::string& doing, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const cl::Error& e) {
    throw_cl(e, doing);
  }
}

// The device's own float atomic add (cl_ext_float_atomics) where it has one for this precision,
// unless $IVR_FLOAT_ATOMICS=0 asks for the compare-and-swap loop (for comparisons).
bool use_float_atomics(const DeviceInfo& info, bool f64);

struct Device::Impl {
  DeviceInfo info;
  cl::Platform platform;
  cl::Device device;
  cl::Context context;
  cl::CommandQueue queue;  // in order, profiling enabled
  ProgramCache programs;

  // Device buffer of `bytes`, checked against the device's limits first so that an impossible
  // request is a clear out_of_memory error rather than a driver failure later.
  cl::Buffer buffer(cl_mem_flags flags, std::size_t bytes, const void* host, const char* what);
};

}  // namespace ivr
