// jacobian.cpp — forward-mode differentiation: parameters by group, passes of up to 32 tangent
// lanes of kernels/jacobian.cl on the session's device copies, the Jacobian's columns and the
// loss gradient (the work-groups' partial sums reduced) assembled on the device; and the
// one-shot jacobian().
#include "ivr/jacobian.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "gradient/parameter_groups.hpp"
#include "ivr/error.hpp"
#include "ivr_constants.h"
#include "jacobian/jacobian.hpp"
#include "render/render.hpp"
#include "runtime/real_args.hpp"
#include "scene/scene.hpp"
#include "scene/tf_kinds.hpp"
#include "session/session.hpp"

namespace ivr {

namespace {

constexpr int kMaxLanes = IVR_MAX_LANES;

// Lane kinds of kernels/jacobian.cl.
enum LaneKind {
  lane_none = IVR_LANE_NONE,
  lane_tf = IVR_LANE_TF,
  lane_background = IVR_LANE_BACKGROUND,
  lane_camera = IVR_LANE_CAMERA,
  lane_voxel = IVR_LANE_VOXEL,
  lane_step = IVR_LANE_STEP,
  lane_ray = IVR_LANE_RAY
};

Error bad_parameter(std::size_t i, const std::string& why) {
  return Error(Status::invalid_argument, "parameter " + std::to_string(i) + ": " + why);
}

// The kernel's int4 for parameter i of the scene (checked against the scene).
cl_int4 lane_of(const Scene& scene, const Parameter& p, std::size_t i) {
  switch (p.group) {
    case ParameterGroup::tf: {
      const auto shape = tf_gradient_shape(scene.tf);
      const int columns = int(shape[1]) + (scene.tf.kind == TfKind::piecewise_linear ? 1 : 0);
      if (p.index < 0 || std::size_t(p.index) >= shape[0] || p.column < 0 || p.column >= columns)
        throw bad_parameter(i, "tf row " + std::to_string(p.index) + " column " +
                                   std::to_string(p.column) + " is outside the TF's " +
                                   std::to_string(shape[0]) + " x " + std::to_string(columns));
      return {{lane_tf, cl_int(p.index), p.column, 0}};
    }
    case ParameterGroup::background: {
      const int channels = scene.model == Model::absorption ? 1 : 3;
      if (p.index < 0 || p.index >= channels)
        throw bad_parameter(i, "background channel " + std::to_string(p.index) +
                                   " (the scene has " + std::to_string(channels) + ")");
      return {{lane_background, cl_int(p.index), 0, 0}};
    }
    case ParameterGroup::camera:
      if (scene.has_ray_list())
        throw bad_parameter(i, "camera view " + std::to_string(p.index) +
                                   ": the scene's rays are a ray list, which has no camera to "
                                   "differentiate");
      if (p.index < 0 || std::size_t(p.index) >= scene.cameras.size() || p.column < 0 ||
          p.column > 6)
        throw bad_parameter(
            i, "camera view " + std::to_string(p.index) + " component " + std::to_string(p.column) +
                   " (views: " + std::to_string(scene.cameras.size()) + ", components 0..6)");
      return {{lane_camera, cl_int(p.index), p.column, 0}};
    case ParameterGroup::step:
      return {{lane_step, 0, 0, 0}};
    case ParameterGroup::ray:
      if (!scene.has_ray_list())
        throw bad_parameter(i, "ray " + std::to_string(p.index) +
                                   ": the scene's rays are cameras' pixels, not a ray list");
      if (p.index < 0 || std::size_t(p.index) >= scene.rays.count() || p.column < 0 ||
          p.column >= RayList::kColumns)
        throw bad_parameter(i, "ray " + std::to_string(p.index) + " column " +
                                   std::to_string(p.column) + " (rays: " +
                                   std::to_string(scene.rays.count()) + ", columns 0..7)");
      // Every ray's column shares one lane (kernels/jacobian_ray.cl); .z keeps the ray.
      return {{lane_ray, p.column, cl_int(p.index), 0}};
    case ParameterGroup::voxel: {
      const Volume& v = scene.volume;
      if (p.index < 0 || std::size_t(p.index) >= v.voxel_count())
        throw bad_parameter(i, "voxel " + std::to_string(p.index) + " is outside the volume's " +
                                   std::to_string(v.voxel_count()) + " voxels");
      const std::int64_t plane = std::int64_t(v.nx) * v.ny;
      return {{lane_voxel, cl_int(p.index % v.nx), cl_int(p.index % plane / v.nx),
               cl_int(p.index / plane)}};
    }
  }
  throw bad_parameter(i, "unknown group");
}

// "3,17,40-45" → voxel indices, checked against the volume.
std::vector<std::int64_t> voxel_list(const std::string& list, const Volume& volume) {
  std::vector<std::int64_t> out;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ',')) {
    const std::size_t dash = item.find('-');
    std::int64_t a = 0, b = 0;
    try {
      a = std::stoll(item.substr(0, dash));
      b = dash == std::string::npos ? a : std::stoll(item.substr(dash + 1));
    } catch (const std::exception&) {
      throw Error(Status::invalid_argument,
                  "voxels: '" + item + "' is not an index or a range a-b");
    }
    if (a < 0 || b < a)
      throw Error(Status::invalid_argument, "voxels: range '" + item + "' is empty");
    if (std::size_t(b) >= volume.voxel_count())
      throw Error(Status::invalid_argument, "voxels: " + std::to_string(b) +
                                                " is outside the volume's " +
                                                std::to_string(volume.voxel_count()) + " voxels");
    for (std::int64_t i = a; i <= b; ++i) out.push_back(i);
  }
  if (out.empty()) throw Error(Status::invalid_argument, "voxels: the list is empty");
  return out;
}

}  // namespace

