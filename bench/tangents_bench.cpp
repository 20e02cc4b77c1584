// tangents_bench.cpp — forward against adjoint mode by parameter count: for P = 1, 2, 4, ...,
// max voxel parameters of a 128³ volume into a 256² image, the kernel time of forward mode
// (ceil(P / 32) passes), of the adjoint (every voxel at once), and of --mode auto (the planner's
// choice from this device's calibration, made first); the crossover P; and the two targets of
// issue 4: auto within 1.25x of the faster mode at every P, forward with P lanes at most
// (1 + 0.5 P) renders up to P = 32. Prints one JSON document (plot: bench/plot_tangents.py).
#include <CLI/CLI.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "bench_scene.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"

using ivr::bench::median;
using nlohmann::json;

namespace {

constexpr double kAutoTarget = 1.25;

// P distinct voxels drawn with a fixed seed from the volume's middle half (where rays see them).
std::string voxel_list(const ivr::Scene& scene, int p) {
  const ivr::Volume& v = scene.volume;
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> x(v.nx / 4, 3 * v.nx / 4), y(v.ny / 4, 3 * v.ny / 4),
      z(v.nz / 4, 3 * v.nz / 4);
  std::vector<std::int64_t> picked;
  while (picked.size() < std::size_t(p)) {
    const std::int64_t i = (std::int64_t(z(rng)) * v.ny + y(rng)) * v.nx + x(rng);
    if (std::find(picked.begin(), picked.end(), i) == picked.end()) picked.push_back(i);
  }
  std::string list = "voxels:";
  for (std::size_t k = 0; k < picked.size(); ++k)
    list += (k ? "," : "") + std::to_string(picked[k]);
  return list;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr forward/adjoint crossover benchmark"};
  std::string device_sel, out_path;
  int volume = 128, image = 256, repeats = 3, max_p = 256;
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--volume", volume, "Volume edge (default 128)");
  app.add_option("--image", image, "Image edge (default 256)");
  app.add_option("--repeats", repeats, "Timed runs per measurement (median reported)");
  app.add_option("--max-p", max_p, "Largest parameter count (powers of two up to it)");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  CLI11_PARSE(app, argc, argv);

  try {
    ivr::Device device(device_sel);
    // This device's cost model, measured now and used by --mode auto below.
    const ivr::Calibration calibration = ivr::calibrate(device);
    const std::string model_path =
        (std::filesystem::temp_directory_path() / "ivr_tangents_bench_cost.json").string();
    ivr::save_cost_model(model_path, calibration.model, device.info());
    ::setenv("IVR_COST_MODEL", model_path.c_str(), 1);

    const ivr::Scene scene = ivr::bench::bench_scene(volume, image);
    const ivr::Image target = ivr::bench::perturbed_target(device, scene, 0);
    ivr::GradientOptions forward, adjoint, automatic;
    forward.mode = ivr::Mode::forward;
    adjoint.mode = ivr::Mode::adjoint;

    // Render and adjoint (independent of P), interleaved; one warm-up round compiles.
    std::vector<double> render_s, adjoint_s;
    const std::string one = voxel_list(scene, 1);
    for (int r = 0; r <= repeats; ++r) {
      ivr::RenderStats st;
      ivr::render(device, scene, {ivr::Precision::f32}, &st);
      const auto a = ivr::gradient(device, scene, target, {one}, adjoint);
      if (r > 0) {
        render_s.push_back(st.kernel_seconds);
        adjoint_s.push_back(a.kernel_seconds);
      }
    }
    const double render_ms = 1e3 * median(render_s), adjoint_ms = 1e3 * median(adjoint_s);

    json rows = json::array();
    bool auto_ok = true, lanes_ok = true;
    int crossover = 0;
    double worst_auto = 0, worst_lanes = 0;
    for (int p = 1; p <= max_p; p *= 2) {
      const std::string group = voxel_list(scene, p);
      std::vector<double> f_s, auto_s;
      ivr::Mode chosen = ivr::Mode::automatic;
      ivr::Plan plan;
      for (int r = 0; r <= repeats; ++r) {
        const auto f = ivr::gradient(device, scene, target, {group}, forward);
        const auto a = ivr::gradient(device, scene, target, {group}, automatic);
        chosen = a.plan.mode;
        plan = a.plan;
        if (r > 0) {
          f_s.push_back(f.kernel_seconds);
          auto_s.push_back(a.kernel_seconds);
        }
      }
      const double forward_ms = 1e3 * median(f_s), auto_ms = 1e3 * median(auto_s);
      const double faster = std::min(forward_ms, adjoint_ms);
      const double auto_ratio = auto_ms / faster;
      worst_auto = std::max(worst_auto, auto_ratio);
      auto_ok = auto_ok && auto_ratio <= kAutoTarget;
      if (crossover == 0 && adjoint_ms < forward_ms) crossover = p;
      json row = {{"parameters", p},
                  {"forward_ms", forward_ms},
                  {"adjoint_ms", adjoint_ms},
                  {"auto_mode", ivr::mode_name(chosen)},
                  {"auto_ms", auto_ms},
                  {"auto_over_faster", auto_ratio},
                  {"predicted_forward_ms", 1e3 * plan.forward_seconds},
                  {"predicted_adjoint_ms", 1e3 * plan.adjoint_seconds},
                  {"forward_over_render", forward_ms / render_ms}};
      if (p <= 32) {
        const double limit = 1 + 0.5 * p, ratio = forward_ms / render_ms;
        row["forward_limit_renders"] = limit;
        worst_lanes = std::max(worst_lanes, ratio / limit);
        lanes_ok = lanes_ok && ratio <= limit;
      }
      rows.push_back(row);
      std::cerr << "P " << p << ": forward " << forward_ms << " ms, adjoint " << adjoint_ms
                << " ms, auto " << ivr::mode_name(chosen) << " " << auto_ms << " ms\n";
    }
    const json doc = {
        {"benchmark", "tangents"},
        {"device", device.info().name},
        {"platform", device.info().platform},
        {"ivr_version", IVR_VERSION_STRING},
        {"volume", volume},
        {"image", image},
        {"repeats", repeats},
        {"statistic", "median kernel time"},
        {"parameters_kind", "voxel densities (voxels:LIST), drawn from the volume's middle"},
        {"render_ms", render_ms},
        {"adjoint_ms", adjoint_ms},
        {"cost_model",
         {{"forward_base", calibration.model.forward_base},
          {"forward_per_lane", calibration.model.forward_per_lane},
          {"adjoint", calibration.model.adjoint},
          {"seconds_per_sample", calibration.model.seconds_per_sample}}},
        {"crossover_parameters", crossover},
        {"rows", rows},
        {"targets",
         {{"auto_within_1.25x_of_faster", {{"pass", auto_ok}, {"worst", worst_auto}}},
          {"forward_at_most_1_plus_half_P_renders",
           {{"pass", lanes_ok}, {"worst_ratio_to_limit", worst_lanes}}}}}};
    ivr::bench::emit_json(doc, out_path);
  } catch (const std::exception& e) {
    std::cerr << "ivr_tangents_bench: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
