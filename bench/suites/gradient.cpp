// gradient.cpp — the gradient suite: d loss / d every voxel (MSE against a target) by ivr's adjoint
// against the native hand-written adjoint and the Python baselines' reverse mode (JAX jax.grad,
// Dr.Jit dr.backward, PyTorch autograd) on the same scene and step. ivr's gradient is checked
// first against central differences of the independent float64 reference's loss along a smooth
// direction; every other implementation must then agree with ivr's gradient entry by entry. Beside
// ivr's: its time over a render's and its memory at step 0.1 over step 0.5's (issue 3's targets).
// On CPU devices also every integrator's gradient, the packet kernel beside the one-ray kernel.
#include <cmath>
#include <iostream>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "reference/native_marcher.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"
#include "reference/reference.hpp"

namespace ivr::bench {

namespace {

constexpr double kDirectionalTolerance = 2e-3;  // relative, against central differences
constexpr double kAgreement = 1e-3;             // relative L2 against ivr's gradient

// A smooth direction over the voxels (x fastest), so the difference quotient stays in the smooth
// regime of the loss.
std::vector<double> smooth_direction(const Volume& v) {
  std::vector<double> d(v.data.size());
  std::size_t i = 0;
  for (int z = 0; z < v.nz; ++z)
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < v.nx; ++x)
        d[i++] = std::sin(5.0 * x / v.nx + 1) * std::cos(3.0 * y / v.ny - 2.0 * z / v.nz);
  return d;
}

// The float64 reference's MSE loss with the densities moved by eps · direction.
double reference_loss(const Scene& scene, const std::vector<double>& direction, double eps,
                      double step_world, const Image& target) {
  Scene s = scene;
  for (std::size_t i = 0; i < direction.size(); ++i)
    s.volume.data[i] = float(double(scene.volume.data[i]) + eps * direction[i]);
  const std::vector<double> img = reference::render_midpoint(s, step_world, true);
  double sum = 0;
  for (std::size_t i = 0; i < img.size(); ++i) {
    const double e = img[i] - double(target.pixels[i]);
    sum += e * e;
  }
  return sum / double(img.size());
}

double dot(const std::vector<float>& a, const std::vector<double>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += double(a[i]) * b[i];
  return s;
}

struct Case {
  int volume, image;
  double step;
  std::string name() const { return scene_case(volume, image, step); }
};

// On CPU devices, where the adjoint marches packets of rays: each integrator's density gradient
// (the benchmark scene in bench_scene.hpp's looks; "": midpoint), timed as the packet kernel
// ("ivr") and as the one-ray kernel ("ivr-one-ray", $IVR_PACKET=0) in the same run, each checked
// against the other (the one-ray kernel is the one the tests hold to differences; the two differ
// by the order of the float atomic adds). The midpoint's packet record is the suite's "ivr".
void integrator_gradients(Context& ctx, const Case& c, const nlohmann::json& params) {
  if (ctx.device.info().type != "cpu") return;  // (other devices march one ray per work-item)
  constexpr double kSameKernel = 1e-5;             // relative L2: float sums in another order
  for (const char* look : {"", "trapezoid", "preintegrated", "exact"}) {
    const Scene scene = look_scene(c.volume, c.image, look);
    const Image target = perturbed_target(ctx.device, scene, c.step);
    const std::string name = c.name() + (*look ? std::string("_") + look : "");
    AdjointOptions o;
    o.step = c.step;
    std::vector<float> packet, one_ray;
    {
      packet = adjoint(ctx.device, scene, target, o).density;
      const ScopedEnv env("IVR_PACKET", "0");
      one_ray = adjoint(ctx.device, scene, target, o).density;
    }
    for (const bool packets : {true, false}) {
      if (!*look && packets) continue;
      const ScopedEnv env("IVR_PACKET", packets ? "1" : "0");
      Record r{ctx.device_key, "gradient", name, packets ? "ivr" : "ivr-one-ray", params};
      if (*look) r.params["look"] = look;
      const Check check = check_l2(difference(packets ? packet : one_ray,
                                              widen(packets ? one_ray : packet)),
                                   packets ? "the one-ray kernel's gradient"
                                           : "the packet kernel's gradient",
                                   kSameKernel);
      AdjointGradient g;
      const Measurement m = measure(
          ctx.budget,
          [&] {
            g = adjoint(ctx.device, scene, target, o);
            return g.kernel_seconds;
          },
          [&] { return check.passed; });
      add_timing(r, m);
      r.metrics["samples"] = g.samples;
      r.metrics["samples_per_s"] = double(g.samples) / m.wall.median;
      record_checked(ctx, std::move(r), check);
    }
  }
}

}  // namespace

