// integrators.cpp — the integrators suite: speed against error for every integrator (midpoint,
// trapezoid, pre-integrated; exact for absorption), each with and without empty-space skipping,
// over a range of steps, on every scene of the accuracy suite (bench/accuracy_suite.hpp: the
// synthetic volumes and the shared real ones; the quick run: Marschner–Lobb) under a smooth TF, a
// narrow-band TF and the absorption model. The error is against the float64 continuous integral
// (reference/); before timing, midpoint is checked against the reference's same-step midpoint rule
// and pre-integration against its same-step linear-segment definition, the others for a bounded
// error (skipping changes none of these). Per scene: each integrator's time at a relative error of
// 1e-3 (the best against midpoint's), the exact scheme's error in float64 too, and the tolerance
// section (the step choose_step picks for 1e-2, 1e-3, 1e-4, checked to meet it, beside the largest
// step that would have). bench/plot_accuracy.py draws the Pareto plots, bench/accuracy_tables.py
// prints the tables.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <sstream>

#include "../accuracy_suite.hpp"
#include "../runner/suite.hpp"
#include "reference/reference.hpp"

namespace ivr::bench {

namespace {

// Same-step checks, float32 against float64: relative L2 over the image. Not the largest pixel
// error: a ray whose float32 length rounds to one sample more or fewer than in float64 samples
// half a step elsewhere, which under a narrow-band TF changes that pixel by up to ~1e-2.
constexpr double kSameStep = 1e-3;
// Trapezoid has no same-step definition in the reference: its image must be the scene's (relative
// L2 against the continuous integral below 1/2; a wrong image is off by order 1), and its error is
// what the suite reports.
constexpr double kSanity = 0.5;
// The relative error at which the integrators' times are compared.
constexpr double kTargetError = 1e-3;

std::string step_text(double s) {
  std::string t = std::to_string(s);
  while (t.size() > 1 && t.back() == '0') t.pop_back();
  if (t.back() == '.') t.pop_back();  // "1", not "1."
  return t;
}

// An integrator as the suite runs it: a scheme, with or without empty-space skipping. `name` is the
// plots' label ("midpoint+skip"), `key` the case and metric names' ("midpoint_skip").
struct IntegratorRun {
  std::string name, key;
  Scheme scheme;
  EmptySpace empty_space;
};

std::vector<IntegratorRun> integrators_for(Model model) {
  std::vector<IntegratorRun> out;
  for (Scheme s : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact}) {
    if (s == Scheme::exact && model != Model::absorption) continue;
    const std::string name = scheme_name(s);
    out.push_back({name, name, s, EmptySpace::off});
    out.push_back({name + "+skip", name + "_skip", s, EmptySpace::on});
  }
  return out;
}

// The check made before timing an integrator's image: midpoint against the reference's midpoint
// rule and pre-integration against its linear segments at the same step (`step` in world units),
// exact against the continuous integral; trapezoid only for a bounded error.
Check same_step_check(const Scene& scene, const Image& img, const std::vector<double>& truth,
                      double step) {
  switch (scene.integrator.scheme) {
    case Scheme::midpoint:
      return check_l2(difference(img.pixels, reference::render_midpoint(scene, step)),
                      "reference f64 midpoint, same step", kSameStep);
    case Scheme::preintegrated:
      return check_l2(difference(img.pixels, reference::render_linear_segments(scene, step)),
                      "reference f64 linear segments, same step", kSameStep);
    case Scheme::exact:
      return check_l2(difference(img.pixels, truth), "reference f64 continuous integral",
                      kSameStep);
    default:
      return check_l2(difference(img.pixels, truth), "reference f64 continuous integral", kSanity);
  }
}

// The tolerance section: the step choose_step picks for a tolerance, the error it gives, and the
// largest step that would have met it (a 1.25× ladder, then bisection). Checked: the error of the
// chosen step is within the tolerance.
void tolerance_case(Context& ctx, const Budget& budget, const Scene& base,
                    const std::vector<double>& truth, const std::string& scene_name,
                    const nlohmann::json& params, Scheme scheme, double tolerance) {
  Scene scene = base;
  scene.integrator.scheme = scheme;
  StepChoice c;
  const Measurement m = measure(budget, [&] {
    c = choose_step(ctx.device, scene, tolerance);
    return -1.0;
  });
  const auto error_at = [&](double step) {
    return difference(render(ctx.device, scene, {Precision::f32, step}).pixels, truth).relative_l2;
  };
  const double error = error_at(c.step);
  double good = c.step, bad = NAN;
  if (error <= tolerance) {
    while (good < 4 * kToleranceMaxStep) {
      if (error_at(good * 1.25) > tolerance) {
        bad = good * 1.25;
        break;
      }
      good *= 1.25;
    }
    for (int i = 0; std::isfinite(bad) && i < 4; ++i) {
      const double mid = std::sqrt(good * bad);
      (error_at(mid) <= tolerance ? good : bad) = mid;
    }
  }
  std::ostringstream name;
  name << scene_name << "_" << scheme_name(scheme) << "_tolerance_" << tolerance;
  nlohmann::json p = params;
  p["scheme"] = scheme_name(scheme);
  p["tolerance"] = tolerance;
  Record r{ctx.device_key, "integrators", name.str(), "ivr", p};
  add_timing(r, m);  // the time choosing takes (its pilot renders)
  r.metrics["chosen_step"] = c.step;
  r.metrics["estimated_error"] = c.estimated_error;
  r.metrics["pilots"] = c.pilots;
  if (error <= tolerance) {
    r.metrics["needed_step"] = good;
    r.metrics["needed_over_chosen"] = good / c.step;
  }
  record_checked(
      ctx, std::move(r),
      {error <= tolerance, "reference f64 continuous integral", "relative_l2", error, tolerance});
}

}  // namespace

