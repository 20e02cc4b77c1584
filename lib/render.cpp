// render.cpp — the forward render operation: packs the scene for the device, picks the kernel
// variant, launches every view at once and reads back images and sample counts.
#include "ivr/render.hpp"

#include <cmath>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <numeric>

#include "device_params.hpp"
#include "kernel_sources.hpp"
#include "runtime.hpp"
#include "scene_checks.hpp"
#include "variants.hpp"

namespace ivr {

namespace {

// $IVR_BUILD_OPTIONS: extra OpenCL compiler options for experiments (part of the cache key).
std::string extra_build_options() {
  const char* extra = std::getenv("IVR_BUILD_OPTIONS");
  return extra ? extra : "";
}

template <class Real>
struct ClVec;
template <>
struct ClVec<float> {
  using type = cl_float4;
};
template <>
struct ClVec<double> {
  using type = cl_double4;
};

template <class Real>
typename ClVec<Real>::type vec4(double x, double y, double z, double w = 0) {
  typename ClVec<Real>::type v;
  v.s[0] = Real(x);
  v.s[1] = Real(y);
  v.s[2] = Real(z);
  v.s[3] = Real(w);
  return v;
}

// Per view: eye, forward, right and up scaled to the image plane, orthographic flag (see
// kernels/config.cl, IVR_CAMERA_STRIDE).
template <class Real>
std::vector<Real> pack_cameras(const std::vector<Camera>& cameras) {
  constexpr int stride = 16;
  std::vector<Real> out(cameras.size() * stride, Real(0));
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    const glm::dvec3 fwd = glm::normalize(c.target - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(fwd, c.up));
    const glm::dvec3 up = glm::cross(right, fwd);
    const double aspect = double(c.width) / double(c.height);
    const bool ortho = c.projection == Projection::orthographic;
    const double half = ortho ? 0.5 * c.ortho_height : std::tan(0.5 * c.fov_y * M_PI / 180.0);
    const glm::dvec3 r = half * aspect * right, u = half * up;
    const double values[13] = {
        c.eye.x, c.eye.y, c.eye.z,          fwd.x, fwd.y, fwd.z, r.x, r.y, r.z, u.x,
        u.y,     u.z,     ortho ? 1.0 : 0.0};
    for (int k = 0; k < 13; ++k) out[i * stride + k] = Real(values[k]);
  }
  return out;
}

// Transfer-function rows in the layout of kernels/tf.cl; scalars = (a, b) or (lo, hi).
template <class Real>
std::vector<Real> pack_tf(const TransferFunction& tf, int* count, double scalars[2]) {
  std::vector<Real> out;
  scalars[0] = scalars[1] = 0;
  switch (tf.kind) {
    case TfKind::identity:
      scalars[0] = tf.extinction_scale;
      scalars[1] = tf.color_scale;
      *count = 0;
      out.push_back(0);  // buffers cannot be empty
      break;
    case TfKind::piecewise_linear:
      for (const TfPoint& p : tf.points)
        out.insert(out.end(), {Real(p.density), Real(p.color.x), Real(p.color.y), Real(p.color.z),
                               Real(p.extinction)});
      *count = int(tf.points.size());
      break;
    case TfKind::table:
      for (const glm::dvec4& e : tf.entries)
        out.insert(out.end(), {Real(e.x), Real(e.y), Real(e.z), Real(e.w)});
      scalars[0] = tf.range.x;
      scalars[1] = tf.range.y;
      *count = int(tf.entries.size());
      break;
    case TfKind::gaussian:
      for (const TfGaussian& g : tf.gaussians)
        out.insert(out.end(), {Real(g.mean), Real(g.width), Real(g.color.x), Real(g.color.y),
                               Real(g.color.z), Real(g.extinction)});
      *count = int(tf.gaussians.size());
      break;
  }
  return out;
}

template <class Real>
Image render_as(Device::Impl& dev, const Scene& scene, const Integrator& integrator,
                Precision precision, RenderStats* stats) {
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
  std::vector<Real> converted;
  const void* volume_host = scene.volume.data.data();
  if constexpr (!std::is_same_v<Real, float>) {
    if (scene.volume.voxel_count() * sizeof(Real) > dev.info.max_allocation)
      dev.buffer(CL_MEM_READ_ONLY, scene.volume.voxel_count() * sizeof(Real), nullptr,
                 "the volume");  // throws
    converted.assign(scene.volume.data.begin(), scene.volume.data.end());
    volume_host = converted.data();
  }
  cl::Buffer volume = dev.buffer(CL_MEM_READ_ONLY, scene.volume.voxel_count() * sizeof(Real),
                                 volume_host, "the volume");
  const std::vector<Real> cams = pack_cameras<Real>(scene.cameras);
  cl::Buffer cameras =
      dev.buffer(CL_MEM_READ_ONLY, cams.size() * sizeof(Real), cams.data(), "the cameras");
  int tf_count = 0;
  double tf_scalars[2];
  const std::vector<Real> tf = pack_tf<Real>(scene.tf, &tf_count, tf_scalars);
  cl::Buffer tf_buffer =
      dev.buffer(CL_MEM_READ_ONLY, tf.size() * sizeof(Real), tf.data(), "the transfer function");

  const RenderVariant variant = RenderVariant::of(scene, integrator, precision);
  double build_seconds = 0;
  const cl::Program program = dev.programs.get(
      dev.context, dev.device, dev.info, variant.preamble() + assemble_kernel("render.cl"),
      extra_build_options(), "render.cl [" + variant.label() + "]", &build_seconds);

  const glm::dvec3 h = scene.voxel_size();
  const double step = integrator.step * std::min(h.x, std::min(h.y, h.z));
  const glm::dvec3 bg = scene.effective_background();
  cl::Event done;
  cl_call("running the render kernel on " + dev.info.name, [&] {
    cl::Kernel k(program, "render");
    int a = 0;
    k.setArg(a++, volume);
    k.setArg(a++, cl_int4{{scene.volume.nx, scene.volume.ny, scene.volume.nz, 0}});
    k.setArg(a++, vec4<Real>(scene.box_min.x, scene.box_min.y, scene.box_min.z));
    k.setArg(a++, vec4<Real>(scene.box_max.x, scene.box_max.y, scene.box_max.z));
    k.setArg(a++, vec4<Real>(1 / h.x, 1 / h.y, 1 / h.z));
    k.setArg(a++, cameras);
    k.setArg(a++, cl_int(image.width));
    k.setArg(a++, cl_int(image.height));
    k.setArg(a++, tf_buffer);
    k.setArg(a++, cl_int(tf_count));
    k.setArg(a++, vec4<Real>(tf_scalars[0], tf_scalars[1], 0));
    k.setArg(a++, vec4<Real>(bg.x, bg.y, bg.z));
    k.setArg(a++, Real(step));
    k.setArg(a++, Real(integrator.min_transmittance));
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
    stats->kernel_seconds = 1e-9 * double(done.getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                                          done.getProfilingInfo<CL_PROFILING_COMMAND_START>());
    stats->build_seconds = build_seconds;
    stats->samples = std::accumulate(samples.begin(), samples.end(), std::uint64_t(0));
    stats->variant = variant.label();
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
    return render_as<double>(dev, scene, integrator, options.precision, stats);
  }
  return render_as<float>(dev, scene, integrator, options.precision, stats);
}

}  // namespace ivr
