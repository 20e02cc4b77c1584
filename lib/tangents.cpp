// tangents.cpp — forward-mode differentiation: parameters by group, passes of up to 32 tangent
// lanes of kernels/tangents.cl, the Jacobian assembled and the loss gradient summed on the host
// from the work-groups' partial sums.
#include "ivr/tangents.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "device_params.hpp"
#include "device_scene.hpp"
#include "empty_space.hpp"
#include "ivr/error.hpp"
#include "ivr/tolerance.hpp"
#include "kernel_sources.hpp"
#include "scene_checks.hpp"
#include "variants.hpp"

namespace ivr {

namespace {

constexpr int kMaxLanes = 32;

// Lane kinds of kernels/tangents.cl.
enum LaneKind {
  lane_none = 0,
  lane_tf = 1,
  lane_background = 2,
  lane_camera = 3,
  lane_voxel = 4,
  lane_step = 5
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
      if (p.index < 0 || std::size_t(p.index) >= scene.cameras.size() || p.column < 0 ||
          p.column > 6)
        throw bad_parameter(
            i, "camera view " + std::to_string(p.index) + " component " + std::to_string(p.column) +
                   " (views: " + std::to_string(scene.cameras.size()) + ", components 0..6)");
      return {{lane_camera, cl_int(p.index), p.column, 0}};
    case ParameterGroup::step:
      return {{lane_step, 0, 0, 0}};
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

int lanes_for(std::size_t count) {
  int lanes = 1;
  while (std::size_t(lanes) < count) lanes *= 2;
  return lanes;
}

template <class Real>
void run_passes(Device::Impl& dev, const Scene& scene, const Integrator& integrator,
                const std::vector<cl_int4>& all_lanes, const Image* target, const TangentOptions& o,
                Tangents& out) {
  const Camera& cam0 = scene.cameras.front();
  const int views = int(scene.cameras.size()), channels = scene.channels();
  const std::size_t pixels = std::size_t(views) * cam0.height * cam0.width;
  const std::size_t params = all_lanes.size();
  const bool loss = target != nullptr;

  const DeviceScene<Real> dscene(dev, scene);
  const std::vector<Real> cams = pack_camera_params<Real>(scene.cameras);
  cl::Buffer camera_params = dev.buffer(CL_MEM_READ_ONLY, cams.size() * sizeof(Real),
                                        const_cast<Real*>(cams.data()), "the camera parameters");
  std::vector<Real> target_real;
  if (loss)
    target_real.assign(target->pixels.begin(), target->pixels.end());
  else
    target_real.assign(1, Real(0));
  cl::Buffer target_buf = dev.buffer(CL_MEM_READ_ONLY, target_real.size() * sizeof(Real),
                                     target_real.data(), "the target");
  cl::Buffer image_buf =
      dev.buffer(CL_MEM_WRITE_ONLY, pixels * channels * sizeof(float), nullptr, "the image");

  // Work-groups of 8x8 (the database's size where it has one), within the kernel's limit.
  RenderVariant variant = RenderVariant::of(
      scene, integrator, std::is_same_v<Real, double> ? Precision::f64 : Precision::f32);
  // Empty-space skipping where every pass stays exact (as the adjoint decides, gradient_may_skip).
  bool any_tf = false, any_position = false;
  for (const cl_int4& l : all_lanes) {
    any_tf |= l.s[0] == lane_tf;
    any_position |= l.s[0] == lane_camera || l.s[0] == lane_voxel;
  }
  const BrickGrid grid = plan_skipping(dev, dscene.volume, scene, o.empty_space, o.brick_size,
                                       RenderOptions().min_empty_fraction,
                                       gradient_may_skip(scene.tf, any_tf, any_position), variant);
  const cl::Buffer occupied = occupancy_buffer(dev, grid);
  out.skipped_empty = variant.skip_empty;
  const LaunchParams launch = launch_params(dev.info, "tangents");

  out.image = Image{views, cam0.height, cam0.width, channels, {}};
  if (o.jacobian) out.jacobian.assign(pixels * channels * params, 0.0f);
  if (loss) out.gradient.assign(params, 0.0);
  const int pass_lanes = lanes_for(std::min<std::size_t>(params, kMaxLanes));
  out.lanes = pass_lanes;
  for (std::size_t first = 0; first < params || (params == 0 && first == 0); first += kMaxLanes) {
    const std::size_t count = std::min<std::size_t>(kMaxLanes, params - first);
    std::vector<cl_int4> lanes(std::size_t(pass_lanes), cl_int4{{lane_none, 0, 0, 0}});
    bool any_tf = false, any_camera = false, any_voxel = false;
    for (std::size_t k = 0; k < count; ++k) {
      lanes[k] = all_lanes[first + k];
      any_tf |= lanes[k].s[0] == lane_tf;
      any_camera |= lanes[k].s[0] == lane_camera;
      any_voxel |= lanes[k].s[0] == lane_voxel;
    }
    const auto flag = [](bool b) { return b ? "1\n" : "0\n"; };
    const std::string preamble =
        variant.preamble() + "#define IVR_LANES " + std::to_string(pass_lanes) +
        "\n#define IVR_TANGENT_TF " + flag(any_tf) + "#define IVR_TANGENT_CAMERA " +
        flag(any_camera) + "#define IVR_TANGENT_VOXEL " + flag(any_voxel) +
        "#define IVR_JACOBIAN " + flag(o.jacobian) + "#define IVR_LOSS_GRADIENT " + flag(loss) +
        "#define IVR_LOSS_L1 " + flag(o.loss == Loss::l1);
    const cl::Program program = dev.programs.get(
        dev.context, dev.device, dev.info, preamble + assemble_kernel("tangents.cl"),
        extra_build_options(),
        "tangents.cl [" + variant.label() + " lanes=" + std::to_string(pass_lanes) + "]");
    cl::Kernel k(program, "tangents");
    const std::size_t max_group = k.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(dev.device);
    int lx = launch.local_x, ly = launch.local_y;
    if (lx <= 0 || std::size_t(lx) * std::size_t(ly) > max_group)
      lx = ly = max_group >= 64 ? 8 : max_group >= 16 ? 4 : 1;
    const int gx = (cam0.width + lx - 1) / lx * lx, gy = (cam0.height + ly - 1) / ly * ly;
    const std::size_t groups = std::size_t(gx / lx) * std::size_t(gy / ly) * std::size_t(views);
    const std::size_t row = std::size_t(pass_lanes) + 1;

    cl::Buffer lanes_buf = dev.buffer(CL_MEM_READ_ONLY, lanes.size() * sizeof(cl_int4),
                                      lanes.data(), "the tangent lanes");
    const std::size_t jacobian_size = o.jacobian ? pixels * channels * std::size_t(pass_lanes) : 1;
    cl::Buffer jacobian_buf =
        dev.buffer(CL_MEM_WRITE_ONLY, jacobian_size * sizeof(float), nullptr, "the Jacobian");
    cl::Buffer partial_buf =
        dev.buffer(CL_MEM_WRITE_ONLY, groups * row * sizeof(Real), nullptr, "the partial sums");
    out.device_bytes =
        dscene.bytes + (cams.size() + target_real.size() + groups * row) * sizeof(Real) +
        (pixels * channels + jacobian_size) * sizeof(float) + lanes.size() * sizeof(cl_int4);

    std::vector<float> jac(o.jacobian ? jacobian_size : 0);
    std::vector<Real> partial(loss ? groups * row : 0);
    cl_call("running the tangent kernel on " + dev.info.name, [&] {
      int a = dscene.set_args(k, scene, integrator);
      k.setArg(a++, lanes_buf);
      k.setArg(a++, camera_params);
      k.setArg(a++, target_buf);
      k.setArg(a++, Real(1.0 / double(pixels * channels)));
      k.setArg(a++, image_buf);
      k.setArg(a++, jacobian_buf);
      k.setArg(a++, partial_buf);
      k.setArg(a++, cl::Local(std::size_t(lx) * ly * row * sizeof(Real)));
      k.setArg(a++, occupied);
      k.setArg(a++, brick_counts(grid));
      cl::Event done;
      dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(gx, gy, views),
                                     cl::NDRange(lx, ly, 1), nullptr, &done);
      done.wait();
      out.kernel_seconds += event_seconds(done);
      if (o.jacobian)
        dev.queue.enqueueReadBuffer(jacobian_buf, CL_TRUE, 0, jac.size() * sizeof(float),
                                    jac.data());
      if (loss)
        dev.queue.enqueueReadBuffer(partial_buf, CL_TRUE, 0, partial.size() * sizeof(Real),
                                    partial.data());
      if (first == 0) {
        out.image.pixels.resize(pixels * channels);
        dev.queue.enqueueReadBuffer(image_buf, CL_TRUE, 0, out.image.pixels.size() * sizeof(float),
                                    out.image.pixels.data());
      }
    });
    ++out.passes;
    if (o.jacobian)
      for (std::size_t e = 0; e < pixels * channels; ++e)
        for (std::size_t q = 0; q < count; ++q)
          out.jacobian[e * params + first + q] = jac[e * pass_lanes + q];
    if (loss) {
      double total = 0;
      for (std::size_t g = 0; g < groups; ++g) {
        total += double(partial[g * row]);
        for (std::size_t q = 0; q < count; ++q)
          out.gradient[first + q] += double(partial[g * row + 1 + q]);
      }
      out.loss = total;
    }
    if (params == 0) break;
  }
}

}  // namespace

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
  } else if (group == "density") {
    for (std::size_t i = 0; i < scene.volume.voxel_count(); ++i)
      out.push_back({ParameterGroup::voxel, std::int64_t(i), 0});
  } else if (group.rfind("voxels:", 0) == 0) {
    for (std::int64_t i : voxel_list(group.substr(7), scene.volume))
      out.push_back({ParameterGroup::voxel, i, 0});
  } else {
    throw Error(Status::invalid_argument,
                "unknown parameter group '" + group +
                    "' (known: density, tf, tf_points, scales, background, camera, step, "
                    "voxels:LIST)");
  }
  return out;
}

Tangents tangents(Device& device, const Scene& scene, const std::vector<Parameter>& parameters,
                  const Image* target, const TangentOptions& options) {
  const Integrator integrator =
      integrator_for(device, scene, options.step, options.precision, options.empty_space);
  validate_with(scene, integrator);
  if (target) check_target(scene, *target);
  std::vector<cl_int4> lanes;
  lanes.reserve(parameters.size());
  for (std::size_t i = 0; i < parameters.size(); ++i)
    lanes.push_back(lane_of(scene, parameters[i], i));
  Device::Impl& dev = device.impl();
  Tangents out;
  out.step = integrator.step;
  if (options.precision == Precision::f64) {
    if (!dev.info.fp64)
      throw Error(Status::unsupported,
                  "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
    run_passes<double>(dev, scene, integrator, lanes, target, options, out);
  } else {
    run_passes<float>(dev, scene, integrator, lanes, target, options, out);
  }
  return out;
}

}  // namespace ivr