void gradient_suite(Context& ctx) {
  const Case c = ctx.quick ? Case{32, 64, 0.5} : Case{128, 256, 0.5};
  const Scene scene = bench_scene(c.volume, c.image);
  const Image target = perturbed_target(ctx.device, scene, c.step);
  const nlohmann::json params = {{"volume", c.volume},
                                 {"image", c.image},
                                 {"step", c.step},
                                 {"loss", "mse"},
                                 {"wrt", "density"}};

  // Central differences of the float64 reference loss: the directional derivative every
  // gradient is held to. Once per run (it does not depend on the device).
  // Without early termination: a ray whose transmittance crosses the threshold between the two
  // evaluations jumps by ~ the threshold, which swamps the quotient. ivr's gradient of that scene
  // is held to it; the timed gradient (with termination) is held to that one.
  static std::map<std::string, double> fd_cache;
  Scene smooth = scene;
  smooth.integrator.min_transmittance = 0;
  const std::vector<double> direction = smooth_direction(scene.volume);
  const double h = reference::min_voxel_edge(scene), eps = 1e-3;
  if (!fd_cache.count(c.name())) {
    std::cerr << "ivr-bench: gradient/" << c.name() << ": float64 central differences...\n";
    fd_cache[c.name()] = (reference_loss(smooth, direction, eps, c.step * h, target) -
                          reference_loss(smooth, direction, -eps, c.step * h, target)) /
                         (2 * eps);
  }
  const double fd = fd_cache[c.name()];
  auto directional_check = [&](const std::vector<float>& g) {
    Check k;
    k.against =
        "float64 reference, central differences along a smooth direction (no early termination)";
    k.measure = "relative_directional";
    k.error = std::abs(dot(g, direction) - fd) / std::max(std::abs(fd), 1e-30);
    k.tolerance = kDirectionalTolerance;
    k.passed = k.error <= k.tolerance;
    return k;
  };

  // Issue 3's measures beside the gradient: its kernel time over a render's of the same scene and
  // step, and its peak device memory at step 0.1 over step 0.5's (the adjoint stores nothing per
  // sample, so it should not grow as the step shrinks).
  RenderStats render_stats;
  const Measurement render_m = measure(ctx.budget, [&] {
    render(ctx.device, scene, {Precision::f32, c.step}, &render_stats);
    return render_stats.kernel_seconds;
  });
  AdjointOptions fine;
  fine.step = 0.1;
  const AdjointGradient fine_gradient = adjoint(ctx.device, scene, target, fine);

  std::vector<float> ivr_gradient;
  for (const bool deterministic : {false, true}) {
    AdjointOptions o;
    o.step = c.step;
    o.deterministic = deterministic;
    const Check check = directional_check(adjoint(ctx.device, smooth, target, o).density);
    AdjointGradient g;
    const Measurement m = measure(
        ctx.budget,
        [&] {
          g = adjoint(ctx.device, scene, target, o);
          return g.kernel_seconds;
        },
        [&] { return check.passed; });
    Record r{ctx.device_key, "gradient", c.name(), deterministic ? "ivr-deterministic" : "ivr",
             params};
    add_timing(r, m);
    r.params["deterministic"] = g.deterministic;
    r.params["atomics"] = g.atomics;
    if (g.deterministic) {  // the fixed-point scale and the passes it took (1 unless its bound failed)
      r.params["fixed_exponent"] = g.fixed_exponent;
      r.params["fixed_passes"] = g.fixed_passes;
    }
    r.metrics["loss"] = g.loss;
    r.metrics["samples"] = g.samples;
    r.metrics["samples_per_s"] = double(g.samples) / m.wall.median;
    r.metrics["peak_device_bytes"] = g.device_bytes;
    r.metrics["memory_bytes"] = operation_memory(ctx, m, g.device_bytes);
    if (!deterministic && m.timed) {
      ivr_gradient = g.density;
      if (m.device && render_m.device && render_m.device->median > 0)
        r.metrics["gradient_over_render"] = m.device->median / render_m.device->median;
      r.metrics["peak_device_bytes_step_0.1"] = fine_gradient.device_bytes;
      if (g.device_bytes > 0)
        r.metrics["memory_step_0.1_over_step_0.5"] =
            double(fine_gradient.device_bytes) / double(g.device_bytes);
    }
    record_checked(ctx, std::move(r), check);
  }
  // Resident: the scene and the target already on the device in a session, the loss and the
  // gradient left there. Checked the same way, on a session of the smooth scene.
  for (const bool deterministic : {false, true}) {
    SessionOptions so;
    so.step = c.step;
    GradientRequest request;
    request.mode = Mode::adjoint;
    request.deterministic = deterministic;
    Session checked_session(ctx.device, smooth, so);
    checked_session.set_target(target);
    const Check check =
        directional_check(checked_session.gradient(request)["density"].to_floats());
    Session session(ctx.device, scene, so);
    session.set_target(target);
    SessionGradient g;
    const Measurement m = measure_resident(
        ctx.budget, session,
        [&] {
          g = session.gradient(request);
          g["density"].wait();
          g.loss.wait();
        },
        [&] { return check.passed; });
    const OperationStats stats = session.last_stats();
    Record r{ctx.device_key, "gradient", c.name(),
             deterministic ? "ivr-resident-deterministic" : "ivr-resident", params};
    add_timing(r, m);
    r.params["deterministic"] = stats.deterministic;
    r.params["atomics"] = g.atomics;
    if (stats.deterministic) {
      r.params["fixed_exponent"] = stats.fixed_exponent;
      r.params["fixed_passes"] = stats.fixed_passes;
      r.metrics["fixed_bound"] = stats.fixed_bound;
      r.metrics["fixed_largest"] = stats.fixed_largest;
    }
    r.metrics["loss"] = g.loss.to_doubles()[0];
    r.metrics["samples"] = stats.samples;
    r.metrics["samples_per_s"] = double(stats.samples) / m.wall.median;
    r.metrics["peak_device_bytes"] = stats.device_bytes;
    r.metrics["memory_bytes"] = operation_memory(ctx, m, stats.device_bytes);
    record_checked(ctx, std::move(r), check);
  }
  integrator_gradients(ctx, c, params);
  if (!ctx.host_baselines && !ctx.python_baselines) return;
  const std::vector<double> ivr_wide = widen(ivr_gradient);
  auto agreement = [&](const std::vector<float>& g, Record& r) {
    const Difference d = difference(g, ivr_wide);
    r.metrics["relative_l2_vs_ivr"] = d.relative_l2;
    return check_l2(d, "ivr's gradient (checked against the float64 reference)", kAgreement);
  };
  if (ivr_gradient.empty()) return;

  if (ctx.host_baselines) {  // The native hand-written adjoint.
    std::vector<float> g;
    double loss = 0;
    std::size_t samples = 0;
    Record r{kHostDevice, "gradient", c.name(), "native", params};
    Check check;
    const Measurement m = measure(
        ctx.budget,
        [&] {
          samples = native_gradient(scene, c.step, target.pixels, g, loss);
          return -1.0;
        },
        [&] {
          check = agreement(g, r);
          return check.passed;
        });
    add_timing(r, m);
    r.metrics["loss"] = loss;
    r.metrics["samples"] = samples;
    r.metrics["memory_bytes"] = m.peak_increase();
    record_checked(ctx, std::move(r), check);
  }

  const std::string dir = write_case(ctx.work_dir + "/gradient_" + c.name(), scene, c.step, target);
  run_python_baselines(ctx, "gradient", c.name(), params, dir, "grad", "grad",
                       [&](const BaselineRun& run, Record& r) {
                         const std::vector<float> g(run.output.begin(), run.output.end());
                         return agreement(g, r);
                       });
}

}  // namespace ivr::bench
