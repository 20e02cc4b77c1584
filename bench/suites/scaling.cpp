// scaling.cpp — the scaling suite: ivr's render and density gradient as the volume grows (32³ →
// 512³), the image grows (64² → 1024²) and the step shrinks, with time and memory per case and the
// exponents of power laws fitted to them (time ∝ size^k by least squares in log–log). Each result
// is checked against the native marcher and its hand-written adjoint (themselves checked against
// the float64 reference in the render and gradient suites).
#include <cmath>
#include <iostream>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../native_marcher.hpp"
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
  std::vector<Series> series(3);
  series[0].name = "volume";
  for (int v : volumes) series[0].points.push_back({v, base_image, 0.5});
  series[1].name = "image";
  for (int i : images) series[1].points.push_back({base_volume, i, 0.5});
  series[2].name = "step";
  for (double s : steps) series[2].points.push_back({base_volume, base_image, s});

  Record summary{ctx.device_key, "scaling", "exponents", "ivr", nlohmann::json::object()};
  for (const Series& s : series) {
    std::vector<std::pair<double, double>> render_time, gradient_time, gradient_memory;
    for (const Point& p : s.points) {
      const Scene scene = bench_scene(p.volume, p.image);
      const std::string name = s.name + "_" + scene_case(p.volume, p.image, p.step);
      const nlohmann::json params = {
          {"grows", s.name}, {"volume", p.volume}, {"image", p.image}, {"step", p.step}};
      std::cerr << "ivr-bench: scaling/" << name << "\n";
      const double x = s.name == "volume" ? p.volume : s.name == "image" ? p.image : 1.0 / p.step;

      {  // render
        RenderStats stats;
        Image img;
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
      {  // density gradient
        const Image target = perturbed_target(ctx.device, scene, p.step);
        GradientOptions o;
        o.step = p.step;
        Gradient g;
        Check k;
        const Measurement m = measure(
            ctx.budget,
            [&] {
              g = gradient(ctx.device, scene, target, o);
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
