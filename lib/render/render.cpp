// render.cpp — the forward render: the scene's variant (model, TF, integrator, precision,
// skipping) marched for every pixel of every view in one launch on the session's device copies;
// and the one-shot render(), a session for one call.
#include "ivr/render.hpp"

#include <cstdlib>
#include <string>

#include "ivr/error.hpp"
#include "render/render.hpp"

#include "brick/bricked_render.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"

namespace ivr {

// Rays per work-item of a packet (kernels/rays.cl): 16 float32 or 8 float64 lanes, one AVX-512
// register (128³ into 256² on PoCL, 2 Skylake-AVX512 cores: 16 lanes ~40 ms, 8 lanes ~60 ms, one
// ray per work-item ~200 ms, measured beside a build); $IVR_PACKET_LANES=8 takes 8 for float32.
int packet_lanes(Precision precision) {
  if (precision == Precision::f64) return 8;
  const char* env = std::getenv("IVR_PACKET_LANES");
  return env && std::string(env) == "8" ? 8 : 16;
}

// Whether a render marches packets of rays in vector lanes: on CPU devices (PoCL runs a
// work-item's march as scalar code and cannot vectorise across work-items), for every integrator,
// TF kind, model and precision, with or without skipping. $IVR_PACKET=0 turns it off (tests
// compare both), and so does the tuner while it times the one-ray-per-work-item kernel.
bool use_packet(const Device::Impl& dev) {
  if (const char* env = std::getenv("IVR_PACKET"); env && std::string(env) == "0") return false;
  if (const TuningProbe* probe = tuning_probe(); probe && !probe->packet) return false;  // ivr tune
  return dev.info.type == "cpu";
}

// Whether the adjoint takes its primal march from a packet render: what kernels/adjoint.cl reads
// back (C, T and a midpoint march's samples, which are its end without skipping).
bool use_packet_primal(const Device::Impl& dev, const RenderVariant& v) {
  return use_packet(dev) && v.scheme == Scheme::midpoint && v.model == Model::emission_absorption &&
         !v.empty_space;
}

KernelConfig packet_config(const RenderVariant& variant, bool primal) {
  return variant.config("render.cl", "render")
      .set(Switch::rays, packet_lanes(variant.precision))
      .set(Switch::packet_primal, primal);
}

PacketShape packet_shape(int lanes, bool ray_list) {
  if (ray_list && (lanes == 16 || lanes == 8 || lanes == 1)) return {lanes, 1};
  if (lanes == 16) return {4, 4};
  if (lanes == 8) return {4, 2};
  if (lanes == 1) return {1, 1};
  throw Error(Status::invalid_argument,
              "packets hold 1, 8 or 16 rays, not " + std::to_string(lanes));
}

PixelLaunch packet_launch(Device::Impl& dev, const cl::Kernel& kernel, const Scene& scene,
                          Precision precision) {
  const ImageExtent c = image_extent(scene);
  const PacketShape tile = packet_shape(packet_lanes(precision), scene.has_ray_list());
  return pixel_launch(dev, kernel, "render_packet", tile.across(c.width), tile.down(c.height),
                      c.views, false);
}

DeviceArray enqueue_render(Session::Impl& s, OperationRecord& op) {
  const Integrator& integrator = s.integrator();
  RenderVariant variant = s.variant_of(integrator);
  const cl::Buffer& occupied = s.plan_skipping(true, variant, op.stats);
  const bool packet = use_packet(s.dev);
  const KernelConfig config =
      packet ? packet_config(variant, false) : variant.config("render.cl", "render");
  const std::size_t pixels = s.pixels();
  const std::vector<std::int64_t> shape = s.image_shape();
  // The image in the precision it was computed in (float64 stays float64 to the user).
  DeviceArray image = s.output("image", shape, real_dtype(s.f64), "the image");
  const cl::Buffer& samples = s.scratch("samples", pixels * sizeof(cl_uint), "the sample counts");
  cl_call("running the render kernel on " + s.dev.info.name, [&] {
    cl::Kernel& k = s.kernels.get(config, &op.stats.build_seconds);
    int a = s.set_scene_args(k, integrator);
    k.setArg(a++, occupied);
    k.setArg(a++, s.brick_counts());
    k.setArg(a++, buffer_of(image));
    k.setArg(a++, samples);
    const ImageExtent c = image_extent(s.scene);
    const PixelLaunch launch = packet ? packet_launch(s.dev, k, s.scene, variant.precision)
                                      : pixel_launch(s.dev, k, "render", c.width, c.height,
                                                     c.views, false);
    op.events.push_back(enqueue(s.dev, k, launch));
  });
  mark_written(image, op.events.back());
  op.samples = samples;
  op.sample_count = pixels;
  op.stats.variant = config.label();
  op.stats.skipped_empty = variant.empty_space;
  op.stats.step = integrator.step;
  op.stats.device_bytes = s.scene_bytes() + image.bytes() + pixels * sizeof(cl_uint) +
                          (variant.empty_space ? s.grid.grid.occupied.size() : 1);
  return image;
}

Session one_shot_session(Device& device, const Scene& scene, const SessionOptions& options) {
  if (scene.volume.data.size() != scene.volume.voxel_count())
    throw Error(Status::invalid_argument,
                "volume: holds " + std::to_string(scene.volume.data.size()) +
                    " values but dims need " + std::to_string(scene.volume.voxel_count()));
  return Session(std::make_unique<Session::Impl>(device, scene, options, true));
}

void download_kept(const DeviceArray& a, std::vector<float>* floats, std::vector<double>* doubles) {
  doubles->clear();
  if (a.dtype() != DType::f64) {
    *floats = a.to_floats();
    return;
  }
  *doubles = a.to_doubles();
  floats->assign(doubles->begin(), doubles->end());
}

Image image_of(const DeviceArray& image) {
  const std::vector<std::int64_t> shape = image.shape();
  // A ray list's (rays, channels) is one view of one row on the host (ivr::Image).
  Image out = shape.size() == 2 ? Image{1, 1, int(shape[0]), int(shape[1])}
                                : Image{int(shape[0]), int(shape[1]), int(shape[2]), int(shape[3])};
  download_kept(image, &out.pixels, &out.pixels_f64);
  return out;
}

Image render(Device& device, const Scene& scene, const RenderOptions& options, RenderStats* stats) {
  const BrickPlan plan = plan_render(device, scene, options.precision, options.volume_brick);
  if (plan.layout.edge) return render_bricked(device, scene, options, plan, stats);
  Session session = one_shot_session(device, scene,
                                     {options.precision, options.step, options.empty_space,
                                      options.min_empty_fraction, options.brick_size});
  Session::Impl& s = session.impl();
  const Image out = image_of(enqueue_render(s, s.begin("render")));
  if (stats) {
    const OperationStats st = session.last_stats();
    stats->kernel_seconds = st.kernel_seconds;
    stats->build_seconds = st.build_seconds;
    stats->samples = st.samples;
    stats->variant = st.variant;
    stats->skipped_empty = st.skipped_empty;
    stats->empty_fraction = st.empty_fraction;
    stats->grid_seconds = st.grid_seconds;
    stats->scheme = scheme_name(s.integrator().scheme);
    stats->step = st.step;
    stats->estimated_error = s.choice.estimated_error;
    stats->step_seconds = s.choice.seconds;
    stats->device_bytes = st.device_bytes;
  }
  return out;
}

}  // namespace ivr
