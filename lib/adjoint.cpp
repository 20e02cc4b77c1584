// adjoint.cpp — the gradient operation: one launch of kernels/adjoint.cl (primal march, loss, and
// the constant-memory adjoint march) per evaluation, reductions of the per-pixel terms on the host.
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numeric>

#include "adjoint_device.hpp"
#include "device_params.hpp"
#include "device_scene.hpp"
#include "empty_space.hpp"
#include "ivr/gradient.hpp"
#include "ivr/tolerance.hpp"
#include "kernel_sources.hpp"
#include "render_packet.hpp"
#include "scene_checks.hpp"
#include "variants.hpp"

namespace ivr {

std::vector<std::size_t> tf_gradient_shape(const TransferFunction& tf) {
  switch (tf.kind) {
    case TfKind::identity:
      return {1, 2};
    case TfKind::piecewise_linear:
      return {tf.points.size(), 4};
    case TfKind::table:
      return {tf.entries.size(), 4};
    case TfKind::gaussian:
      return {tf.gaussians.size(), 6};
  }
  return {0, 0};
}

namespace {

std::string gradient_preamble(const RenderVariant& variant, const GradientOptions& o,
                              std::size_t tf_rows, bool fixed) {
  // IVR_TF_ROWS sizes the per-ray TF-gradient cache (kernels/tf_grad.cl).
  return variant.preamble() + "#define IVR_TF_ROWS " + std::to_string(tf_rows) +
         "\n#define IVR_GRAD_DENSITY " + (o.density ? "1" : "0") + "\n#define IVR_GRAD_TF " +
         (o.tf ? "1" : "0") + "\n#define IVR_GRAD_CAMERA " + (o.camera ? "1" : "0") +
         "\n#define IVR_LOSS_L1 " + (o.loss == Loss::l1 ? "1" : "0") +
         "\n#define IVR_DETERMINISTIC " + (fixed ? "1" : "0") + "\n";
}

constexpr std::size_t kFixedHeader = 4;  // IVR_FIXED_HEADER (kernels/adjoint_scatter.cl)

bool has_int64_atomics(Device::Impl& dev) {
  return dev.device.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_khr_int64_base_atomics") !=
         std::string::npos;
}

// The scale 2^S that puts the largest contribution |c| just under cap/2 (so that no sum of up to
// 8 contributions per ray and voxel passes 2^62); frexp keeps it a function of |c|'s bits alone.
int fixed_exponent_for(float largest, int cap_exponent) {
  int e = 0;
  std::frexp(double(largest), &e);  // largest < 2^e
  return cap_exponent - 1 - e;
}

template <class Real>
Gradient gradient_as(Device::Impl& dev, const Scene& scene, const Integrator& integrator,
                     const Image& target, const GradientOptions& o,
                     const cl::Buffer* resident = nullptr, cl::Buffer* density_out = nullptr,
                     int* fixed_exponent = nullptr) {
  const Camera& cam0 = scene.cameras.front();
  const int views = int(scene.cameras.size()), channels = scene.channels();
  const std::size_t pixels = std::size_t(views) * cam0.height * cam0.width;
  const std::size_t voxels = scene.volume.voxel_count();
  const std::vector<std::size_t> tf_shape = tf_gradient_shape(scene.tf);
  const std::size_t tf_size = tf_shape[0] * tf_shape[1];

  std::vector<Real> target_real(target.pixels.begin(), target.pixels.end());
  cl::Buffer target_buf = dev.buffer(CL_MEM_READ_ONLY, target_real.size() * sizeof(Real),
                                     target_real.data(), "the target");
  cl::Buffer image_buf =
      dev.buffer(CL_MEM_WRITE_ONLY, pixels * channels * sizeof(float), nullptr, "the image");
  cl::Buffer terms_buf =
      dev.buffer(CL_MEM_WRITE_ONLY, pixels * 4 * sizeof(Real), nullptr, "the per-pixel terms");
  cl::Buffer samples_buf =
      dev.buffer(CL_MEM_WRITE_ONLY, pixels * sizeof(cl_uint), nullptr, "the sample counts");
  const std::size_t grad_voxels = o.density ? voxels : 1;
  // Deterministic: the density gradient summed in fixed point, where the device has 64-bit
  // integer atomics (else the float atomics below, and Gradient::deterministic stays false).
  const bool fixed = o.density && o.deterministic && has_int64_atomics(dev);
  const std::size_t grad_bytes =
      fixed ? (voxels + kFixedHeader) * sizeof(cl_long) : grad_voxels * sizeof(Real);
  cl::Buffer grad_volume =
      dev.buffer(CL_MEM_READ_WRITE, grad_bytes, nullptr, "the density gradient");
  cl::Buffer grad_tf =
      dev.buffer(CL_MEM_READ_WRITE, std::max<std::size_t>(tf_size, 1) * sizeof(Real), nullptr,
                 "the transfer-function gradient");
  const DeviceScene<Real> dscene(dev, scene, resident);

  RenderVariant variant = RenderVariant::of(
      scene, integrator, std::is_same_v<Real, double> ? Precision::f64 : Precision::f32);
  const bool native_atomics = use_float_atomics(dev.info, std::is_same_v<Real, double>);
  bool primal_given = false;  // the CPU packet render marches the primal (set below)
  auto program_of = [&](const RenderVariant& v) {
    const std::string label =
        "adjoint.cl [" + v.label() + (o.tf ? " grad_tf" : "") + (o.camera ? " grad_camera" : "") +
        (native_atomics ? " float_atomics" : "") + (fixed ? " deterministic" : "") +
        (primal_given ? " primal_given" : "") + "]";
    std::string preamble = gradient_preamble(v, o, tf_shape[0], fixed);
    if (primal_given) preamble += "#define IVR_PRIMAL_GIVEN 1\n";
    std::string options = extra_build_options();
    if (native_atomics) {
      preamble += "#define IVR_FLOAT_ATOMICS 1\n";
      options = "-cl-std=" + dev.info.atomics_std + " " + options;
    }
    return dev.programs.get(dev.context, dev.device, dev.info,
                            preamble + assemble_kernel("adjoint.cl"), options, label);
  };
  // Empty-space skipping where the gradient stays exact (as the render decides, see there).
  const BrickGrid grid = plan_skipping(
      dev, dscene.volume, scene, o.empty_space, o.brick_size, RenderOptions().min_empty_fraction,
      gradient_may_skip(scene.tf, o.tf, o.density || o.camera), variant);
  // On CPU devices the packet render (16 rays per work-item in vector lanes) marches the primal
  // several times faster than the adjoint kernel's own one-ray march; it leaves each pixel's C, T
  // and samples in the image and sample buffers, where the adjoint kernel reads them.
  primal_given = use_packet(dev, scene, variant);
  const cl::Program program = program_of(variant);
  const cl::Buffer occupied = occupancy_buffer(dev, grid);
  cl::Kernel primal_kernel;
  if (primal_given)
    cl_call("setting up the packet primal on " + dev.info.name, [&] {
      primal_kernel = cl::Kernel(packet_program(dev, variant, true), "render_packet");
      int a = dscene.set_args(primal_kernel, scene, integrator);
      primal_kernel.setArg(a++, occupied);
      primal_kernel.setArg(a++, brick_counts(grid));
      primal_kernel.setArg(a++, image_buf);
      primal_kernel.setArg(a++, samples_buf);
    });
  cl::Event primal_done;

  Gradient g;
  g.atomics = native_atomics ? "cl_ext_float_atomics" : "compare-and-swap";
  g.deterministic = fixed;
  g.skipped_empty = variant.skip_empty;
  g.step = integrator.step;
  g.empty_fraction = grid.empty_fraction;
  g.device_bytes = dscene.bytes + target_real.size() * sizeof(Real) +
                   pixels * (channels * sizeof(float) + 4 * sizeof(Real) + sizeof(cl_uint)) +
                   grad_bytes + std::max<std::size_t>(tf_size, 1) * sizeof(Real) +
                   (fixed ? voxels * sizeof(Real) : 0);
  cl::Event zero_volume, zero_tf, done;
  const std::vector<Real> camera_values = pack_camera_params<Real>(scene.cameras);
  cl::Buffer camera_params =
      dev.buffer(CL_MEM_READ_ONLY, camera_values.size() * sizeof(Real),
                 const_cast<Real*>(camera_values.data()), "the camera parameters");
  cl::Buffer camera_partial;
  std::size_t groups_x = 0, groups_per_view = 0;
  cl::Buffer density = grad_volume;  // the density gradient as reals
  cl_call("running the adjoint kernel on " + dev.info.name, [&] {
    cl::Kernel k(program, "adjoint");
    int a = dscene.set_args(k, scene, integrator);
    k.setArg(a++, target_buf);
    k.setArg(a++, Real(1.0 / double(pixels * channels)));
    k.setArg(a++, image_buf);
    k.setArg(a++, terms_buf);
    k.setArg(a++, grad_volume);
    k.setArg(a++, grad_tf);
    k.setArg(a++, cl::Local(std::max<std::size_t>(tf_size, 1) * sizeof(Real)));
    k.setArg(a++, cl_int(o.tf ? tf_size : 0));
    k.setArg(a++, samples_buf);
    // A work-group's items share one local TF accumulator (the padding items only meet
    // barriers), so the size is always explicit: the database's, else 8x8 (smaller where the
    // kernel allows less).
    const std::size_t max_group = k.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(dev.device);
    const LaunchParams launch = launch_params(dev.info, "adjoint");
    int lx = launch.local_x, ly = launch.local_y;
    if (lx <= 0 || std::size_t(lx) * std::size_t(ly) > max_group)
      lx = ly = max_group >= 64 ? 8 : max_group >= 16 ? 4 : 1;
    const int gx = (cam0.width + lx - 1) / lx * lx, gy = (cam0.height + ly - 1) / ly * ly;
    // The camera gradient: 7 values per work-group, summed per view on the host.
    groups_x = std::size_t(gx / lx);
    groups_per_view = groups_x * std::size_t(gy / ly);
    const std::size_t partials = o.camera ? groups_per_view * std::size_t(views) * 7 : 1;
    camera_partial = dev.buffer(CL_MEM_WRITE_ONLY, partials * sizeof(Real), nullptr,
                                "the camera gradient's partial sums");
    g.device_bytes += (partials + camera_values.size()) * sizeof(Real);
    k.setArg(a++, camera_params);
    k.setArg(a++, camera_partial);
    k.setArg(a++, cl::Local((o.camera ? std::size_t(lx) * ly * 7 : 1) * sizeof(Real)));
    k.setArg(a++, occupied);
    k.setArg(a++, brick_counts(grid));
    // Fixed point: no scaled contribution above 2^62 / (8 · rays) (at most 8 per ray reach a
    // voxel), so no sum leaves the long range.
    const int cap_exponent = 62 - int(std::ceil(std::log2(8.0 * double(pixels))));
    auto run_pass = [&](int exponent) {
      if (fixed) {
        dev.queue.enqueueFillBuffer(grad_volume, cl_long(0), 0, grad_bytes, nullptr, &zero_volume);
        const cl_long header[kFixedHeader] = {exponent, cl_long(1) << cap_exponent, 0, 0};
        dev.queue.enqueueWriteBuffer(grad_volume, CL_TRUE, 0, sizeof header, header);
      } else {
        dev.queue.enqueueFillBuffer(grad_volume, Real(0), 0, grad_bytes, nullptr, &zero_volume);
      }
      dev.queue.enqueueFillBuffer(
          grad_tf, Real(0), 0, std::max<std::size_t>(tf_size, 1) * sizeof(Real), nullptr, &zero_tf);
      if (primal_given) enqueue_packet(dev, primal_kernel, scene, &primal_done);
      dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(gx, gy, views),
                                     cl::NDRange(lx, ly, 1), nullptr, &done);
      done.wait();
    };
    if (!fixed) {
      run_pass(0);
      return;
    }
    // The scale comes from the largest contribution, which an order-independent atomic max
    // records: the previous call's where the caller keeps it, else a first pass's. A pass whose
    // contributions outgrew the cap runs again at the scale it measured, so every decision is a
    // function of the inputs alone.
    bool known = fixed_exponent && *fixed_exponent != kUnknownExponent;
    int exponent = known ? *fixed_exponent : 0;
    for (int pass = 0;; ++pass) {
      run_pass(exponent);
      cl_long header[kFixedHeader];
      dev.queue.enqueueReadBuffer(grad_volume, CL_TRUE, 0, sizeof header, header);
      float largest = 0;
      std::memcpy(&largest, &header[3], sizeof largest);
      const int ideal = largest > 0 ? fixed_exponent_for(largest, cap_exponent) : exponent;
      if (fixed_exponent) *fixed_exponent = ideal;
      if ((header[2] > 0 || !known) && largest > 0 && pass == 0) {
        exponent = ideal;
        known = true;
        continue;
      }
      if (header[2] > 0)
        throw Error(Status::opencl, "the fixed-point density gradient overflowed at scale 2^" +
                                        std::to_string(exponent));
      break;
    }
    g.fixed_exponent = exponent;
    density = dev.buffer(CL_MEM_READ_WRITE, voxels * sizeof(Real), nullptr, "the density gradient");
    cl::Kernel convert(program, "fixed_to_real");
    convert.setArg(0, cl_int(voxels));
    convert.setArg(1, grad_volume);
    convert.setArg(2, density);
    dev.queue.enqueueNDRangeKernel(convert, cl::NullRange, cl::NDRange(voxels), cl::NullRange);
  });

