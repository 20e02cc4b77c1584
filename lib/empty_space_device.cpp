// empty_space_device.cpp — the occupancy grid for a launch: brick ranges on the host for CPU
// devices, by the brick_ranges kernel (kernels/empty_space.cl) elsewhere.
#include <cstdlib>

#include "empty_space.hpp"
#include "ivr/error.hpp"
#include "runtime.hpp"

namespace ivr {

namespace {

// Where the grid's brick ranges are taken: on CPU devices the host (the volume is in host memory
// anyway; bench/empty_space_bench.cpp, MNI152 on PoCL: 17–21 ms threaded on the host against
// 52–62 ms by the kernel), elsewhere the device, next to its copy of the volume.
// $IVR_GRID=host|device overrides (tests run both on any device).
bool grid_on_device(const DeviceInfo& info) {
  const char* env = std::getenv("IVR_GRID");
  if (!env || !*env) return info.type != "cpu";
  const std::string v = env;
  if (v != "host" && v != "device")
    throw Error(Status::invalid_argument, "IVR_GRID must be host or device, got '" + v + "'");
  return v == "device";
}

// The occupancy grid from the volume already on the device: brick ranges by a kernel of the
// skipping variant's program, read back and mapped through the TF on the host.
BrickGrid device_grid(Device::Impl& dev, const cl::Program& program, const cl::Buffer& volume,
                      const Scene& scene, int size) {
  BrickGrid grid = brick_layout(scene.volume, size);
  const std::size_t count = std::size_t(grid.nx) * grid.ny * grid.nz;
  std::vector<float> ranges(2 * count);
  cl::Buffer out =
      dev.buffer(CL_MEM_WRITE_ONLY, ranges.size() * sizeof(float), nullptr, "the brick ranges");
  cl_call("computing the empty-space grid on " + dev.info.name, [&] {
    cl::Kernel k(program, "brick_ranges");
    k.setArg(0, volume);
    k.setArg(1, cl_int4{{scene.volume.nx, scene.volume.ny, scene.volume.nz, 0}});
    k.setArg(2, cl_int4{{grid.nx, grid.ny, grid.nz, 0}});
    k.setArg(3, out);
    dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(grid.nx, grid.ny, grid.nz));
    dev.queue.enqueueReadBuffer(out, CL_TRUE, 0, ranges.size() * sizeof(float), ranges.data());
  });
  occupy_from_ranges(grid, ranges, scene.tf);
  return grid;
}

}  // namespace

BrickGrid scene_grid(Device::Impl& dev, const cl::Program& program, const cl::Buffer& volume,
                     const Scene& scene, int size) {
  return grid_on_device(dev.info) ? device_grid(dev, program, volume, scene, size)
                                  : build_brick_grid(scene.volume, scene.tf, size);
}

}  // namespace ivr
