// launch.hpp — the one launch layer of every operation: a kernel configuration (file, entry point,
// generated #define preamble, build flags) → its program from the cache → a kernel object kept by
// its owner → launches shaped by the device's tuned parameters (lib/runtime/device_params.cpp).
#pragma once
#include <CL/opencl.hpp>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "runtime/kernel_config.hpp"
#include "runtime/runtime.hpp"

namespace ivr {


// The program of a configuration: remembered per process by its key (so a warm call neither
// assembles nor hashes the source), else through the program cache (memory, disk, compiler).
// *seconds (optional) receives the time spent.
cl::Program program_for(Device::Impl& dev, const KernelConfig& config, double* seconds = nullptr);

// The kernels one owner (a session, a projector) has made, by configuration: each is created once
// and then only has its arguments set. Not shared between threads (setArg is not thread-safe on
// one kernel object); a session serialises its operations.
class KernelSet {
 public:
  explicit KernelSet(Device::Impl& dev) : dev_(&dev) {}
  cl::Kernel& get(const KernelConfig& config, double* build_seconds = nullptr);

 private:
  Device::Impl* dev_;
  std::unordered_map<std::string, cl::Kernel> kernels_;
};

// One work-item per pixel of every view. The work-group size comes from the parameter database
// under `tuning`; kernels with barriers or local memory (`needs_group`) always get one (the
// database's, else 8x8, within the kernel's limit); others leave it to the driver where the
// database has none. The global size is rounded up to whole groups; kernels skip the padding.
struct PixelLaunch {
  cl::NDRange global, local;
  int group_x = 0, group_y = 0;      // 0 with a driver-chosen size
  std::size_t groups_per_view = 0;   // whole work-groups per view (with an explicit size)
  std::string tuning;                // the database's name for the kernel
  bool needs_group = false;          // barriers or local memory: always an explicit group
  std::size_t kernel_max_group = 0;  // CL_KERNEL_WORK_GROUP_SIZE, where it was asked for
};
PixelLaunch pixel_launch(Device::Impl& dev, const cl::Kernel& kernel, const std::string& tuning,
                         int width, int height, int views, bool needs_group);

// The tuner's hook (lib/tune/tune.cpp), the one way its shapes reach the launches: while a probe is
// installed on a thread, pixel launches there under the probe's tuning name take its shape instead
// of the database's (0x0: the driver's choice, or the fallback of kernels that need a group),
// renders can be kept off the CPU packet kernel, and every pixel launch is recorded with its
// shape and event. Nothing in the environment changes, so other threads launch as before.
struct TuningProbe {
  std::string kernel;  // the tuning name to shape; "" shapes none and only records
  int local_x = 0, local_y = 0;
  bool packet = true;  // false: renders take the one-ray-per-work-item kernel on CPU devices too
  struct Launch {
    PixelLaunch shape;  // its tuning name, group (0x0: the driver's choice) and kernel limit
    cl::Event event;
  };
  std::vector<Launch> launches;
};
// Installs `probe` on this thread for the scope's life (nesting restores the outer one).
class ScopedTuningProbe {
 public:
  explicit ScopedTuningProbe(TuningProbe& probe);
  ~ScopedTuningProbe();
  ScopedTuningProbe(const ScopedTuningProbe&) = delete;
  ScopedTuningProbe& operator=(const ScopedTuningProbe&) = delete;

 private:
  TuningProbe* outer_;
};
TuningProbe* tuning_probe();  // this thread's, or null

// Enqueues and returns the kernel's event (profiling is on for the device's queue); `offset`: the
// first work-item's ids (a rectangle of the image), `wait`: what it waits for.
cl::Event enqueue(Device::Impl& dev, const cl::Kernel& kernel, const PixelLaunch& launch,
                  const cl::NDRange& offset = cl::NullRange,
                  const std::vector<cl::Event>* wait = nullptr);
// One work-item per element: n rounded up to `group` (0: the driver's choice, n as is).
cl::Event enqueue_1d(Device::Impl& dev, const cl::Kernel& kernel, std::size_t n,
                     std::size_t group = 0);
// `groups` work-groups of `group` items (the reductions of kernels/array_ops.cl).
cl::Event enqueue_groups(Device::Impl& dev, const cl::Kernel& kernel, std::size_t groups,
                         std::size_t group);

// Device time of a finished command from its profiling event.
double event_seconds(const cl::Event& e);
// Their sum; waits for each.
double events_seconds(const std::vector<cl::Event>& events);

}  // namespace ivr