int lanes_for(std::size_t count) {
  int lanes = 1;
  while (std::size_t(lanes) < count) lanes *= 2;
  return lanes;
}

std::vector<cl_int4> lanes_of(const Scene& scene, const std::vector<Parameter>& parameters) {
  std::vector<cl_int4> lanes;
  lanes.reserve(parameters.size());
  for (std::size_t i = 0; i < parameters.size(); ++i)
    lanes.push_back(lane_of(scene, parameters[i], i));
  return lanes;
}

JacobianResult enqueue_jacobian(Session::Impl& s, const std::vector<cl_int4>& requested,
                                const DeviceArray* target, bool jacobian, Loss loss_kind,
                                OperationRecord& op) {
  Device::Impl& dev = s.dev;
  const Scene& scene = s.scene;
  const Integrator& integrator = s.integrator();
  const ImageExtent cam0 = image_extent(scene);
  const int views = cam0.views, channels = scene.channels();
  const std::size_t pixels = s.pixels(), real = s.real_size;
  const bool loss = target != nullptr;

  // A ray list's own parameters apart: each ray's pixel depends on its ray only, so column k of
  // every ray is one lane, and one pass of all 8 columns (IVR_RAY_GRADIENT) writes every ray's
  // d loss / d column; the gradient is then assembled from the other lanes' sums and those
  // per-ray values. `assemble[i]`: ray · 8 + column, or −1 − the parameter's place among the
  // other lanes.
  std::vector<cl_int4> all_lanes;
  std::vector<cl_long> assemble;
  bool ray_lanes = false;
  for (const cl_int4& l : requested) {
    if (l.s[0] == lane_ray) {
      assemble.push_back(cl_long(l.s[2]) * RayList::kColumns + l.s[1]);
      ray_lanes = true;
    } else {
      assemble.push_back(-1 - cl_long(all_lanes.size()));
      all_lanes.push_back(l);
    }
  }
  if (ray_lanes && jacobian)
    throw Error(Status::invalid_argument,
                "the Jacobian of ray parameters is not built (each ray's pixel depends on its own "
                "ray only): ask for their loss gradient, whose dot loss with one-hot weights "
                "gives any channel's derivatives");
  if (ray_lanes && !loss)
    throw Error(Status::invalid_argument,
                "ray parameters need a target: their loss gradient is what is computed");
  const std::size_t params = all_lanes.size(), total = requested.size();

  RenderVariant variant = s.variant_of(integrator);
  // Empty-space skipping where every pass stays exact (as the adjoint decides, gradient_may_skip).
  bool any_tf = false, any_position = ray_lanes;
  for (const cl_int4& l : all_lanes) {
    any_tf |= l.s[0] == lane_tf;
    any_position |= l.s[0] == lane_camera || l.s[0] == lane_voxel;
  }
  const cl::Buffer& occupied =
      s.plan_skipping(gradient_may_skip(scene.tf, any_tf, any_position), variant, op.stats);

  // The passes: up to 32 of the other lanes each (one pass without lanes where there are none,
  // for the image and the loss), then the rays' pass.
  struct Pass {
    std::size_t first = 0, count = 0;  // the other lanes it carries
    int lanes = 1;                     // IVR_LANES
    bool rays = false;
  };
  std::vector<Pass> passes;
  const int plain_lanes = lanes_for(std::min<std::size_t>(params, kMaxLanes));
  for (std::size_t first = 0; first < params || (params == 0 && !ray_lanes && first == 0);
       first += kMaxLanes) {
    passes.push_back({first, std::min<std::size_t>(kMaxLanes, params - first), plain_lanes, false});
    if (params == 0) break;
  }
  if (ray_lanes) passes.push_back({0, 0, RayList::kColumns, true});

  JacobianResult out;
  out.image = s.output("tangent image", s.image_shape(), real_dtype(s.f64), "the image");
  if (jacobian) {
    std::vector<std::int64_t> shape = s.image_shape();
    shape.push_back(std::int64_t(params));
    out.jacobian = s.output("jacobian", shape, real_dtype(s.f64), "the Jacobian");
  }
  const DType acc = s.arrays.acc_dtype();
  const std::size_t acc_size = dtype_size(acc);
  if (loss) {
    out.loss = s.output("loss", {1}, acc, "the loss");
    out.gradient = s.output("forward gradient", {std::int64_t(total)}, acc, "the gradient");
  }
  // With ray lanes the other lanes' sums gather here first, and the rays' values in ray_values.
  const cl::Buffer& plain_gradient =
      ray_lanes ? s.scratch("other lanes' gradient", std::max<std::size_t>(params, 1) * acc_size,
                            "the gradient")
                : cl::Buffer();
  const cl::Buffer& ray_values =
      ray_lanes ? s.scratch("ray gradients", pixels * RayList::kColumns * real,
                            "the rays' gradients")
                : cl::Buffer();
  const std::size_t jacobian_size = jacobian ? pixels * channels * std::size_t(plain_lanes) : 1;
  const cl::Buffer& jacobian_pass =
      s.scratch("jacobian pass", jacobian_size * (s.f64 ? 8 : 4), "the Jacobian");
  const cl::Buffer& sums =
      s.scratch("tangent sums", (std::size_t(kMaxLanes) + 1) * 8, "the loss gradient's sums");
  const cl::Buffer& target_buf =
      loss ? buffer_of(*target) : s.scratch("no target", real, "the target");

  KernelConfig base = variant.config("jacobian.cl", "jacobian");
  base.set(Switch::jacobian, jacobian)
      .set(Switch::loss_gradient, loss)
      .set(Switch::loss_l1, loss && loss_kind == Loss::l1)
      .set(Switch::loss_dot, loss && loss_kind == Loss::dot);
  op.stats.skipped_empty = variant.empty_space;
  op.stats.step = integrator.step;
  op.stats.mode = Mode::forward;
  op.stats.lanes = passes.front().lanes;
  for (std::size_t pass = 0; pass < passes.size(); ++pass) {
    const Pass& ps = passes[pass];
    const std::size_t row = std::size_t(ps.lanes) + 1;
    std::vector<cl_int4> lanes(std::size_t(ps.lanes), cl_int4{{lane_none, 0, 0, 0}});
    bool pass_tf = false, pass_camera = ps.rays, pass_voxel = false;
    if (ps.rays) {
      for (int k = 0; k < RayList::kColumns; ++k) lanes[std::size_t(k)] = {{lane_ray, k, 0, 0}};
    } else {
      for (std::size_t k = 0; k < ps.count; ++k) {
        lanes[k] = all_lanes[ps.first + k];
        pass_tf |= lanes[k].s[0] == lane_tf;
        pass_camera |= lanes[k].s[0] == lane_camera;
        pass_voxel |= lanes[k].s[0] == lane_voxel;
      }
    }
    KernelConfig config = base;
    config.set(Switch::lanes, ps.lanes)
        .set(Switch::tangent_tf, pass_tf)
        .set(Switch::tangent_camera, pass_camera)
        .set(Switch::tangent_voxel, pass_voxel)
        .set(Switch::jacobian, jacobian && !ps.rays)
        .set(Switch::ray_gradient, ps.rays);
    // On CPUs a pass of TF and background lanes marches packets of rays in vector lanes (each
    // lane a vector of the rays' tangents); camera, ray and voxel lanes, whose geometry is per
    // ray, one ray per work-item.
    const int rays =
        use_packet(dev) && !pass_camera && !pass_voxel ? packet_lanes(variant.precision) : 1;
    if (rays > 1) config.set(Switch::rays, rays);
    op.stats.variant = config.label();
    cl_call("running the tangent kernel on " + dev.info.name, [&] {
      double build = 0;
      cl::Kernel& k = s.kernels.get(config, &build);
      op.stats.build_seconds += build;
      const PacketShape tile = packet_shape(rays, variant.ray_list);
      const PixelLaunch launch =
          pixel_launch(dev, k, rays > 1 ? "jacobian_packet" : "jacobian", tile.across(cam0.width),
                       tile.down(cam0.height), views, true);
      const std::size_t groups = launch.groups_per_view * std::size_t(views);
      const cl::Buffer& partial =
          s.scratch("tangent partials", groups * row * real, "the partial sums");
      const cl::Buffer lanes_buf =
          dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, lanes.size() * sizeof(cl_int4),
                     lanes.data(), "the tangent lanes");
      op.stats.device_bytes = std::max<std::uint64_t>(
          op.stats.device_bytes,
          s.scene_bytes() + (loss ? target->bytes() : real) + groups * row * real +
              (pixels * channels + (ps.rays ? pixels * RayList::kColumns : jacobian_size)) *
                  sizeof(float) +
              lanes.size() * sizeof(cl_int4));
      int a = s.set_scene_args(k, integrator);
      k.setArg(a++, lanes_buf);
      k.setArg(a++, s.camera_params);
      k.setArg(a++, target_buf);
      set_real(k, a++, s.f64, 1.0 / double(pixels * channels));
      k.setArg(a++, buffer_of(out.image));
      k.setArg(a++, ps.rays ? ray_values : jacobian_pass);
      k.setArg(a++, partial);
      k.setArg(a++, cl::Local(std::size_t(launch.group_x) * launch.group_y * row * real));
      k.setArg(a++, occupied);
      k.setArg(a++, s.brick_counts());
      op.events.push_back(enqueue(dev, k, launch));
      if (jacobian && !ps.rays && ps.count > 0)
        op.events.push_back(s.arrays.copy_columns(pixels * channels, jacobian_pass, ps.lanes, 0,
                                                  buffer_of(out.jacobian), int(params),
                                                  int(ps.first), int(ps.count)));
      if (loss) {
        op.events.push_back(s.arrays.sum_rows(partial, int(groups), int(row), 1, sums));
        if (pass == 0) {
          op.events.push_back(cl::Event());
          dev.queue.enqueueCopyBuffer(sums, buffer_of(out.loss), 0, 0, acc_size, nullptr,
                                      &op.events.back());
        }
        if (ps.count > 0) {
          op.events.push_back(cl::Event());
          dev.queue.enqueueCopyBuffer(sums, ray_lanes ? plain_gradient : buffer_of(out.gradient),
                                      acc_size, ps.first * acc_size, ps.count * acc_size, nullptr,
                                      &op.events.back());
        }
      }
    });
    ++op.stats.passes;
  }
  if (ray_lanes)
    cl_call("assembling the gradient of the ray parameters", [&] {
      const cl::Buffer index =
          dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, assemble.size() * sizeof(cl_long),
                     assemble.data(), "the gradient's sources");
      op.events.push_back(s.arrays.assemble(ray_values, plain_gradient, index, total,
                                            buffer_of(out.gradient)));
    });
  for (DeviceArray* a : {&out.image, &out.jacobian, &out.loss, &out.gradient})
    if (a->valid()) mark_written(*a, op.events.back());
  return out;
}