  std::vector<Real> terms(pixels * 4);
  std::vector<cl_uint> samples(pixels);
  std::vector<Real> grad(o.density ? voxels : 0), grad_tf_host(o.tf ? tf_size : 0), camera_host;
  cl_call("reading the gradient back", [&] {
    dev.queue.enqueueReadBuffer(terms_buf, CL_TRUE, 0, terms.size() * sizeof(Real), terms.data());
    dev.queue.enqueueReadBuffer(samples_buf, CL_TRUE, 0, samples.size() * sizeof(cl_uint),
                                samples.data());
    if (o.density && !density_out)
      dev.queue.enqueueReadBuffer(density, CL_TRUE, 0, grad.size() * sizeof(Real), grad.data());
    if (o.tf)
      dev.queue.enqueueReadBuffer(grad_tf, CL_TRUE, 0, grad_tf_host.size() * sizeof(Real),
                                  grad_tf_host.data());
    if (o.camera) {
      camera_host.resize(groups_per_view * std::size_t(views) * 7);
      dev.queue.enqueueReadBuffer(camera_partial, CL_TRUE, 0, camera_host.size() * sizeof(Real),
                                  camera_host.data());
    }
  });
  if (o.camera) {
    g.camera.assign(std::size_t(views) * 7, 0.0);
    for (std::size_t group = 0; group < groups_per_view * std::size_t(views); ++group)
      for (std::size_t c = 0; c < 7; ++c)
        g.camera[group / groups_per_view * 7 + c] += double(camera_host[group * 7 + c]);
  }
  double background[3] = {0, 0, 0};
  for (std::size_t p = 0; p < pixels; ++p) {
    g.loss += double(terms[p * 4]);
    for (int c = 0; c < 3; ++c) background[c] += double(terms[p * 4 + 1 + c]);
  }
  if (o.density && density_out)
    *density_out = density;
  else if (o.density)
    g.density.assign(grad.begin(), grad.end());
  if (o.tf) g.tf.assign(grad_tf_host.begin(), grad_tf_host.end());
  if (o.background) g.background.assign(background, background + (channels == 4 ? 3 : 1));
  g.samples = std::accumulate(samples.begin(), samples.end(), std::uint64_t(0));
  g.kernel_seconds = event_seconds(done) + event_seconds(zero_volume) + event_seconds(zero_tf) +
                     (primal_given ? event_seconds(primal_done) : 0.0);
  return g;
}

}  // namespace

