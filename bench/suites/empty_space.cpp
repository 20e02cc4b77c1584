// empty_space.cpp — the empty-space suite: render and density-gradient time with empty-space
// skipping on (implementation "ivr") against off ("ivr-no-skipping"), on the real volumes with
// large empty regions (neghip, MNI152) and on the benchmark scene (Marschner–Lobb: no empty
// bricks, what automatic skipping costs there), for every integrator (exact: the scenes under the
// absorption model). Checked before timing: the image with skipping equals the image without to
// 1e-5, the density gradient to 1e-4 of its largest entry (skipping leaves both exact).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

namespace {

// σ = 0 below density 0.1, rising to 40 at 0.5: the usual way empty space is made; two views.
Scene real_scene(const std::string& volume_json, int image) {
  Scene s = parse_scene(R"({"volume": )" + volume_json + R"(, "model": "emission_absorption",
      "tf": {"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
        {"density": 0.1, "color": [0.2, 0.4, 1.0], "extinction": 0},
        {"density": 0.5, "color": [1.0, 0.7, 0.3], "extinction": 40}]},
      "cameras": [{"eye": [1.2, 0.7, 1.5]}, {"eye": [-1.6, 0.3, -0.4]}]})",
                        ".");
  for (Camera& c : s.cameras) c.width = c.height = image;
  return s;
}

struct SkipCase {
  std::string name;
  Scene scene;
};

std::vector<SkipCase> skip_cases(const Context& ctx, int image) {
  std::vector<SkipCase> cases;
  const std::string neghip = ctx.data_dir + "/neghip_64x64x64_uint8.raw";
  const std::string mni = ctx.data_dir + "/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz";
  if (std::filesystem::exists(neghip))
    cases.push_back({"neghip", real_scene(R"({"file": ")" + neghip +
                                              R"(", "dims": [64, 64, 64], "type": "uint8"})",
                                          image)});
  if (!ctx.quick && std::filesystem::exists(mni))
    cases.push_back({"mni152", real_scene(R"({"file": ")" + mni + R"("})", image)});
  const int n = ctx.quick ? 64 : 128;
  cases.push_back({"marschner_lobb_" + std::to_string(n), bench_scene(n, image)});
  return cases;
}

double largest(const std::vector<float>& v) {
  double m = 0;
  for (float x : v) m = std::max(m, double(std::abs(x)));
  return m;
}

// The renders of one case and step, off then on.
void render_pair(Context& ctx, const SkipCase& c, const std::string& case_name,
                 const nlohmann::json& params, double step) {
  RenderOptions off{Precision::f32, step}, on = off;
  off.empty_space = EmptySpace::off;
  on.empty_space = EmptySpace::on;
  RenderStats s_off, s_on;
  Image i_off, i_on;
  Check check;
  const Measurement m_off = measure(ctx.budget, [&] {
    i_off = render(ctx.device, c.scene, off, &s_off);
    return s_off.kernel_seconds;
  });
  Record r_off{ctx.device_key, "empty_space", case_name, "ivr-no-skipping", params};
  add_timing(r_off, m_off);
  r_off.metrics["samples"] = s_off.samples;
  ctx.results.add(std::move(r_off));

  const Measurement m_on = measure(
      ctx.budget,
      [&] {
        i_on = render(ctx.device, c.scene, on, &s_on);
        return s_on.kernel_seconds;
      },
      [&] {
        check = check_max(difference(i_on.pixels, widen(i_off.pixels)), "ivr without skipping",
                          1e-5, 0);
        return check.passed;
      });
  Record r{ctx.device_key, "empty_space", case_name, "ivr", params};
  add_timing(r, m_on);
  r.metrics["empty_fraction"] = s_on.empty_fraction;
  r.metrics["grid_s"] = s_on.grid_seconds;
  r.metrics["samples"] = s_on.samples;
  r.metrics["samples_ratio"] = s_off.samples > 0 ? double(s_on.samples) / s_off.samples : 0.0;
  if (m_on.timed && m_off.wall.median > 0) {
    r.metrics["speedup_vs_no_skipping"] = m_off.wall.median / m_on.wall.median;
    if (m_on.device && m_off.device && m_on.device->median > 0)
      r.metrics["kernel_speedup_vs_no_skipping"] = m_off.device->median / m_on.device->median;
  }
  record_checked(ctx, std::move(r), check);
}

// The density gradient (adjoint, d mse / d density) of one case, off then on, at step 0.5.
void gradient_pair(Context& ctx, const SkipCase& c, const std::string& case_name,
                   const nlohmann::json& params) {
  const Image target = perturbed_target(ctx.device, c.scene, 0.5);
  AdjointOptions off, on;
  off.step = on.step = 0.5;
  off.empty_space = EmptySpace::off;
  on.empty_space = EmptySpace::on;
  AdjointGradient g_off, g_on;
  const Measurement m_off = measure(ctx.budget, [&] {
    g_off = adjoint(ctx.device, c.scene, target, off);
    return g_off.kernel_seconds;
  });
  Record r_off{ctx.device_key, "empty_space", case_name, "ivr-no-skipping", params};
  add_timing(r_off, m_off);
  ctx.results.add(std::move(r_off));
  Check check;
  const Measurement m_on = measure(
      ctx.budget,
      [&] {
        g_on = adjoint(ctx.device, c.scene, target, on);
        return g_on.kernel_seconds;
      },
      [&] {
        // The largest difference relative to the largest entry (skipping leaves it exact).
        const double d = difference(g_on.density, widen(g_off.density)).max_abs;
        const double scale = std::max(largest(g_off.density), 1e-30);
        check = {d <= 1e-4 * scale, "ivr without skipping", "max_abs / max", d / scale, 1e-4};
        return check.passed;
      });
  Record r{ctx.device_key, "empty_space", case_name, "ivr", params};
  add_timing(r, m_on);
  r.metrics["skipped"] = g_on.skipped_empty;
  if (m_off.wall.median > 0 && m_on.wall.median > 0)
    r.metrics["speedup_vs_no_skipping"] = m_off.wall.median / m_on.wall.median;
  record_checked(ctx, std::move(r), check);
}

}  // namespace

void empty_space_suite(Context& ctx) {
  const int image = ctx.quick ? 64 : 256;
  const std::vector<Scheme> schemes =
      ctx.quick ? std::vector<Scheme>{Scheme::midpoint, Scheme::exact}
                : std::vector<Scheme>{Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated,
                                      Scheme::exact};
  const std::vector<double> steps =
      ctx.quick ? std::vector<double>{0.5} : std::vector<double>{0.5, 0.25};
  for (SkipCase c : skip_cases(ctx, image))
    for (Scheme scheme : schemes) {
      c.scene.integrator.scheme = scheme;
      c.scene.model = scheme == Scheme::exact ? Model::absorption : Model::emission_absorption;
      const std::string base = c.name + "_" + scheme_name(scheme);
      for (double step : steps) {
        std::ostringstream name;
        name << base << "_s" << step;
        render_pair(ctx, c, name.str(),
                    {{"volume", c.name},
                     {"scheme", scheme_name(scheme)},
                     {"step", step},
                     {"image", image},
                     {"views", 2}},
                    step);
      }
      gradient_pair(ctx, c, base + "_gradient",
                    {{"volume", c.name},
                     {"scheme", scheme_name(scheme)},
                     {"step", 0.5},
                     {"image", image},
                     {"views", 2},
                     {"operation", "density gradient"}});
    }
}

}  // namespace ivr::bench
