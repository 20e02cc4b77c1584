// adjoint.cpp — the gradient operation in reverse mode: one launch of kernels/adjoint.cl (primal
// march, loss, and the constant-memory adjoint march) on the session's device copies, then the
// per-pixel terms and per-group camera sums reduced on the device; and the one-shot gradient().
#include <cmath>
#include <cstring>

#include "ivr/gradient.hpp"
#include "real_args.hpp"
#include "render_packet.hpp"
#include "scene_checks.hpp"
#include "session_impl.hpp"

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

KernelConfig adjoint_config(const RenderVariant& v, const AdjointRequest& r, std::size_t tf_rows,
                            bool fixed, bool primal_given, bool native_atomics) {
  KernelConfig c;
  c.file = "adjoint.cl";
  c.entry = "adjoint";
  // IVR_TF_ROWS sizes the per-ray TF-gradient cache (kernels/tf_grad.cl).
  c.preamble = v.preamble() + "#define IVR_TF_ROWS " + std::to_string(tf_rows) +
               "\n#define IVR_GRAD_DENSITY " + (r.density ? "1" : "0") + "\n#define IVR_GRAD_TF " +
               (r.tf ? "1" : "0") + "\n#define IVR_GRAD_CAMERA " + (r.camera ? "1" : "0") +
               "\n#define IVR_LOSS_L1 " + (r.loss == Loss::l1 ? "1" : "0") +
               "\n#define IVR_DETERMINISTIC " + (fixed ? "1" : "0") + "\n";
  if (primal_given) c.preamble += "#define IVR_PRIMAL_GIVEN 1\n";
  if (native_atomics) c.preamble += "#define IVR_FLOAT_ATOMICS 1\n";
  c.float_atomics = native_atomics;
  c.label = "adjoint.cl [" + v.label() + (r.tf ? " grad_tf" : "") + (r.camera ? " grad_camera" : "") +
            (native_atomics ? " float_atomics" : "") + (fixed ? " deterministic" : "") +
            (primal_given ? " primal_given" : "") + "]";
  return c;
}

}  // namespace

