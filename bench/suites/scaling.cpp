// scaling.cpp — the scaling suite: ivr's render and density gradient as the volume grows (32³ →
// 512³), the image grows (64² → 1024²) and the step shrinks, with time and memory per case and the
// exponents of power laws fitted to them (time ∝ size^k by least squares in log–log). Each result
// is checked against the native marcher and its hand-written adjoint (themselves checked against
// the float64 reference in the render and gradient suites).
#include <cmath>
#include <iostream>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "reference/native_marcher.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

namespace {

constexpr double kAtol = 1e-4, kRtol = 1e-3, kGradientAgreement = 1e-3;

struct Point {
  int volume, image;
  double step;
};

// Least-squares slope of log(y) against log(x).
double slope(const std::vector<std::pair<double, double>>& xy) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = double(xy.size());
  for (const auto& [x, y] : xy) {
    sx += std::log(x);
    sy += std::log(y);
    sxx += std::log(x) * std::log(x);
    sxy += std::log(x) * std::log(y);
  }
  return n < 2 ? NAN : (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

// The same render and gradient resident (the scene and target on the device in a session),
// held to the one-shot results (checked against the native marcher) first.
void resident_cases(Context& ctx, const Scene& scene, double step, const std::string& name,
                    const nlohmann::json& params, const Image& image, const Image& target,
                    const std::vector<float>& density) {
  SessionOptions so;
  so.step = step;
  Session session(ctx.device, scene, so);
  {
    DeviceArray out;
    Check k;
    const Measurement m = measure_resident(
        ctx.budget, session,
        [&] {
          out = session.render();
          out.wait();
        },
        [&] {
          k = check_max(difference(out.to_floats(), widen(image.pixels)),
                        "ivr one-shot (checked against the native marcher)", kAtol, kRtol);
          return k.passed;
        });
    const OperationStats stats = session.last_stats();
    Record r{ctx.device_key, "scaling", name + "_render", "ivr-resident", params};
    add_timing(r, m);
    r.metrics["samples_per_s"] = double(stats.samples) / m.wall.median;
    r.metrics["peak_device_bytes"] = stats.device_bytes;
    r.metrics["memory_bytes"] = operation_memory(ctx, m, stats.device_bytes);
    record_checked(ctx, std::move(r), k);
  }
  session.set_target(target);
  GradientRequest request;
  request.mode = Mode::adjoint;
  SessionGradient g;
  Check k;
  const Measurement m = measure_resident(
      ctx.budget, session,
      [&] {
        g = session.gradient(request);
        g["density"].wait();
      },
      [&] {
        k = check_l2(difference(g["density"].to_floats(), widen(density)),
                     "ivr one-shot (checked against the native adjoint)", kGradientAgreement);
        return k.passed;
      });
  const OperationStats stats = session.last_stats();
  Record r{ctx.device_key, "scaling", name + "_gradient", "ivr-resident", params};
  add_timing(r, m);
  r.metrics["peak_device_bytes"] = stats.device_bytes;
  r.metrics["memory_bytes"] = operation_memory(ctx, m, stats.device_bytes);
  record_checked(ctx, std::move(r), k);
}

// Setting a new volume in a session (its upload and the device pass that checks it) against the
// raw upload of the same bytes into a device array.
void set_volume_case(Context& ctx, const Scene& scene, const std::string& name,
                     const nlohmann::json& params) {
  Session session(ctx.device, scene);
  const Volume& v = scene.volume;
  DeviceArray raw(ctx.device, {v.nz, v.ny, v.nx}, DType::f32);
  Measurement upload_m, set_m;
  Check k;
  upload_m = measure(ctx.budget, [&] {
    raw.upload(v.data.data(), v.data.size());
    raw.wait();
    return -1.0;
  });
  set_m = measure(
      ctx.budget,
      [&] {
        session.set_volume(v);
        return -1.0;
      },
      [&] {
        k = check_max(difference(session.volume().to_floats(), widen(v.data)),
                      "the host densities", 0, 0);
        return k.passed;
      });
  Record up{ctx.device_key, "scaling", name + "_upload", "raw-upload", params};
  add_timing(up, upload_m);
  up.metrics["bytes"] = v.data.size() * sizeof(float);
  up.metrics["bytes_per_s"] = double(v.data.size() * sizeof(float)) / upload_m.wall.median;
  ctx.results.add(std::move(up));
  Record r{ctx.device_key, "scaling", name + "_set_volume", "ivr-resident", params};
  add_timing(r, set_m);
  r.metrics["over_raw_upload"] = set_m.wall.median / upload_m.wall.median;
  record_checked(ctx, std::move(r), k);
}

}  // namespace

void scaling_suite(Context& ctx) {
  struct Series {
    std::string name;  // what grows
    std::vector<Point> points;
  };
  const std::vector<int> volumes =
      ctx.quick ? std::vector<int>{32, 64} : std::vector<int>{32, 64, 128, 256, 512};
  const std::vector<int> images =
      ctx.quick ? std::vector<int>{64, 128} : std::vector<int>{64, 128, 256, 512, 1024};
  const std::vector<double> steps =
      ctx.quick ? std::vector<double>{1, 0.5} : std::vector<double>{1, 0.5, 0.25, 0.125};
  const int base_volume = ctx.quick ? 32 : 128, base_image = ctx.quick ? 64 : 256;
  std::vector<Series> series(4);
  series[0].name = "volume";
  for (int v : volumes) series[0].points.push_back({v, base_image, 0.5});
  series[1].name = "image";
  for (int i : images) series[1].points.push_back({base_volume, i, 0.5});
  series[2].name = "step";
  for (double s : steps) series[2].points.push_back({base_volume, base_image, s});
  // Volume and image together (an image of twice the volume's edge): the adjoint's kernel time
  // against the render's at 128³ → 256² and 256³ → 512², the sizes issue 18's target names.
  series[3].name = "volume_and_image";
  for (int v : ctx.quick ? std::vector<int>{16, 32} : std::vector<int>{64, 128, 256})
    series[3].points.push_back({v, 2 * v, 0.5});

  Record summary{ctx.device_key, "scaling", "exponents", "ivr", nlohmann::json::object()};
  for (const Series& s : series) {
    std::vector<std::pair<double, double>> render_time, gradient_time, gradient_memory;
    for (const Point& p : s.points) {
      const Scene scene = bench_scene(p.volume, p.image);
      const std::string name = s.name + "_" + scene_case(p.volume, p.image, p.step);
      const nlohmann::json params = {
          {"grows", s.name}, {"volume", p.volume}, {"image", p.image}, {"step", p.step}};
      std::cerr << "ivr-bench: scaling/" << name << "\n";
      const double x = s.name == "image" ? p.image : s.name == "step" ? 1.0 / p.step : p.volume;

      Image img;  // the one-shot results, checked against the native marcher, hold the resident
      AdjointGradient g;
      {  // render
        RenderStats stats;
        const RenderOptions o{Precision::f32, p.step};
        Check k;
        const Measurement m = measure(
            ctx.budget,
            [&] {
              img = render(ctx.device, scene, o, &stats);
              return stats.kernel_seconds;
            },
            [&] {
              std::vector<float> native;
              native_render(scene, p.step, native);
              k = check_max(difference(img.pixels, widen(native)), "native marcher", kAtol, kRtol);
              return k.passed;
            });
        Record r{ctx.device_key, "scaling", name + "_render", "ivr", params};
        add_timing(r, m);
        r.metrics["samples"] = stats.samples;
        r.metrics["samples_per_s"] = double(stats.samples) / m.wall.median;
        r.metrics["peak_device_bytes"] = stats.device_bytes;
        r.metrics["memory_bytes"] = operation_memory(ctx, m, stats.device_bytes);
        if (k.passed) render_time.push_back({x, m.wall.median});
        record_checked(ctx, std::move(r), k);
      }
      const Image target = perturbed_target(ctx.device, scene, p.step);
      {  // density gradient
        AdjointOptions o;
        o.step = p.step;
        Check k;
        const Measurement m = measure(
            ctx.budget,
            [&] {
              g = adjoint(ctx.device, scene, target, o);
              return g.kernel_seconds;
            },
            [&] {
              std::vector<float> native;
              double loss = 0;
              native_gradient(scene, p.step, target.pixels, native, loss);
              k = check_l2(difference(g.density, widen(native)), "native adjoint",
                           kGradientAgreement);
              return k.passed;
            });
        Record r{ctx.device_key, "scaling", name + "_gradient", "ivr", params};
        add_timing(r, m);
        r.metrics["samples"] = g.samples;
        r.metrics["peak_device_bytes"] = g.device_bytes;
        const std::uint64_t memory = operation_memory(ctx, m, g.device_bytes);
        r.metrics["memory_bytes"] = memory;
        if (k.passed) {
          gradient_time.push_back({x, m.wall.median});
          gradient_memory.push_back({x, double(g.device_bytes)});
        }
        record_checked(ctx, std::move(r), k);
      }
      resident_cases(ctx, scene, p.step, name, params, img, target, g.density);
      if (s.name == "volume") set_volume_case(ctx, scene, name, params);
    }
    const std::string per = s.name == "step" ? "inverse_step" : s.name + "_edge";
    summary.metrics["render_time_vs_" + per] = slope(render_time);
    summary.metrics["gradient_time_vs_" + per] = slope(gradient_time);
    summary.metrics["gradient_device_memory_vs_" + per] = slope(gradient_memory);
  }
  summary.note = "exponents k of time ∝ x^k (least squares, log–log) over the cases that passed";
  ctx.results.add(std::move(summary));
}

}  // namespace ivr::bench