void integrators_suite(Context& ctx) {
  // Two views of 128² (as the earlier accuracy program measured; 32² in the quick run).
  const int image = ctx.quick ? 32 : 128;
  const std::vector<double> steps =
      ctx.quick ? std::vector<double>{1, 0.5} : std::vector<double>{2, 1, 0.5, 0.25, 0.125, 0.0625};
  std::vector<SuiteVolume> volumes;
  for (SuiteVolume& v : suite_volumes(ctx.data_dir, ctx.quick))
    if (!ctx.quick || v.name == "marschner_lobb") volumes.push_back(std::move(v));
  std::vector<SuiteLook> looks;
  for (const SuiteLook& l : suite_looks())
    if (!ctx.quick || l.name != "band") looks.push_back(l);
  // The full run has ~1,000 points (8 volumes × 3 looks × 7–8 integrators × 6 steps): each is timed
  // for at most half a second (at least min_runs runs), or the suite alone would take half an hour.
  Budget budget = ctx.budget;
  budget.seconds = std::min(budget.seconds, 0.5);

  // The references depend on the scene only: once per run.
  static std::map<std::string, std::vector<double>> continuous;
  for (const SuiteLook& look : looks)
    for (const SuiteVolume& volume : volumes) {
      const Scene base = suite_scene(volume, look, image);
      const std::string scene_name = volume.name + "_" + look.name;
      const std::string key = scene_name + "_" + std::to_string(image);
      if (!continuous.count(key)) {
        std::cerr << "ivr-bench: integrators/" << scene_name << ": continuous reference...\n";
        continuous[key] = reference::render_continuous(base);
      }
      const std::vector<double>& truth = continuous[key];
      const double h = reference::min_voxel_edge(base);
      const nlohmann::json scene_params = {{"volume", volume.name},
                                           {"look", look.name},
                                           {"image", image},
                                           {"views", base.cameras.size()},
                                           {"empty_share", volume.empty}};
      std::map<std::string, std::vector<std::pair<double, double>>> curves;  // (s, error)
      for (const IntegratorRun& integ : integrators_for(look.model)) {
        const Scheme scheme = integ.scheme;
        for (double step : steps) {
          if (scheme == Scheme::exact && step != steps.front()) continue;  // no step to vary
          Scene scene = base;
          scene.integrator.scheme = scheme;
          const RenderOptions options{Precision::f32, step, integ.empty_space};
          RenderStats stats;
          Image img;
          Check k;
          const Measurement m = measure(
              budget,
              [&] {
                img = render(ctx.device, scene, options, &stats);
                return stats.kernel_seconds + stats.grid_seconds;
              },
              [&] { return (k = same_step_check(scene, img, truth, step * h)).passed; });
          nlohmann::json params = scene_params;
          params["integrator"] = integ.name;
          params["scheme"] = scheme_name(scheme);
          params["empty_space"] = integ.empty_space == EmptySpace::on ? "on" : "off";
          params["step"] = scheme == Scheme::exact ? 0.0 : step;
          Record r{ctx.device_key, "integrators",
                   scene_name + "_" + integ.key +
                       (scheme == Scheme::exact ? "" : "_s" + step_text(step)),
                   "ivr", params};
          add_timing(r, m);
          r.metrics["samples"] = stats.samples;
          r.metrics["samples_per_s"] = double(stats.samples) / m.wall.median;
          r.metrics["skipped_empty"] = stats.skipped_empty;
          const Difference e = difference(img.pixels, truth);
          r.metrics["error_relative_l2"] = e.relative_l2;
          r.metrics["error_relative_max"] = e.ref_max > 0 ? e.max_abs / e.ref_max : e.max_abs;
          if (m.timed)
            curves[integ.key].emplace_back(m.device ? m.device->median : m.wall.median,
                                           e.relative_l2);
          if (scheme == Scheme::exact) {  // float64 too (the step changes nothing)
            const RenderOptions o64{Precision::f64, step, integ.empty_space};
            const Difference e64 = difference(render(ctx.device, scene, o64).pixels_f64, truth);
            r.metrics["error_relative_l2_f64"] = e64.relative_l2;
            r.metrics["error_relative_max_f64"] =
                e64.ref_max > 0 ? e64.max_abs / e64.ref_max : e64.max_abs;
          }
          record_checked(ctx, std::move(r), k);
        }
      }
      // Speed against error as one number per integrator: its time at a relative error of
      // kTargetError (log-log between the steps around it), and the best against midpoint's.
      {
        Record r{ctx.device_key, "integrators", scene_name + "_time_at_target", "ivr",
                 scene_params};
        r.params["target_relative_l2"] = kTargetError;
        double best = NAN;
        for (const auto& [name, curve] : curves) {
          const double t = time_at(curve, kTargetError);
          if (std::isfinite(t)) {
            r.metrics[name + "_s_at_target"] = t;
            if (!(t >= best)) best = t;
          }
        }
        if (std::isfinite(best)) r.metrics["best_s_at_target"] = best;
        if (r.metrics.contains("midpoint_s_at_target") && std::isfinite(best))
          r.metrics["midpoint_over_best"] = r.metrics["midpoint_s_at_target"].get<double>() / best;
        ctx.results.add(std::move(r));
      }
      for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated})
        for (double tolerance :
             ctx.quick ? std::vector<double>{1e-2} : std::vector<double>{1e-2, 1e-3, 1e-4})
          tolerance_case(ctx, budget, base, truth, scene_name, scene_params, scheme, tolerance);
    }
}

}  // namespace ivr::bench
