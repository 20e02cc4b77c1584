// launch.cpp — kernel configurations to programs and kernel objects, and launch shapes from the
// device's parameter database.
#include "runtime/launch.hpp"

#include <chrono>
#include <cstdlib>

#include "runtime/device_params.hpp"
#include "ivr/error.hpp"
#include "runtime/kernel_sources.hpp"

namespace ivr {

cl::Program program_for(Device::Impl& dev, const KernelConfig& config, double* seconds) {
  const auto start = std::chrono::steady_clock::now();
  const std::string options = config.options(dev.info);
  const std::string key = config.key() + '\n' + options;
  cl::Program program = dev.programs.recall(key);
  if (!program()) {
    program = dev.programs.get(dev.context, dev.device, dev.info,
                               config.preamble() + assemble_kernel(config.file), options,
                               config.label());
    dev.programs.remember(key, program);
  }
  if (seconds)
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return program;
}

cl::Kernel& KernelSet::get(const KernelConfig& config, double* build_seconds) {
  const std::string key = config.key() + '\n' + config.entry;
  if (build_seconds) *build_seconds = 0;
  if (auto it = kernels_.find(key); it != kernels_.end()) return it->second;
  const cl::Program program = program_for(*dev_, config, build_seconds);
  cl::Kernel kernel = cl_call("creating kernel " + config.entry + " of " + config.label(),
                              [&] { return cl::Kernel(program, config.entry.c_str()); });
  return kernels_.emplace(key, std::move(kernel)).first->second;
}

namespace {
thread_local TuningProbe* current_probe = nullptr;
}  // namespace

ScopedTuningProbe::ScopedTuningProbe(TuningProbe& probe) : outer_(current_probe) {
  current_probe = &probe;
}
ScopedTuningProbe::~ScopedTuningProbe() {
  current_probe = outer_;
}
TuningProbe* tuning_probe() {
  return current_probe;
}

PixelLaunch pixel_launch(Device::Impl& dev, const cl::Kernel& kernel, const std::string& tuning,
                         int width, int height, int views, bool needs_group) {
  TuningProbe* probe = current_probe;
  const bool tuned = probe && probe->kernel == tuning;
  const LaunchParams params = tuned ? LaunchParams{probe->local_x, probe->local_y, "tuner"}
                                    : launch_params(dev.info, tuning);
  int lx = params.local_x, ly = params.local_y;
  PixelLaunch l;
  l.tuning = tuning;
  l.needs_group = needs_group;
  if (needs_group || probe)
    l.kernel_max_group = cl_call("querying " + tuning + "'s work-group limit", [&] {
      return kernel.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(dev.device);
    });
  const std::size_t max_group = l.kernel_max_group;
  if (needs_group && (lx <= 0 || std::size_t(lx) * std::size_t(ly) > max_group)) {
    // The tuner asks for shapes within the limit; one beyond it here would not be what it times.
    if (tuned && lx > 0)
      throw Error(Status::invalid_argument, "tuning " + tuning + ": " + std::to_string(lx) + "x" +
                                                std::to_string(ly) + " exceeds the kernel's " +
                                                std::to_string(max_group) + " work-items");
    lx = ly = max_group >= 64 ? 8 : max_group >= 16 ? 4 : 1;
  }
  if (lx <= 0) {  // the driver's choice
    l.global = cl::NDRange(std::size_t(width), std::size_t(height), std::size_t(views));
    l.local = cl::NullRange;
    return l;
  }
  // One row (a ray list, lib/scene/ray_list.cpp): the group's work-items along it, not idle rows.
  if (height == 1 && ly > 1) lx *= ly, ly = 1;
  const int gx = (width + lx - 1) / lx * lx, gy = (height + ly - 1) / ly * ly;
  l.global = cl::NDRange(std::size_t(gx), std::size_t(gy), std::size_t(views));
  l.local = cl::NDRange(std::size_t(lx), std::size_t(ly), 1);
  l.group_x = lx;
  l.group_y = ly;
  l.groups_per_view = std::size_t(gx / lx) * std::size_t(gy / ly);
  return l;
}

cl::Event enqueue(Device::Impl& dev, const cl::Kernel& kernel, const PixelLaunch& launch,
                  const cl::NDRange& offset, const std::vector<cl::Event>* wait) {
  cl::Event done;
  dev.queue.enqueueNDRangeKernel(kernel, offset, launch.global, launch.local, wait, &done);
  if (TuningProbe* probe = current_probe) probe->launches.push_back({launch, done});
  return done;
}

cl::Event enqueue_1d(Device::Impl& dev, const cl::Kernel& kernel, std::size_t n,
                     std::size_t group) {
  cl::Event done;
  const std::size_t global = group ? (n + group - 1) / group * group : n;
  dev.queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(std::max<std::size_t>(global, 1)),
                                 group ? cl::NDRange(group) : cl::NullRange, nullptr, &done);
  return done;
}

cl::Event enqueue_groups(Device::Impl& dev, const cl::Kernel& kernel, std::size_t groups,
                         std::size_t group) {
  cl::Event done;
  dev.queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(groups * group),
                                 cl::NDRange(group), nullptr, &done);
  return done;
}

double event_seconds(const cl::Event& e) {
  return 1e-9 * double(e.getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                       e.getProfilingInfo<CL_PROFILING_COMMAND_START>());
}

double events_seconds(const std::vector<cl::Event>& events) {
  double total = 0;
  for (const cl::Event& e : events) {
    e.wait();
    total += event_seconds(e);
  }
  return total;
}

}  // namespace ivr
