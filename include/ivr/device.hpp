// ivr/device.hpp — OpenCL devices as ivr sees them: listing, selecting, and a handle that owns a
// context, a queue and the compiled kernels for one device.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ivr/export.h"

namespace ivr {

struct DeviceInfo {
  int index = 0;                                              // position in list_devices()
  int platform_index = 0;                                     // OpenCL platform number
  int device_index = 0;                                       // device number within its platform
  std::string platform, name, vendor, type, version, driver;  // type: cpu, gpu, accelerator
  bool fp64 = false;
  // CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT in CL_DEVICE_SINGLE_FP_CONFIG: the device can build
  // float32 division and sqrt correctly rounded (-cl-fp32-correctly-rounded-divide-sqrt).
  bool correctly_rounded_divide_sqrt = false;
  // cl_ext_float_atomics: atomic add of float / double to global and local memory (the adjoint's
  // scatter uses it instead of a compare-and-swap loop), and the -cl-std that enables it.
  bool float_atomic_add = false, double_atomic_add = false;
  std::string atomics_std;  // "CL3.0" or "CL2.0" where either is true
  // NVIDIA's OpenCL (cl_nv_device_attribute_query): the CUDA compute capability, major·10 + minor
  // (0 elsewhere). Its OpenCL C compiles inline PTX, whose red.global.add.f32 (sm_20 on) and
  // .f64 (sm_60 on) are the native float atomic adds it does not report as cl_ext_float_atomics.
  int nv_compute_capability = 0;
  std::uint64_t global_memory = 0, max_allocation = 0;
  int compute_units = 0;
  int max_clock_mhz = 0;  // CL_DEVICE_MAX_CLOCK_FREQUENCY (0 where the driver does not say)
  // CL_DEVICE_HOST_UNIFIED_MEMORY: the device's memory is the host's (CPUs, integrated GPUs), so
  // DeviceArray::wrap and map() reach host memory without a copy.
  bool host_unified_memory = false;
};

// Every device of every platform; throws ivr::Error(no_device) if there is no OpenCL platform.
IVR_API std::vector<DeviceInfo> list_devices();
// The same as one JSON document: {"devices": [{index, platform, name, vendor, type, version,
// driver, fp64, float_atomic_add, double_atomic_add, global_memory, ...}, ...]}.
IVR_API std::string devices_json();

// A selected device with its context, in-order profiling queue and program cache.
// Selector: "" uses $IVR_DEVICE, else the first GPU, else the first device; "cpu", "gpu" or
// "accelerator" take the first of that type; "N" the N-th of list_devices(); "P:D" platform P's
// device D; anything else is a case-insensitive substring of "platform device-name".
class IVR_API Device {
 public:
  explicit Device(const std::string& selector = "");
  ~Device();
  Device(Device&&) noexcept;
  Device& operator=(Device&&) noexcept;

  const DeviceInfo& info() const;

  struct Impl;
  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ivr
