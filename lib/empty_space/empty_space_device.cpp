// empty_space_device.cpp — the brick ranges behind the occupancy grid taken on the device (the
// brick_ranges kernel of kernels/empty_space.cl), and where a session takes them.
#include <cstdlib>

#include "empty_space/empty_space.hpp"
#include "ivr/error.hpp"
#include "runtime/launch.hpp"
#include "runtime/variants.hpp"

namespace ivr {

bool grid_on_device(const DeviceInfo& info) {
  const char* env = std::getenv("IVR_GRID");
  if (!env || !*env) return info.type != "cpu";
  const std::string v = env;
  if (v != "host" && v != "device")
    throw Error(Status::invalid_argument, "IVR_GRID must be host or device, got '" + v + "'");
  return v == "device";
}

std::vector<float> device_brick_ranges(Device::Impl& dev, KernelSet& kernels,
                                       const cl::Buffer& volume, const Volume& dims, int size,
                                       bool f64) {
  KernelConfig config("empty_space.cl", "brick_ranges");
  config.set(Switch::f64, f64).set(Switch::brick_size, size);
  const EmptySpaceGrid grid = brick_layout(dims, size);
  const std::size_t count = std::size_t(grid.nx) * grid.ny * grid.nz;
  std::vector<float> ranges(2 * count);
  cl::Buffer out =
      dev.buffer(CL_MEM_WRITE_ONLY, ranges.size() * sizeof(float), nullptr, "the brick ranges");
  cl_call("computing the empty-space grid on " + dev.info.name, [&] {
    cl::Kernel& k = kernels.get(config);
    k.setArg(0, volume);
    k.setArg(1, cl_int4{{dims.nx, dims.ny, dims.nz, 0}});
    k.setArg(2, cl_int4{{grid.nx, grid.ny, grid.nz, 0}});
    k.setArg(3, out);
    dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(grid.nx, grid.ny, grid.nz));
    dev.queue.enqueueReadBuffer(out, CL_TRUE, 0, ranges.size() * sizeof(float), ranges.data());
  });
  return ranges;
}

}  // namespace ivr
