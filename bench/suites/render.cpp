// render.cpp — the render suite: ivr's forward render against the native C++/OpenMP marcher (the
// full run: 128³/256³ volumes into 256²/512² images at steps 0.5/0.25, and 128³ → 256² at step
// 0.5 through the identity TF and in the absorption model) and the Python baselines on the
// benchmark scene, each checked against the independent float64 reference at the same step before
// its times count; the error against a fine-step reference is reported beside every time. Both
// runs also render with the `preintegrated` and `exact` integrators (128³ → 256², quick: 64³ →
// 128²), and on CPU devices time the one-ray-per-work-item kernel ($IVR_PACKET=0,
// "ivr-one-ray", checked equal to the packet image bit for bit) beside the packet render of
// those cases and the others at step 0.5 of that size.
#include <functional>
#include <iostream>
#include <map>

#include "../bench_scene.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"
#include "reference/native_marcher.hpp"
#include "reference/reference.hpp"

namespace ivr::bench {

namespace {

struct RenderCase {
  int volume, image;
  double step;
  bool python_baselines = true;  // the grid's larger cases: ivr and the native marcher only
  std::string look;  // "": the benchmark scene; "identity", "absorption", "preintegrated", "exact"
  std::string name() const { return scene_case(volume, image, step) + (look.empty() ? "" : "_" + look); }
};

// The case's scene (bench_scene.hpp's looks).
Scene case_scene(const RenderCase& c) {
  return look_scene(c.volume, c.image, c.look);
}

// The float64 reference of the case's own integrator at the same step: the midpoint rule's
// discretisation, pre-integration's linear segments, or (exact) the continuous integral.
std::vector<double> same_step_reference(const Scene& scene, double step_world) {
  switch (scene.integrator.scheme) {
    case Scheme::preintegrated:
      return reference::render_linear_segments(scene, step_world);
    case Scheme::exact:
      return reference::render_continuous(scene, true);
    default:
      return reference::render_midpoint(scene, step_world, true);
  }
}

// References are the same for every device: computed once per run.
struct References {
  std::vector<double> same_step, fine;
};
std::map<std::string, References>& reference_cache() {
  static std::map<std::string, References> cache;
  return cache;
}

constexpr double kFineStep = 1.0 / 16;  // voxels: the "continuous" image the error is against
constexpr double kAtol = 1e-4, kRtol = 1e-3;

}  // namespace

void render_suite(Context& ctx) {
  // The full run: 128³ and 256³ into 256² and 512² at steps 0.5 and 0.25 against the native
  // marcher, the Python baselines on the first two.
  // Quick: the benchmark scene and the two exact integrators at 64³ → 128².
  std::vector<RenderCase> cases{{64, 128, 0.5}, {64, 128, 0.5, false, "preintegrated"},
                                {64, 128, 0.5, false, "exact"}};
  if (!ctx.quick) {
    cases = {{128, 256, 0.5}, {128, 256, 0.25}};
    for (int volume : {128, 256})
      for (int image : {256, 512})
        for (double step : {0.5, 0.25})
          if (volume != 128 || image != 256) cases.push_back({volume, image, step, false});
    for (const char* look : {"identity", "absorption", "preintegrated", "exact"})
      cases.push_back({128, 256, 0.5, false, look});
  }
  for (const RenderCase& c : cases) {
    if (!ctx.wants(c.name())) continue;
    const Scene scene = case_scene(c);
    const double h = reference::min_voxel_edge(scene);
    nlohmann::json params = {{"volume", c.volume},
                             {"image", c.image},
                             {"step", c.step},
                             {"scene", "calibration (Marschner–Lobb, 4-point TF)"}};
    if (!c.look.empty()) params["look"] = c.look;
    // The same-step reference per case, the fine one per scene (shared by its steps).
    References& ref = reference_cache()[c.name()];
    std::vector<double>& fine = reference_cache()["fine_" + std::to_string(c.volume) + "_" +
                                                  std::to_string(c.image) + c.look]
                                    .fine;
    if (ref.same_step.empty()) {
      std::cerr << "ivr-bench: render/" << c.name() << ": float64 references...\n";
      ref.same_step = same_step_reference(scene, c.step * h);
      if (!ctx.quick && fine.empty()) fine = reference::render(scene, kFineStep * h, true);
      ref.fine = fine;
    }
    auto with_error = [&](Record& r, const std::vector<float>& pixels) {
      if (ref.fine.empty()) return;
      const Difference e = difference(pixels, ref.fine);
      r.metrics["error_max_vs_fine"] = e.max_abs;
      r.metrics["error_relative_l2_vs_fine"] = e.relative_l2;
      r.params["fine_step"] = kFineStep;
    };
    const std::string against = "reference f64, same step";

    // ivr::render of the case, timed and checked by check_of(image) before its times count.
    const RenderOptions options{Precision::f32, c.step};
    struct Timed {
      Image image;
      RenderStats stats;
      Measurement m;
      Check check;
      Record r;
    };
    auto timed_render = [&](const std::string& implementation,
                            const std::function<Check(const Image&)>& check_of) {
      Timed t{{}, {}, {}, {}, {ctx.device_key, "render", c.name(), implementation, params}};
      t.m = measure(
          ctx.budget,
          [&] {
            t.image = render(ctx.device, scene, options, &t.stats);
            return t.stats.kernel_seconds;
          },
          [&] {
            t.check = check_of(t.image);
            return t.check.passed;
          });
      add_timing(t.r, t.m);
      t.r.metrics["samples"] = t.stats.samples;
      t.r.metrics["samples_per_s"] = double(t.stats.samples) / t.m.wall.median;
      return t;
    };

    // ivr on this device.
    {
      Timed t = timed_render("ivr", [&](const Image& image) {
        return check_max(difference(image.pixels, ref.same_step), against, kAtol, kRtol);
      });
      t.r.metrics["peak_device_bytes"] = t.stats.device_bytes;
      t.r.metrics["memory_bytes"] = operation_memory(ctx, t.m, t.stats.device_bytes);
      with_error(t.r, t.image.pixels);
      record_checked(ctx, std::move(t.r), t.check);

      // The same kernel with one ray per work-item, where packets are what runs (CPU devices):
      // what the packets gain, in the same run. Its image must be the packet's bit for bit.
      if ((ctx.quick || (c.volume == 128 && c.image == 256)) && c.step == 0.5 &&
          ctx.device.info().type == "cpu") {
        const std::vector<double> packet = widen(t.image.pixels);
        const ScopedEnv one_ray("IVR_PACKET", "0");
        Timed o = timed_render("ivr-one-ray", [&](const Image& image) {
          return check_max(difference(image.pixels, packet), "the packet render, bit for bit", 0,
                           0);
        });
        o.r.params["variant"] = o.stats.variant;
        record_checked(ctx, std::move(o.r), o.check);
      }
    }

    // ivr resident: the scene already on the device in a session, the image left there.
    {
      SessionOptions so;
      so.step = c.step;
      Session session(ctx.device, scene, so);
      DeviceArray image;
      Check check;
      const Measurement m = measure_resident(
          ctx.budget, session,
          [&] {
            image = session.render();
            image.wait();
          },
          [&] {
            check = check_max(difference(image.to_floats(), ref.same_step), against, kAtol, kRtol);
            return check.passed;
          });
      const OperationStats stats = session.last_stats();
      Record r{ctx.device_key, "render", c.name(), "ivr-resident", params};
      add_timing(r, m);
      r.metrics["samples"] = stats.samples;
      r.metrics["samples_per_s"] = double(stats.samples) / m.wall.median;
      r.metrics["peak_device_bytes"] = stats.device_bytes;
      r.metrics["memory_bytes"] = operation_memory(ctx, m, stats.device_bytes);
      if (m.timed) with_error(r, image.to_floats());
      record_checked(ctx, std::move(r), check);
    }
    // The native marcher and the Python baselines march the midpoint rule only: compared on the
    // integrators' cases they would be checked against another integral.
    if (scene.integrator.scheme != Scheme::midpoint) continue;
    if (!ctx.host_baselines && !ctx.python_baselines) continue;

    // The native marcher (host).
    if (ctx.host_baselines) {
      std::vector<float> pixels;
      std::size_t samples = 0;
      Check check;
      const Measurement m = measure(
          ctx.budget,
          [&] {
            samples = native_render(scene, c.step, pixels);
            return -1.0;
          },
          [&] {
            check = check_max(difference(pixels, ref.same_step), against, kAtol, kRtol);
            return check.passed;
          });
      Record r{kHostDevice, "render", c.name(), "native", params};
      add_timing(r, m);
      r.metrics["samples"] = samples;
      r.metrics["samples_per_s"] = double(samples) / m.wall.median;
      r.metrics["memory_bytes"] = m.peak_increase();
      with_error(r, pixels);
      record_checked(ctx, std::move(r), check);
    }

    // The Python baselines on the same case.
    if (!c.python_baselines) continue;
    const Image target = render(ctx.device, scene, {Precision::f32, c.step});
    const std::string dir = write_case(ctx.work_dir + "/render_" + c.name(), scene, c.step, target);
    run_python_baselines(ctx, "render", c.name(), params, dir, "render", "image",
                         [&](const BaselineRun& run, Record& r) {
                           std::vector<float> pixels(run.output.begin(), run.output.end());
                           with_error(r, pixels);
                           return check_max(difference(run.output, ref.same_step), against, kAtol,
                                            kRtol);
                         });
  }
}

}  // namespace ivr::bench
