// runtime.hpp — the OpenCL layer: error translation, device discovery and the Device internals.
#pragma once
#include <atomic>
#include <cstdint>
#include <memory>
#include <CL/opencl.hpp>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/error.hpp"
#include "runtime/program_cache.hpp"

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

// How the scatter kernels (the adjoint's, the back-projector's) add reals to global memory
// (kernels/atomics.cl): the device's own float atomic add where it reports cl_ext_float_atomics
// for this precision, else inline PTX on NVIDIA's OpenCL (which has native adds but does not
// report them), else a compare-and-swap loop. $IVR_ATOMICS=auto|ext|ptx|cas forces one the device
// offers (a clear error otherwise); the older $IVR_FLOAT_ATOMICS=0 means cas.
enum class AtomicAdd { compare_and_swap, ext_float_atomics, ptx };
AtomicAdd atomic_add_for(const DeviceInfo& info, bool f64);
// "compare-and-swap", "cl_ext_float_atomics" or "ptx": the gradient's `atomics` and labels.
const char* atomic_add_name(AtomicAdd kind);

// How kernels/sample_count.cl gets its correctly rounded float32 division and square root on this
// device (the IVR_COUNT_ARITHMETIC values there): through float64 where the device has it and its
// compiler keeps it (fp64_count_usable), else corrected by fma residuals, which need nothing but
// fma. $IVR_COUNT_ARITHMETIC=auto|fp64|option|residual forces one the device offers (residual
// runs everywhere; option: the device's own division built with
// -cl-fp32-correctly-rounded-divide-sqrt), for tests.
enum class CountArithmetic { fp64 = 0, option = 1, residual = 2 };
CountArithmetic count_arithmetic(const DeviceInfo& info);
// Whether (float)((double)a / (double)b) is the correctly rounded float32 quotient on this device:
// it has float64 and is not NVIDIA's OpenCL, whose compiler turns that expression back into its
// float32 division (not correctly rounded by default): measured on an H200 (driver 580.159), where
// the fp64 count took 1764 samples for the definition's 1800 and camera rays moved by an ulp.
bool fp64_count_usable(const DeviceInfo& info);

struct Device::Impl {
  DeviceInfo info;
  cl::Platform platform;
  cl::Device device;
  cl::Context context;
  cl::CommandQueue queue;  // in order, profiling enabled
  ProgramCache programs;

  // Device buffer of `bytes`, checked against the device's limits first so that an impossible
  // request is a clear out_of_memory error rather than a driver failure later. Where
  // $IVR_DEVICE_MEMORY_LIMIT is set, the buffers alive on this device may not exceed it either
  // (the cap that out-of-core operations plan for, lib/brick/; others fail clearly under it).
  cl::Buffer buffer(cl_mem_flags flags, std::size_t bytes, const void* host, const char* what);

  // The bytes and buffers of this device's allocations still alive (every buffer comes from
  // buffer(); the driver's destructor callback counts them out), for leak tests and reports.
  struct Live {
    std::atomic<std::int64_t> bytes{0}, buffers{0};
    std::atomic<std::int64_t> peak{0};  // the most `bytes` has been (reset_peak() to measure)
    void reset_peak() { peak = bytes.load(); }
    // The bytes still counted once the driver's callbacks have caught up: PoCL runs them on its
    // own thread after the commands, so a just-released buffer may still count for a few ms.
    // Waits until `bytes` is at most `target` or has stopped falling for 10 ms, at most
    // `max_ms`; returns `bytes` then. Call after the queue has finished.
    std::int64_t settle(std::int64_t target = 0, int max_ms = 100) const;
  };
  std::shared_ptr<Live> live = std::make_shared<Live>();
};

// Fault injection for tests: the `nth` next buffer() call in this process (1 = the next) fails
// as a driver's CL_MEM_OBJECT_ALLOCATION_FAILURE would; 0 turns it off.
void inject_allocation_failure(long nth);

}  // namespace ivr