Gradient gradient_on_device(Device::Impl& dev, const Scene& scene, const Integrator& integrator,
                            const Image& target, const GradientOptions& options,
                            const cl::Buffer& volume, cl::Buffer* density_out,
                            int* fixed_exponent) {
  check_target(scene, target);
  if (options.precision == Precision::f64)
    return gradient_as<double>(dev, scene, integrator, target, options, &volume, density_out,
                               fixed_exponent);
  return gradient_as<float>(dev, scene, integrator, target, options, &volume, density_out,
                            fixed_exponent);
}

double image_loss(const Image& image, const Image& target, Loss loss) {
  if (image.pixels.size() != target.pixels.size() || image.views != target.views ||
      image.height != target.height || image.width != target.width ||
      image.channels != target.channels)
    throw Error(Status::invalid_argument, "image and target differ in shape");
  double sum = 0;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    const double d = double(image.pixels[i]) - double(target.pixels[i]);
    sum += loss == Loss::l1 ? std::abs(d) : d * d;
  }
  return image.pixels.empty() ? 0.0 : sum / double(image.pixels.size());
}

Gradient gradient(Device& device, const Scene& scene, const Image& target,
                  const GradientOptions& options) {
  const Integrator integrator =
      integrator_for(device, scene, options.step, options.precision, options.empty_space);
  validate_with(scene, integrator);
  check_target(scene, target);
  Device::Impl& dev = device.impl();
  if (options.precision == Precision::f64) {
    if (!dev.info.fp64)
      throw Error(Status::unsupported,
                  "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
    return gradient_as<double>(dev, scene, integrator, target, options);
  }
  return gradient_as<float>(dev, scene, integrator, target, options);
}

}  // namespace ivr