std::vector<Parameter> parameters_of(const Scene& scene, const std::string& group) {
  std::vector<Parameter> out;
  const auto shape = tf_gradient_shape(scene.tf);
  if (group == "tf") {
    for (std::size_t r = 0; r < shape[0]; ++r)
      for (std::size_t c = 0; c < shape[1]; ++c)
        out.push_back({ParameterGroup::tf, std::int64_t(r), int(c)});
  } else if (group == "tf_points") {
    if (scene.tf.kind != TfKind::piecewise_linear)
      throw Error(Status::invalid_argument,
                  "group 'tf_points' needs a piecewise_linear TF (the scene's is " +
                      std::string(tf_kind_name(scene.tf.kind)) + ")");
    for (std::size_t r = 0; r < shape[0]; ++r)
      out.push_back({ParameterGroup::tf, std::int64_t(r), 4});
  } else if (group == "scales") {
    if (scene.tf.kind != TfKind::identity)
      throw Error(Status::invalid_argument,
                  "group 'scales' needs the identity TF (the scene's is " +
                      std::string(tf_kind_name(scene.tf.kind)) + ")");
    out = {{ParameterGroup::tf, 0, 0}, {ParameterGroup::tf, 0, 1}};
  } else if (group == "background") {
    for (int c = 0; c < (scene.model == Model::absorption ? 1 : 3); ++c)
      out.push_back({ParameterGroup::background, c, 0});
  } else if (group == "camera") {
    for (std::size_t v = 0; v < scene.cameras.size(); ++v)
      for (int c = 0; c < 7; ++c) out.push_back({ParameterGroup::camera, std::int64_t(v), c});
  } else if (group == "step") {
    out.push_back({ParameterGroup::step, 0, 0});
  } else if (group == "rays") {
    if (!scene.has_ray_list())
      throw Error(Status::invalid_argument,
                  "group 'rays' needs a scene of rays (a ray list); the scene's are cameras'");
    for (std::size_t r = 0; r < scene.rays.count(); ++r)
      for (int c = 0; c < RayList::kColumns; ++c)
        out.push_back({ParameterGroup::ray, std::int64_t(r), c});
  } else if (group == "density") {
    for (std::size_t i = 0; i < scene.volume.voxel_count(); ++i)
      out.push_back({ParameterGroup::voxel, std::int64_t(i), 0});
  } else if (group.rfind("voxels:", 0) == 0) {
    for (std::int64_t i : voxel_list(group.substr(7), scene.volume))
      out.push_back({ParameterGroup::voxel, i, 0});
  } else {
    throw Error(Status::invalid_argument, unknown_group_message(group));
  }
  return out;
}

Jacobian jacobian(Device& device, const Scene& scene, const std::vector<Parameter>& parameters,
                  const Image* target, const JacobianOptions& options) {
  Session session = one_shot_session(
      device, scene,
      {options.precision, options.step, options.empty_space, 0.05, options.brick_size});
  Session::Impl& s = session.impl();
  if (target) session.set_target(*target);
  const std::vector<cl_int4> lanes = lanes_of(s.scene, parameters);
  const JacobianResult r = enqueue_jacobian(s, lanes, target ? &s.target : nullptr,
                                            options.jacobian, options.loss, s.begin("jacobian"));
  Jacobian out;
  out.image = image_of(r.image);
  if (options.jacobian) download_kept(r.jacobian, &out.jacobian, &out.jacobian_f64);
  if (target) {
    out.loss = r.loss.to_doubles()[0];
    out.gradient = r.gradient.to_doubles();
  }
  const OperationStats st = session.last_stats();
  out.kernel_seconds = st.kernel_seconds;
  out.passes = st.passes;
  out.lanes = st.lanes;
  out.device_bytes = st.device_bytes;
  out.skipped_empty = st.skipped_empty;
  out.variant = st.variant;
  out.step = st.step;
  return out;
}

}  // namespace ivr
