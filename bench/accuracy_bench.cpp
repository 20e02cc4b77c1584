// accuracy_bench.cpp — speed against error: every scene of the suite (bench/accuracy_suite.cpp:
// synthetic and real volumes × transfer functions and models) × every integrator (with and
// without empty-space skipping) × a range of steps, each against the independent float64
// continuous integral (reference/: render_continuous): relative RMS and max error, median
// kernel time (plus the grid), samples. Per scene and integrator the time at a relative RMS of
// --target (log-log interpolation between steps) and the best integrator against midpoint; the
// exact scheme in both precisions; and the tolerance section: the step chosen for each tolerance,
// its measured error and the largest step that meets it. Prints JSON; --csv writes the rows;
// bench/plot_accuracy.py draws the Pareto plot.
#include <CLI/CLI.hpp>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accuracy_suite.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"
#include "reference/reference.hpp"

using ivr::bench::median;
using ivr::bench::time_at;
using ivr::bench::wall_seconds;
using nlohmann::json;

namespace {

struct Integrator {
  std::string name;
  ivr::Scheme scheme;
  ivr::EmptySpace empty_space;
};

std::vector<Integrator> integrators_for(ivr::Model model) {
  std::vector<Integrator> out;
  for (ivr::Scheme s : {ivr::Scheme::midpoint, ivr::Scheme::trapezoid, ivr::Scheme::preintegrated,
                        ivr::Scheme::exact}) {
    if (s == ivr::Scheme::exact && model != ivr::Model::absorption) continue;
    out.push_back({ivr::scheme_name(s), s, ivr::EmptySpace::off});
    out.push_back({std::string(ivr::scheme_name(s)) + "+skip", s, ivr::EmptySpace::on});
  }
  return out;
}

std::vector<double> parse_list(const std::string& text) {
  std::vector<double> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) out.push_back(std::stod(item));
  return out;
}

struct Timed {
  ivr::Image image;
  ivr::RenderStats stats;
  double ms = 0;  // median kernel + grid time
};