AdjointResult enqueue_adjoint(Session::Impl& s, const DeviceArray& target, const AdjointRequest& r,
                              OperationRecord& op) {
  Device::Impl& dev = s.dev;
  const Scene& scene = s.scene;
  const Integrator& integrator = s.integrator();
  const Camera& cam0 = scene.cameras.front();
  const int views = int(scene.cameras.size()), channels = scene.channels();
  const std::size_t pixels = s.pixels(), voxels = scene.volume.voxel_count();
  const std::vector<std::size_t> tf_shape = tf_gradient_shape(scene.tf);
  const std::size_t tf_size = tf_shape[0] * tf_shape[1], real = s.real_size;

  // Deterministic: the density gradient summed in fixed point, where the device has 64-bit
  // integer atomics (else the float atomics, and the stats say it was not).
  const bool fixed = r.density && r.deterministic && has_int64_atomics(dev);
  const bool native_atomics = use_float_atomics(dev.info, s.f64);
  RenderVariant variant = s.variant_of(integrator);
  // Empty-space skipping where the gradient stays exact (lib/empty_space.hpp).
  const cl::Buffer& occupied =
      s.plan_skipping(gradient_may_skip(scene.tf, r.tf, r.density || r.camera), variant, op.stats);
  // On CPU devices the packet render (16 rays per work-item in vector lanes) marches the primal
  // several times faster than the adjoint kernel's own one-ray march; it leaves each pixel's C,
  // T and samples in the image and sample buffers, where the adjoint kernel reads them.
  const bool primal_given = use_packet(dev, scene, variant);

  AdjointResult out;
  out.atomics = native_atomics ? "cl_ext_float_atomics" : "compare-and-swap";
  out.image = s.output("gradient image", s.image_shape(), DType::f32, "the image");
  const cl::Buffer& terms = s.scratch("terms", pixels * 4 * real, "the per-pixel terms");
  const cl::Buffer& samples = s.scratch("samples", pixels * sizeof(cl_uint), "the sample counts");
  const std::size_t grad_bytes =
      fixed ? (voxels + kFixedHeader) * sizeof(cl_long) : (r.density ? voxels : 1) * real;
  // The density gradient: its own array, or the fixed-point sums converted into one.
  if (r.density)
    out.density = s.output("density gradient", s.volume_shape(), real_dtype(s.f64),
                           "the density gradient");
  const cl::Buffer& grad_volume =
      r.density && !fixed ? buffer_of(out.density)
                          : s.scratch(fixed ? "fixed density" : "no density", grad_bytes,
                                      "the density gradient");
  if (r.tf)
    out.tf = s.output("tf gradient", {std::int64_t(tf_shape[0]), std::int64_t(tf_shape[1])},
                      real_dtype(s.f64), "the transfer-function gradient");
  const cl::Buffer& grad_tf =
      r.tf ? buffer_of(out.tf) : s.scratch("no tf", real, "the transfer-function gradient");
  const DType acc = s.arrays.acc_dtype();
  const cl::Buffer& sums = s.scratch("adjoint sums", 4 * 8, "the loss and background sums");

  op.stats.variant = variant.label() + (primal_given ? " packet primal" : "");
  op.stats.skipped_empty = variant.skip_empty;
  op.stats.step = integrator.step;
  op.stats.deterministic = fixed;
  op.stats.mode = Mode::adjoint;
  op.stats.device_bytes = s.scene_bytes() + target.bytes() + out.image.bytes() +
                          pixels * (4 * real + sizeof(cl_uint)) + grad_bytes +
                          std::max<std::size_t>(tf_size, 1) * real +
                          (fixed ? voxels * real : 0);
  cl_call("running the adjoint kernel on " + dev.info.name, [&] {
    double build = 0;
    cl::Kernel& k = s.kernels.get(
        adjoint_config(variant, r, tf_shape[0], fixed, primal_given, native_atomics), &build);
    op.stats.build_seconds += build;
    cl::Kernel* primal = nullptr;
    if (primal_given) {
      primal = &s.kernels.get(packet_config(variant, true), &build);
      op.stats.build_seconds += build;
      int a = s.set_scene_args(*primal, integrator);
      primal->setArg(a++, occupied);
      primal->setArg(a++, s.brick_counts());
      primal->setArg(a++, buffer_of(out.image));
      primal->setArg(a++, samples);
    }
    int a = s.set_scene_args(k, integrator);
    k.setArg(a++, buffer_of(target));
    set_real(k, a++, s.f64, 1.0 / double(pixels * channels));
    k.setArg(a++, buffer_of(out.image));
    k.setArg(a++, terms);
    k.setArg(a++, grad_volume);
    k.setArg(a++, grad_tf);
    k.setArg(a++, cl::Local(std::max<std::size_t>(tf_size, 1) * real));
    k.setArg(a++, cl_int(r.tf ? tf_size : 0));
    k.setArg(a++, samples);
    // A work-group's items share one local TF accumulator (the padding items only meet
    // barriers), so the size is always explicit.
    const PixelLaunch launch =
        pixel_launch(dev, k, "adjoint", cam0.width, cam0.height, views, true);
    // The camera gradient: 7 values per work-group, summed per view on the device.
    const std::size_t partials = r.camera ? launch.groups_per_view * std::size_t(views) * 7 : 1;
    const cl::Buffer& camera_partial =
        s.scratch("camera partials", partials * real, "the camera gradient's partial sums");
    op.stats.device_bytes += partials * real;
    k.setArg(a++, s.camera_params);
    k.setArg(a++, camera_partial);
    k.setArg(a++, cl::Local(
                      (r.camera ? std::size_t(launch.group_x) * launch.group_y * 7 : 1) * real));
    k.setArg(a++, occupied);
    k.setArg(a++, s.brick_counts());
    // Fixed point: no scaled contribution above 2^62 / (8 · rays) (at most 8 per ray reach a
    // voxel), so no sum leaves the long range.
    const int cap_exponent = 62 - int(std::ceil(std::log2(8.0 * double(pixels))));
    auto run_pass = [&](int exponent) {
      if (fixed) {
        op.events.push_back(cl::Event());
        dev.queue.enqueueFillBuffer(grad_volume, cl_long(0), 0, grad_bytes, nullptr,
                                    &op.events.back());
        const cl_long header[kFixedHeader] = {exponent, cl_long(1) << cap_exponent, 0, 0};
        dev.queue.enqueueWriteBuffer(grad_volume, CL_TRUE, 0, sizeof header, header);
      } else if (r.density) {
        op.events.push_back(cl::Event());
        dev.queue.enqueueFillBuffer(grad_volume, cl_uchar(0), 0, grad_bytes, nullptr,
                                    &op.events.back());
      }
      if (r.tf) {
        op.events.push_back(cl::Event());
        dev.queue.enqueueFillBuffer(grad_tf, cl_uchar(0), 0, tf_size * real, nullptr,
                                    &op.events.back());
      }
      if (primal) op.events.push_back(enqueue(dev, *primal, packet_launch(dev, *primal, scene)));
      op.events.push_back(enqueue(dev, k, launch));
    };
    if (!fixed) {
      run_pass(0);
    } else {
      // The scale is the one the largest contribution calls for (an order-independent atomic
      // max records it), so the bits are a function of the inputs alone. The previous call's
      // scale, which the session keeps, is tried first: while the gradient's size changes slowly
      // it is already the right one and one pass does; a pass at another scale (or none known
      // yet, or one whose contributions outgrew the cap) runs again at the scale it measured.
      int exponent = s.fixed_exponent != kUnknownExponent ? s.fixed_exponent : 0;
      for (int pass = 0;; ++pass) {
        run_pass(exponent);
        cl_long header[kFixedHeader];
        dev.queue.enqueueReadBuffer(grad_volume, CL_TRUE, 0, sizeof header, header);
        float largest = 0;
        std::memcpy(&largest, &header[3], sizeof largest);
        const int ideal = largest > 0 ? fixed_exponent_for(largest, cap_exponent) : exponent;
        s.fixed_exponent = ideal;
        if ((header[2] > 0 || ideal != exponent) && largest > 0 && pass == 0) {
          exponent = ideal;
          continue;
        }
        if (header[2] > 0)
          throw Error(Status::opencl, "the fixed-point density gradient overflowed at scale 2^" +
                                          std::to_string(exponent));
        break;
      }
      op.stats.fixed_exponent = exponent;
      cl::Kernel& convert = s.kernels.get(
          adjoint_config(variant, r, tf_shape[0], fixed, primal_given, native_atomics)
              .with_entry("fixed_to_real"));
      convert.setArg(0, cl_int(voxels));
      convert.setArg(1, grad_volume);
      convert.setArg(2, buffer_of(out.density));
      op.events.push_back(enqueue_1d(dev, convert, voxels, 64));
    }
    if (r.density) mark_written(out.density, op.events.back());
    // The loss and the background gradient: the per-pixel terms' column sums; the camera
    // gradient: the groups' partial sums per view.
    op.events.push_back(s.arrays.sum_rows(terms, int(pixels), 4, 1, sums));
    out.loss = s.output("loss", {1}, acc, "the loss");
    op.events.push_back(cl::Event());
    dev.queue.enqueueCopyBuffer(sums, buffer_of(out.loss), 0, 0, dtype_size(acc), nullptr,
                                &op.events.back());
    mark_written(out.loss, op.events.back());
    if (r.background) {
      out.background = s.output("background gradient", {channels == 4 ? 3 : 1}, acc,
                                "the background gradient");
      op.events.push_back(cl::Event());
      dev.queue.enqueueCopyBuffer(sums, buffer_of(out.background), dtype_size(acc), 0,
                                  out.background.bytes(), nullptr, &op.events.back());
      mark_written(out.background, op.events.back());
    }
    if (r.camera) {
      out.camera = s.output("camera gradient", {views, 7}, acc, "the camera gradient");
      op.events.push_back(s.arrays.sum_rows(camera_partial, int(launch.groups_per_view), 7, views,
                                            buffer_of(out.camera)));
      mark_written(out.camera, op.events.back());
    }
    if (r.tf) mark_written(out.tf, op.events.back());
    mark_written(out.image, op.events.back());
  });
  op.samples = samples;
  op.sample_count = pixels;
  return out;
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
  Session session = one_shot_session(
      device, scene, {options.precision, options.step, options.empty_space, 0.05,
                      options.brick_size});
  Session::Impl& s = session.impl();
  session.set_target(target);
  AdjointRequest r;
  r.density = options.density;
  r.tf = options.tf;
  r.background = options.background;
  r.camera = options.camera;
  r.loss = options.loss;
  r.deterministic = options.deterministic;
  const AdjointResult a = enqueue_adjoint(s, s.target, r, s.begin("gradient"));
  Gradient g;
  g.loss = a.loss.to_doubles()[0];
  if (r.density) g.density = a.density.to_floats();
  if (r.tf) g.tf = a.tf.to_doubles();
  if (r.background) g.background = a.background.to_doubles();
  if (r.camera) g.camera = a.camera.to_doubles();
  const OperationStats st = session.last_stats();
  g.kernel_seconds = st.kernel_seconds;
  g.device_bytes = st.device_bytes;
  g.samples = st.samples;
  g.atomics = a.atomics;
  g.skipped_empty = st.skipped_empty;
  g.empty_fraction = st.empty_fraction;
  g.step = st.step;
  g.deterministic = st.deterministic;
  g.fixed_exponent = st.fixed_exponent;
  return g;
}

}  // namespace ivr
