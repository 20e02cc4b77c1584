// adjoint.cpp — the gradient operation in reverse mode: one launch of kernels/adjoint.cl (primal
// march, loss, and the constant-memory adjoint march) on the session's device copies, then the
// per-pixel terms and per-group camera sums reduced on the device; and the one-shot gradient().
#include "ivr/adjoint.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "adjoint/adjoint.hpp"
#include "adjoint/adjoint_bound.hpp"
#include "adjoint/private_sums.hpp"
#include "adjoint/scatter_cache.hpp"
#include "ivr_constants.h"
#include "render/render.hpp"
#include "runtime/real_args.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"

namespace ivr {

namespace {

constexpr std::size_t kFixedHeader = IVR_FIXED_HEADER;  // the longs before the voxels


// The largest |element| of `n` reals on the device (one reduction pass; waits).
double largest_magnitude(Session::Impl& s, const cl::Buffer& values, std::uint64_t n) {
  double lo = 0, hi = 0;
  std::vector<cl::Event> events;
  s.arrays.check_values(values, n, true, &lo, &hi, events);
  return std::max(std::abs(lo), std::abs(hi));
}

// The a-priori bound on one ray's density-gradient contributions (lib/adjoint/adjoint_bound.hpp)
// for this scene, these densities and this target: every input it reads is a function of the
// operation's inputs alone — the densities' exact range (measured again after an optimiser step,
// which only knows its bounds) and the target's largest element (cached with the session's target,
// measured for any other) — so the scale, and with it every bit of the result, is too.
double fixed_ray_bound(Session::Impl& s, const DeviceArray& target, Loss loss,
                       const FixedShare* share) {
  if (!s.volume_range_exact) {
    double lo = 0, hi = 0;
    std::vector<cl::Event> events;
    s.arrays.check_values(buffer_of(s.volume), s.volume.size(), true, &lo, &hi, events);
    s.volume_min = lo;
    s.volume_max = hi;
    s.volume_range_exact = true;
  }
  const bool session_target = target.impl() == s.target.impl() && s.target_abs_max >= 0;
  const double target_max = share ? share->target_max
                            : session_target
                                ? s.target_abs_max
                                : largest_magnitude(s, buffer_of(target), target.size());
  const double bound = ray_gradient_bound(
      s.scene, tf_extremes(s.scene.tf, s.volume_min, s.volume_max), target_max, loss,
      share ? share->elements : s.pixels() * std::size_t(s.scene.channels()));
  return std::ldexp(bound, fixed_bound_shift());
}

// Whether the adjoint marches packets of rays in vector lanes (kernels/adjoint.cl, IVR_RAYS): where
// renders do (CPU devices), for the density and TF gradients of every integrator. The camera
// gradient sums each ray's positions along its march: it keeps one ray per work-item (with the
// primal from a packet render where use_packet_primal says).
bool use_packet_adjoint(const Device::Impl& dev, const AdjointRequest& r) {
  return use_packet(dev) && !r.camera;
}

// Private sums (lib/adjoint/private_sums.hpp) for this operation: not while the tuner looks at
// the pixel launches (ivr tune: it records which an operation makes, then shapes their
// work-groups, which the private sums' one-item groups do not have).
PrivateSums private_sums_of(const Device::Impl& dev, const Scene& scene, std::size_t pixels,
                            std::size_t real, const AdjointRequest& r, bool packet, bool fixed,
                            bool scatter_cache) {
  if (tuning_probe()) return {};
  PrivateSumsQuery q;
  q.packet = packet;
  q.density = r.density;
  q.eligible = !r.camera && !fixed && !scatter_cache;
  q.voxels = scene.volume.voxel_count();
  q.real_size = real;
  q.pixels = pixels;
  q.longest_edge = std::max({scene.volume.nx, scene.volume.ny, scene.volume.nz});
  return private_sums_for(dev.info, q);
}

KernelConfig adjoint_config(const RenderVariant& v, const AdjointRequest& r, std::size_t tf_rows,
                            bool fixed, bool primal_given, AtomicAdd atomics, bool scatter_cache,
                            bool packet, bool private_sums) {
  KernelConfig c = v.config("adjoint.cl", "adjoint");
  if (packet) c.set(Switch::rays, packet_lanes(v.precision));
  // IVR_TF_ROWS sizes the per-ray TF-gradient cache (kernels/adjoint_tf.cl; normalised).
  c.set(Switch::tf_rows, int(std::min<std::size_t>(tf_rows, 1 << 20)))
      .set(Switch::grad_density, r.density)
      .set(Switch::grad_tf, r.tf)
      .set(Switch::grad_camera, r.camera)
      .set(Switch::loss_l1, r.loss == Loss::l1)
      .set(Switch::loss_dot, r.loss == Loss::dot)
      .set(Switch::deterministic, fixed)
      .set(Switch::primal_given, primal_given)
      .set(Switch::scatter_cache, scatter_cache)
      .set(Switch::private_sums, private_sums);
  return c.with_atomics(atomics);
}

}  // namespace

bool has_int64_atomics(Device::Impl& dev) {
  return dev.device.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_khr_int64_base_atomics") !=
         std::string::npos;
}

AdjointResult enqueue_adjoint(Session::Impl& s, const DeviceArray& target, const AdjointRequest& r,
                              OperationRecord& op) {
  Device::Impl& dev = s.dev;
  const Scene& scene = s.scene;
  const Integrator& integrator = s.integrator();
  const ImageExtent cam0 = image_extent(scene);
  const int views = cam0.views, channels = scene.channels();
  if (r.camera && scene.has_ray_list())
    throw Error(Status::invalid_argument,
                "adjoint: the camera gradient of a ray list: its rays have no camera to "
                "differentiate (ask for density, tf or background)");
  const std::size_t pixels = s.pixels(), voxels = scene.volume.voxel_count();
  const std::vector<std::size_t> tf_shape = tf_gradient_shape(scene.tf);
  const std::size_t tf_size = tf_shape[0] * tf_shape[1], real = s.real_size;

  // Deterministic: the density gradient summed in fixed point, where the device has 64-bit
  // integer atomics (else the float atomics, and the stats say it was not).
  const bool fixed = r.density && r.deterministic && has_int64_atomics(dev);
  const AtomicAdd atomics = atomic_add_for(dev.info, s.f64);
  // The density gradient's adds summed per work-group in local memory first where that pays
  // (lib/adjoint/scatter_cache.hpp; the fixed-point adds bypass it), beside the TF accumulator and
  // the camera's per-item scratch.
  const std::size_t other_local = (std::max<std::size_t>(tf_size, 1) +
                                   (r.camera ? expected_group_items(dev.info, "adjoint") * 7 : 1)) *
                                  real;
  const bool scatter_cache = r.density && !fixed && scatter_cache_for(dev, real, other_local);
  RenderVariant variant = s.variant_of(integrator);
  // The fixed-point scale's bound, before the march (it may measure the densities' range again,
  // which the skipping plan below then shares).
  const double fixed_bound = fixed ? fixed_ray_bound(s, target, r.loss, r.share) : 0;
  // Empty-space skipping where the gradient stays exact (lib/empty_space/empty_space.hpp).
  const cl::Buffer& occupied =
      s.plan_skipping(gradient_may_skip(scene.tf, r.tf, r.density || r.camera), variant, op.stats);
  // On CPU devices the adjoint kernel marches packets of rays itself (primal and adjoint); where
  // it marches one ray per work-item there, the packet render (16 rays per work-item in vector
  // lanes) marches the primal several times faster than the kernel's own one-ray march: it leaves
  // each pixel's C, T and samples in the image and sample buffers, where the adjoint kernel reads
  // them.
  const bool packet = use_packet_adjoint(dev, r);
  const bool primal_given = !packet && use_packet_primal(dev, variant);
  // On CPU devices: work-groups of one work-item marching packets, each summing into its own
  // memory without atomics (kernels/private_sums.cl).
  const PrivateSums priv =
      private_sums_of(dev, scene, pixels, real, r, packet, fixed, scatter_cache);

  AdjointResult out;
  out.atomics = atomic_add_name(atomics);
  out.image = s.output("gradient image", s.image_shape(), real_dtype(s.f64), "the image");
  const cl::Buffer& terms = s.scratch("terms", pixels * 4 * real, "the per-pixel terms");
  const cl::Buffer& samples = s.scratch("samples", pixels * sizeof(cl_uint), "the sample counts");
  const std::size_t grad_bytes =
      fixed ? (voxels + kFixedHeader) * sizeof(cl_long) : (r.density ? voxels : 1) * real;
  // The density gradient: its own array, or the fixed-point sums converted into one.
  if (r.density)
    out.density =
        s.output("density gradient", s.volume_shape(), real_dtype(s.f64), "the density gradient");
  const std::size_t private_bytes = priv.on ? priv.bytes(real) : 0;
  if (private_bytes > s.private_copies_bytes) {  // the old copies go before the new are made
    s.private_copies = cl::Buffer();
    s.private_copies_bytes = s.private_copies_clean = 0;
    s.private_copies = dev.buffer(CL_MEM_READ_WRITE, private_bytes, nullptr,
                                  "the density gradient's private copies");
    s.private_copies_bytes = private_bytes;
  }
  const cl::Buffer& grad_volume =
      private_bytes ? s.private_copies
      : r.density && !fixed
          ? buffer_of(out.density)
          : s.scratch(fixed ? "fixed density" : "no density", grad_bytes, "the density gradient");
  if (r.tf)
    out.tf = s.output("tf gradient", {std::int64_t(tf_shape[0]), std::int64_t(tf_shape[1])},
                      real_dtype(s.f64), "the transfer-function gradient");
  const cl::Buffer& grad_tf =
      r.tf ? buffer_of(out.tf) : s.scratch("no tf", real, "the transfer-function gradient");
  const DType acc = s.arrays.acc_dtype();
  const cl::Buffer& sums = s.scratch("adjoint sums", 4 * 8, "the loss and background sums");

  const KernelConfig config = adjoint_config(variant, r, tf_shape[0], fixed, primal_given, atomics,
                                             scatter_cache, packet, priv.on);
  op.stats.variant = config.label();
  op.stats.skipped_empty = variant.empty_space;
  op.stats.step = integrator.step;
  op.stats.deterministic = fixed;
  op.stats.mode = Mode::adjoint;
  op.stats.device_bytes = s.scene_bytes() + target.bytes() + out.image.bytes() +
                          pixels * (4 * real + sizeof(cl_uint)) + grad_bytes +
                          std::max<std::size_t>(tf_size, 1) * real + (fixed ? voxels * real : 0) +
                          private_bytes;
  cl_call("running the adjoint kernel on " + dev.info.name, [&] {
    double build = 0;
    cl::Kernel& k = s.kernels.get(config, &build);
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
    set_real(k, a++, s.f64, 1.0 / double(r.share ? r.share->elements : pixels * channels));
    k.setArg(a++, buffer_of(out.image));
    k.setArg(a++, terms);
    k.setArg(a++, grad_volume);
    k.setArg(a++, grad_tf);
    k.setArg(a++, cl::Local(std::max<std::size_t>(tf_size, 1) * real));
    k.setArg(a++, cl_int(r.tf ? tf_size : 0));
    k.setArg(a++, samples);
    // A work-group's items share one local TF accumulator (the padding items only meet
    // barriers), so the size is always explicit.
    const PacketShape tile = packet_shape(packet ? packet_lanes(variant.precision) : 1, variant.ray_list);
    const PixelLaunch launch =
        priv.on ? PixelLaunch{}
                : pixel_launch(dev, k, packet ? "adjoint_packet" : "adjoint",
                               tile.across(cam0.width), tile.down(cam0.height), views, true);
    // The camera gradient: 7 values per work-group, summed per view on the device.
    const std::size_t partials = r.camera ? launch.groups_per_view * std::size_t(views) * 7 : 1;
    const cl::Buffer& camera_partial =
        s.scratch("camera partials", partials * real, "the camera gradient's partial sums");
    op.stats.device_bytes += partials * real;
    k.setArg(a++, s.camera_params);
    k.setArg(a++, camera_partial);
    k.setArg(a++,
             cl::Local((r.camera ? std::size_t(launch.group_x) * launch.group_y * 7 : 1) * real));
    k.setArg(a++, occupied);
    k.setArg(a++, s.brick_counts());
    // Private sums: the packets' counter and their number.
    const cl::Buffer& work = s.scratch("adjoint work", sizeof(cl_int), "the packets' counter");
    k.setArg(a++, work);
    k.setArg(a++, cl_int(tile.across(cam0.width) * tile.down(cam0.height) * views));
    // Fixed point: no ray's scaled Σ |contribution| above 2^62 / rays, so no voxel's sum leaves
    // the long range.
    const int cap_exponent = fixed_cap_exponent(r.share ? r.share->rays : pixels);
    std::size_t clean = 0;  // the private copies' leading bytes that are 0 after this call
    auto run_pass = [&](int exponent) {
      if (fixed) {
        op.events.push_back(cl::Event());
        dev.queue.enqueueFillBuffer(grad_volume, cl_long(0), 0, grad_bytes, nullptr,
                                    &op.events.back());
        const cl_long header[kFixedHeader] = {exponent, cl_long(1) << cap_exponent, 0, 0, 0};
        dev.queue.enqueueWriteBuffer(grad_volume, CL_TRUE, 0, sizeof header, header);
      } else if (private_bytes) {  // the copies are 0 where the last sum left them so
        if (s.private_copies_clean < private_bytes) {
          op.events.push_back(cl::Event());
          dev.queue.enqueueFillBuffer(grad_volume, cl_uchar(0), 0, private_bytes, nullptr,
                                      &op.events.back());
        }
        clean = std::max(s.private_copies_clean, private_bytes);
        s.private_copies_clean = 0;  // until the sum is enqueued
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
      if (primal)
        op.events.push_back(
            enqueue(dev, *primal, packet_launch(dev, *primal, scene, variant.precision)));
      if (!priv.on) {
        op.events.push_back(enqueue(dev, k, launch));
        return;
      }
      op.events.push_back(cl::Event());
      dev.queue.enqueueFillBuffer(work, cl_int(0), 0, sizeof(cl_int), nullptr, &op.events.back());
      op.events.push_back(enqueue_groups(dev, k, std::size_t(priv.groups), 1));
      if (private_bytes) {  // the copies into the gradient, which leaves them 0
        cl::Kernel& sum = s.kernels.get(config.with_entry("sum_private_copies"));
        sum.setArg(0, cl_int(voxels));
        sum.setArg(1, cl_int(priv.groups));
        sum.setArg(2, grad_volume);
        sum.setArg(3, buffer_of(out.density));
        const std::size_t chunks = (voxels + IVR_PRIVATE_ALIGN - 1) / IVR_PRIVATE_ALIGN;
        op.events.push_back(enqueue_1d(dev, sum, chunks, 0));
        s.private_copies_clean = clean;
      }
    };
    if (!fixed) {
      run_pass(0);
    } else {
      // One pass at the scale the a-priori bound sets (lib/adjoint/adjoint_bound.hpp). The pass
      // counts rays over the cap and records the largest contribution and ray sum (all
      // order-independent); where the bound was violated or far too loose, one more pass runs at
      // the scale the largest ray calls for. Each step is a function of the inputs alone, so the
      // bits are too, whatever the session did before.
      int exponent = fixed_exponent_from_bound(fixed_bound, cap_exponent), passes = 0;
      float largest = 0, largest_ray = 0;
      for (;;) {
        run_pass(exponent);
        ++passes;
        cl_long header[kFixedHeader];
        dev.queue.enqueueReadBuffer(grad_volume, CL_TRUE, 0, sizeof header, header);
        std::memcpy(&largest, &header[3], sizeof largest);
        std::memcpy(&largest_ray, &header[4], sizeof largest_ray);
        if (r.share && r.share->agree) r.share->agree(header[2], largest, largest_ray);
        if (!std::isfinite(largest) || !std::isfinite(largest_ray))
          throw Error(Status::opencl,
                      "the fixed-point density gradient met a contribution that is not finite");
        const int next =
            fixed_exponent_after(exponent, header[2], largest, largest_ray, cap_exponent);
        if (next == exponent) break;
        if (passes == 2)  // the measured scale holds every ray: not reached
          throw Error(Status::opencl, "the fixed-point density gradient overflowed at scale 2^" +
                                          std::to_string(exponent));
        exponent = next;
      }
      op.stats.fixed_exponent = exponent;
      op.stats.fixed_passes = passes;
      op.stats.fixed_bound = fixed_bound;
      op.stats.fixed_largest = largest;
      op.stats.fixed_largest_ray = largest_ray;
      if (r.share && r.share->add) {  // the batch's integer sums, then the one conversion
        std::vector<std::int64_t> sums(voxels);
        const std::size_t at = kFixedHeader * sizeof(cl_long), bytes = voxels * sizeof(cl_long);
        dev.queue.enqueueReadBuffer(grad_volume, CL_TRUE, at, bytes, sums.data());
        r.share->add(sums);
        dev.queue.enqueueWriteBuffer(grad_volume, CL_TRUE, at, bytes, sums.data());
      }
      cl::Kernel& convert = s.kernels.get(config.with_entry("fixed_to_real"));
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
      out.background =
          s.output("background gradient", {channels == 4 ? 3 : 1}, acc, "the background gradient");
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
    if (loss == Loss::dot) {
      sum += double(image.pixels[i]) * double(target.pixels[i]);
      continue;
    }
    const double d = double(image.pixels[i]) - double(target.pixels[i]);
    sum += loss == Loss::l1 ? std::abs(d) : d * d;
  }
  if (loss == Loss::dot) return sum;  // a weighted sum, not a mean (kernels/loss.cl)
  return image.pixels.empty() ? 0.0 : sum / double(image.pixels.size());
}

AdjointGradient adjoint(Device& device, const Scene& scene, const Image& target,
                        const AdjointOptions& options) {
  Session session = one_shot_session(
      device, scene,
      {options.precision, options.step, options.empty_space, 0.05, options.brick_size});
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
  AdjointGradient g;
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
  g.fixed_passes = st.fixed_passes;
  return g;
}

}  // namespace ivr
