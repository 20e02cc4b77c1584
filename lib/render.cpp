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
#include "ivr/tolerance.hpp"
#include "kernel_sources.hpp"
#include "render_packet.hpp"
#include "runtime.hpp"
#include "scene_checks.hpp"
#include "variants.hpp"

namespace ivr {

// Rays per work-item of the packet kernel: 16 (128³ into 256² on PoCL, 2 Skylake-AVX512 cores:
// 16 lanes ~40 ms, 8 lanes ~60 ms, one ray per work-item ~200 ms, measured beside a build);
// $IVR_PACKET_LANES=8 takes 8.
int packet_lanes() {
  const char* env = std::getenv("IVR_PACKET_LANES");
  return env && std::string(env) == "8" ? 8 : 16;
}

// Whether a render takes kernels/render_packet.cl: on CPU devices (PoCL runs a work-item's march
// as scalar code; the packet kernel marches 8 rays in vector lanes) for the case it covers.
// $IVR_PACKET=0 turns it off (tests compare both).
bool use_packet(const Device::Impl& dev, const Scene& scene, const RenderVariant& v) {
  if (const char* env = std::getenv("IVR_PACKET"); env && std::string(env) == "0") return false;
  return dev.info.type == "cpu" && v.precision == Precision::f32 && v.scheme == Scheme::midpoint &&
         v.model == Model::emission_absorption && v.tf == TfKind::piecewise_linear &&
         !v.skip_empty && scene.tf.points.size() >= 1;
}

cl::Program packet_program(Device::Impl& dev, const RenderVariant& variant, bool primal,
                           double* seconds) {
  double s = 0;
  const std::string defines = "#define IVR_LANES " + std::to_string(packet_lanes()) +
                              "\n#define IVR_PACKET_PRIMAL " + (primal ? "1" : "0") + "\n";
  cl::Program p = dev.programs.get(
      dev.context, dev.device, dev.info,
      variant.preamble() + defines + assemble_kernel("render_packet.cl"), extra_build_options(),
      "render_packet.cl [" + variant.label() + (primal ? " primal" : "") + "]", &s);
  if (seconds) *seconds += s;
  return p;
}

void enqueue_packet(Device::Impl& dev, const cl::Kernel& kernel, const Scene& scene,
                    cl::Event* done) {
  const Camera& c = scene.cameras.front();
  dev.queue.enqueueNDRangeKernel(
      kernel, cl::NullRange,
      cl::NDRange((c.width + packet_lanes() - 1) / packet_lanes(), c.height, scene.cameras.size()),
      cl::NullRange, nullptr, done);
}

namespace {

// The render program of a variant (compiled once per process, then from the caches).
cl::Program render_program(Device::Impl& dev, const RenderVariant& variant, bool packet,
                           double* seconds) {
  if (packet) return packet_program(dev, variant, false, seconds);
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
  double grid_seconds = 0;
  const BrickGrid grid =
      plan_skipping(dev, dscene.volume, scene, options.empty_space, options.brick_size,
                    options.min_empty_fraction, true, variant, &grid_seconds);
  if (stats) {
    stats->empty_fraction = grid.empty_fraction;
    stats->grid_seconds = grid_seconds;
  }
  double build_seconds = 0;
  const bool packet = use_packet(dev, scene, variant);
  const cl::Program program = render_program(dev, variant, packet, &build_seconds);
  const cl::Buffer occupied = occupancy_buffer(dev, grid);

  cl::Event done;
  cl_call("running the render kernel on " + dev.info.name, [&] {
    cl::Kernel k(program, packet ? "render_packet" : "render");
    int a = dscene.set_args(k, scene, integrator);
    k.setArg(a++, occupied);
    k.setArg(a++, brick_counts(grid));
    k.setArg(a++, out_image);
    k.setArg(a++, out_samples);
    const LaunchParams launch = launch_params(dev.info, "render");
    if (packet) {  // packet_lanes() pixels of a row per work-item
      enqueue_packet(dev, k, scene, &done);
    } else if (launch.local_x > 0) {  // global size rounded up; the kernel skips the padding
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
    stats->variant = variant.label() + (packet ? " packet" : "");
    stats->skipped_empty = variant.skip_empty;
    stats->device_bytes = dscene.bytes +
                          pixels * (image.channels * sizeof(float) + sizeof(cl_uint)) +
                          std::max<std::size_t>(grid.occupied.size(), 1);
  }
  return image;
}

}  // namespace

Image render(Device& device, const Scene& scene, const RenderOptions& options, RenderStats* stats) {
  StepChoice choice;
  const Integrator integrator =
      integrator_for(device, scene, options.step, options.precision, options.empty_space, &choice);
  validate_with(scene, integrator);
  if (stats) {
    stats->scheme = scheme_name(integrator.scheme);
    stats->step = integrator.step;
    stats->estimated_error = choice.estimated_error;
    stats->step_seconds = choice.seconds;
  }
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
