// empty_space_device.cpp — the occupancy grid for a launch (brick ranges on the host for CPU
// devices, by the brick_ranges kernel of kernels/empty_space.cl elsewhere) and the decision to
// skip.
#include <algorithm>
#include <chrono>
#include <cstdlib>

#include "device_scene.hpp"
#include "empty_space.hpp"
#include "ivr/error.hpp"
#include "kernel_sources.hpp"
#include "runtime.hpp"
#include "variants.hpp"

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

// The occupancy grid from the volume already on the device: brick ranges by a kernel, read back
// and mapped through the TF on the host.
BrickGrid device_grid(Device::Impl& dev, const cl::Buffer& volume, const Scene& scene, int size,
                      Precision precision) {
  RenderVariant variant;
  variant.precision = precision;
  variant.brick_size = size;
  const cl::Program program = dev.programs.get(
      dev.context, dev.device, dev.info, variant.preamble() + assemble_kernel("empty_space.cl"),
      extra_build_options(), "empty_space.cl [" + variant.label() + "]");
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

BrickGrid scene_grid(Device::Impl& dev, const cl::Buffer& volume, const Scene& scene, int size,
                     Precision precision) {
  // A volume that lives only on the device (a reconstruction's) is gridded there too.
  const bool host_data = scene.volume.data.size() == scene.volume.voxel_count();
  return grid_on_device(dev.info) || !host_data ? device_grid(dev, volume, scene, size, precision)
                                                : build_brick_grid(scene.volume, scene.tf, size);
}

BrickGrid plan_skipping(Device::Impl& dev, const cl::Buffer& volume, const Scene& scene,
                        EmptySpace mode, int brick_size, double min_fraction, bool allowed,
                        RenderVariant& variant, double* seconds) {
  BrickGrid grid;
  variant.skip_empty = allowed && (mode == EmptySpace::on ||
                                   (mode == EmptySpace::automatic && tf_has_empty_range(scene.tf)));
  variant.brick_size = RenderVariant().brick_size;
  if (!variant.skip_empty) return grid;
  const int size = brick_size > 0 ? brick_size : auto_brick_size(scene.volume);
  const auto start = std::chrono::steady_clock::now();
  // Where σ > 0 over the volume's whole density range no brick can be empty: one pass over the
  // densities settles what the grid (several reads of each, and a copy) would find, in a fraction
  // of its time.
  const std::vector<float>& data = scene.volume.data;
  if (mode == EmptySpace::automatic && data.size() == scene.volume.voxel_count() && !data.empty()) {
    const auto [lo, hi] = std::minmax_element(data.begin(), data.end());
    if (tf_absorbs_throughout(scene.tf, *lo, *hi)) {
      variant.skip_empty = false;
      if (seconds)
        *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      return grid;
    }
  }
  grid = scene_grid(dev, volume, scene, size, variant.precision);
  if (seconds)
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (mode == EmptySpace::automatic && grid.empty_fraction < min_fraction) {
    variant.skip_empty = false;
    grid.occupied.clear();
    return grid;
  }
  variant.brick_size = size;
  return grid;
}

cl::Buffer occupancy_buffer(Device::Impl& dev, const BrickGrid& grid) {
  const std::uint8_t none = 0;  // kernels need a buffer even when they do not read it
  return dev.buffer(CL_MEM_READ_ONLY, grid.occupied.empty() ? 1 : grid.occupied.size(),
                    grid.occupied.empty() ? &none : grid.occupied.data(), "the occupancy grid");
}

cl_int4 brick_counts(const BrickGrid& grid) {
  return cl_int4{{grid.nx, grid.ny, grid.nz, 0}};
}

}  // namespace ivr