Timed timed_render(ivr::Device& device, const ivr::Scene& scene, const ivr::RenderOptions& o,
                   int repeats) {
  Timed t;
  t.image = ivr::render(device, scene, o, &t.stats);  // warm-up: compiles, caches
  std::vector<double> ms;
  for (int r = 0; r < repeats; ++r) {
    t.image = ivr::render(device, scene, o, &t.stats);
    ms.push_back(1e3 * (t.stats.kernel_seconds + t.stats.grid_seconds));
  }
  t.ms = median(ms);
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr speed-against-error benchmark"};
  std::string device_sel, out_path, csv_path, data = "../shared/data";
  std::string steps_text = "2,1,0.5,0.25,0.125", tolerances_text = "1e-2,1e-3,1e-4";
  std::string looks_text = "ramps,band,absorption";
  int repeats = 3, image = 128;
  double target = 1e-3;
  bool quick = false, no_tolerance = false;
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--data", data, "Folder of the shared real volumes");
  app.add_option("--repeats", repeats, "Timed runs per point (median)")->check(CLI::Range(1, 100));
  app.add_option("--image", image, "Image edge in pixels (two views)")->check(CLI::Range(8, 4096));
  app.add_option("--steps", steps_text, "Comma-separated steps (voxels)");
  app.add_option("--looks", looks_text, "Comma-separated looks: ramps, band, absorption");
  app.add_option("--tolerances", tolerances_text, "Comma-separated tolerances to choose steps for");
  app.add_flag("--no-tolerance", no_tolerance, "Skip the tolerance section");
  app.add_option("--target", target, "Relative RMS error for the time-at-error summary");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  app.add_option("--csv", csv_path, "Write the rows as CSV here");
  app.add_flag("--quick", quick, "Synthetic volumes only");
  CLI11_PARSE(app, argc, argv);

  try {
    ivr::Device device(device_sel);
    const std::vector<double> steps = parse_list(steps_text);
    const std::vector<double> tolerances = parse_list(tolerances_text);
    std::vector<ivr::bench::SuiteLook> looks;
    for (const ivr::bench::SuiteLook& l : ivr::bench::suite_looks())
      if (("," + looks_text + ",").find("," + l.name + ",") != std::string::npos)
        looks.push_back(l);
    const std::vector<ivr::bench::SuiteVolume> volumes = ivr::bench::suite_volumes(data, quick);

    json rows = json::array(), summary = json::array(), best = json::array(),
         tolerance_rows = json::array(), exact_rows = json::array(), scenes = json::array();
    for (const ivr::bench::SuiteLook& look : looks)
      for (const ivr::bench::SuiteVolume& volume : volumes) {
        const ivr::Scene base = ivr::bench::suite_scene(volume, look, image);
        std::vector<double> reference;
        const double ref_seconds =
            wall_seconds([&] { reference = ivr::reference::render_continuous(base); });
        scenes.push_back({{"volume", volume.name},
                          {"look", look.name},
                          {"dims", {volume.volume.nx, volume.volume.ny, volume.volume.nz}},
                          {"empty_share", volume.empty},
                          {"reference_seconds", ref_seconds}});
        std::cerr << volume.name << " / " << look.name << ": reference " << ref_seconds << " s\n";
        double midpoint_ms = NAN, best_ms = NAN;
        std::string best_name;
        for (const Integrator& integ : integrators_for(look.model)) {
          ivr::Scene scene = base;
          scene.integrator.scheme = integ.scheme;
          std::vector<std::pair<double, double>> curve;
          for (double step : steps) {
            const Timed t = timed_render(device, scene,
                                         {ivr::Precision::f32, step, integ.empty_space}, repeats);
            const ivr::bench::RelativeError e =
                ivr::bench::relative_error(t.image.pixels, reference);
            curve.emplace_back(t.ms, e.rms);
            rows.push_back({{"volume", volume.name},
                            {"look", look.name},
                            {"integrator", integ.name},
                            {"step", step},
                            {"relative_rms", e.rms},
                            {"relative_max", e.max},
                            {"ms", t.ms},
                            {"samples", t.stats.samples},
                            {"skipped", t.stats.skipped_empty}});
            std::cerr << "  " << integ.name << " step " << step << ": rel RMS " << e.rms
                      << ", rel max " << e.max << ", " << t.ms << " ms\n";
            if (integ.scheme == ivr::Scheme::exact && integ.empty_space == ivr::EmptySpace::off) {
              // The exact scheme in float64 too (the step changes nothing).
              ivr::RenderOptions o{ivr::Precision::f64, step, ivr::EmptySpace::off};
              const ivr::bench::RelativeError e64 =
                  ivr::bench::relative_error(ivr::render(device, scene, o).pixels, reference);
              exact_rows.push_back(
                  {{"volume", volume.name},
                   {"step", step},
                   {"f32", {{"relative_rms", e.rms}, {"relative_max", e.max}}},
                   {"f64", {{"relative_rms", e64.rms}, {"relative_max", e64.max}}}});
            }
          }
          const double ms = time_at(curve, target);
          summary.push_back({{"volume", volume.name},
                             {"look", look.name},
                             {"integrator", integ.name},
                             {"target_relative_rms", target},
                             {"ms_at_target", std::isfinite(ms) ? json(ms) : json(nullptr)}});
          if (integ.name == "midpoint") midpoint_ms = ms;
          if (std::isfinite(ms) && !(ms >= best_ms)) best_ms = ms, best_name = integ.name;
        }
        best.push_back({{"volume", volume.name},
                        {"look", look.name},
                        {"best", best_name},
                        {"ms_at_target", std::isfinite(best_ms) ? json(best_ms) : json(nullptr)},
                        {"midpoint_ms_at_target",
                         std::isfinite(midpoint_ms) ? json(midpoint_ms) : json(nullptr)},
                        {"speedup", std::isfinite(best_ms) && std::isfinite(midpoint_ms)
                                        ? json(midpoint_ms / best_ms)
                                        : json(nullptr)}});

        if (no_tolerance) continue;
        for (ivr::Scheme scheme :
             {ivr::Scheme::midpoint, ivr::Scheme::trapezoid, ivr::Scheme::preintegrated})
          for (double tolerance : tolerances) {
            ivr::Scene scene = base;
            scene.integrator.scheme = scheme;
            ivr::StepChoice c;
            const double choose_seconds =
                wall_seconds([&] { c = ivr::choose_step(device, scene, tolerance); });
            const auto error_at = [&](double step) {
              return ivr::bench::relative_error(
                         ivr::render(device, scene, {ivr::Precision::f32, step}).pixels, reference)
                  .rms;
            };
            const double error = error_at(c.step);
            // The step needed: the largest meeting the tolerance (1.25× ladder, then bisection).
            double good = c.step, bad = NAN;
            if (error <= tolerance) {
              while (good < 4 * ivr::kToleranceMaxStep) {
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
            tolerance_rows.push_back(
                {{"volume", volume.name},
                 {"look", look.name},
                 {"scheme", ivr::scheme_name(scheme)},
                 {"tolerance", tolerance},
                 {"step", c.step},
                 {"estimated_error", c.estimated_error},
                 {"measured_error", error},
                 {"below_tolerance", error <= tolerance},
                 {"needed_step", error <= tolerance ? json(good) : json(nullptr)},
                 {"needed_over_chosen", error <= tolerance ? json(good / c.step) : json(nullptr)},
                 {"pilots", c.pilots},
                 {"choose_seconds", choose_seconds}});
            std::cerr << "  tolerance " << tolerance << " " << ivr::scheme_name(scheme) << ": step "
                      << c.step << ", error " << error << ", needed " << good << "\n";
          }
      }
    const json result = {{"benchmark", "accuracy"},
                         {"ivr_version", IVR_VERSION_STRING},
                         {"device", device.info().name},
                         {"image", image},
                         {"views", 2},
                         {"reference", "reference/ render_continuous (float64)"},
                         {"time", "median kernel (+ grid) ms over repeats"},
                         {"repeats", repeats},
                         {"scenes", scenes},
                         {"rows", rows},
                         {"time_at_target", summary},
                         {"best_against_midpoint", best},
                         {"exact", exact_rows},
                         {"tolerance", tolerance_rows}};
    ivr::bench::emit_json(result, out_path);
    if (!csv_path.empty()) {
      std::ofstream csv(csv_path);
      csv << "volume,look,integrator,step,relative_rms,relative_max,ms,samples\n";
      for (const json& r : rows)
        csv << r["volume"].get<std::string>() << "," << r["look"].get<std::string>() << ","
            << r["integrator"].get<std::string>() << "," << r["step"] << "," << r["relative_rms"]
            << "," << r["relative_max"] << "," << r["ms"] << "," << r["samples"] << "\n";
      if (!csv) throw ivr::Error(ivr::Status::io, "cannot write the rows to " + csv_path);
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
