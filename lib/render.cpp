// render.cpp — the forward render operation: packs the scene for the device, picks the kernel
// variant, launches every view at once and reads back images and sample counts.
#include "ivr/render.hpp"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <numeric>

#include "device_params.hpp"
#include "device_scene.hpp"
#include "empty_space.hpp"
#include "kernel_sources.hpp"
#include "runtime.hpp"
#include "scene_checks.hpp"
#include "variants.hpp"

namespace ivr {

namespace {

// The render program of a variant (compiled once per process, then from the caches).
cl::Program render_program(Device::Impl& dev, const RenderVariant& variant, double* seconds) {
  double s = 0;
  cl::Program p = dev.programs.get(
      dev.context, dev.device, dev.info, variant.preamble() + assemble_kernel("render.cl"),
      extra_build_options(), "render.cl [" + variant.label() + "]", &s);
  *seconds += s;
  return p;
}

template <class Real>
Image render_as(Device::Impl& dev, const Scene& scene, const Integrator& integrator,
                const RenderOptions& options, RenderStats* stats) {
  const Precision precision = options.precision;
  const Camera& cam0 = scene.cameras.front();
  Image image;
  image.views = int(scene.cameras.size());
  image.height = cam0.height;
  image.width = cam0.width;
  image.channels = scene.channels();
  const std::size_t pixels = std::size_t(image.views) * image.height * image.width;

  // Device buffers first: their size checks fail before any large host allocation.
  cl::Buffer out_image =
      dev.buffer(CL_MEM_WRITE_ONLY, pixels * image.channels * sizeof(float), nullptr, "the image");
  cl::Buffer out_samples =
      dev.buffer(CL_MEM_WRITE_ONLY, pixels * sizeof(cl_uint), nullptr, "the sample counts");
  const DeviceScene<Real> dscene(dev, scene);

  RenderVariant variant = RenderVariant::of(scene, integrator, precision);
  double build_seconds = 0;
  BrickGrid grid;
  // Skipping when asked for, or (automatic) when the TF has a zero range and enough bricks are
  // empty: the grid comes from the skipping variant's program, which then renders.
  variant.skip_empty =
      options.empty_space == EmptySpace::on ||
      (options.empty_space == EmptySpace::automatic && tf_has_empty_range(scene.tf));
  if (variant.skip_empty)
    variant.brick_size =
        options.brick_size > 0 ? options.brick_size : auto_brick_size(scene.volume);
  cl::Program program = render_program(dev, variant, &build_seconds);
  if (variant.skip_empty) {
    const auto start = std::chrono::steady_clock::now();
    grid = scene_grid(dev, program, dscene.volume, scene, variant.brick_size);
    if (stats) {
      stats->empty_fraction = grid.empty_fraction;
      stats->grid_seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    if (options.empty_space == EmptySpace::automatic &&
        grid.empty_fraction < options.min_empty_fraction) {
      variant.skip_empty = false;
      variant.brick_size = RenderVariant().brick_size;
      program = render_program(dev, variant, &build_seconds);
    }
  }
  const std::uint8_t none = 0;  // kernels need a buffer even when they do not read it
  cl::Buffer occupied =
      dev.buffer(CL_MEM_READ_ONLY, variant.skip_empty ? grid.occupied.size() : 1,
                 variant.skip_empty ? grid.occupied.data() : &none, "the occupancy grid");

  cl::Event done;
  cl_call("running the render kernel on " + dev.info.name, [&] {
    cl::Kernel k(program, "render");
    int a = dscene.set_args(k, scene, integrator);
    k.setArg(a++, occupied);
    k.setArg(a++, cl_int4{{grid.nx, grid.ny, grid.nz, 0}});
    k.setArg(a++, out_image);
    k.setArg(a++, out_samples);
    const LaunchParams launch = launch_params(dev.info, "render");
    if (launch.local_x > 0) {  // global size rounded up; the kernel skips the padding
      const int lx = launch.local_x, ly = launch.local_y;
      const int gx = (image.width + lx - 1) / lx * lx, gy = (image.height + ly - 1) / ly * ly;
      dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(gx, gy, image.views),
                                     cl::NDRange(lx, ly, 1), nullptr, &done);
    } else {
      dev.queue.enqueueNDRangeKernel(k, cl::NullRange,
                                     cl::NDRange(image.width, image.height, image.views),
                                     cl::NullRange, nullptr, &done);
    }
    done.wait();
  });

  image.pixels.resize(pixels * image.channels);
  std::vector<cl_uint> samples(pixels);
  cl_call("reading the image back", [&] {
    dev.queue.enqueueReadBuffer(out_image, CL_TRUE, 0, image.pixels.size() * sizeof(float),
                                image.pixels.data());
    dev.queue.enqueueReadBuffer(out_samples, CL_TRUE, 0, samples.size() * sizeof(cl_uint),
                                samples.data());
  });
  if (stats) {
    stats->kernel_seconds = event_seconds(done);
    stats->build_seconds = build_seconds;
    stats->samples = std::accumulate(samples.begin(), samples.end(), std::uint64_t(0));
    stats->variant = variant.label();
    stats->skipped_empty = variant.skip_empty;
  }
  return image;
}

}  // namespace

Image render(Device& device, const Scene& scene, const RenderOptions& options, RenderStats* stats) {
  Integrator integrator = scene.integrator;
  if (options.step != 0) integrator.step = options.step;
  validate_with(scene, integrator);
  Device::Impl& dev = device.impl();
  if (options.precision == Precision::f64) {
    if (!dev.info.fp64)
      throw Error(Status::unsupported,
                  "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
    return render_as<double>(dev, scene, integrator, options, stats);
  }
  return render_as<float>(dev, scene, integrator, options, stats);
}

}  // namespace ivr
