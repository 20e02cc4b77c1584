// accuracy_bench.cpp — speed against error: every scene of the suite (synthetic: smooth blob,
// sharp shell, Marschner–Lobb; real: headsq, neghip, tooth, C60, MNI152) × every integrator ×
// a range of steps; for each, the error against a float64 render at a fine step (relative RMS and
// relative max), the kernel time (median of repeats) and the samples taken. Also, per scene and
// integrator, the time at a relative RMS error of 1e-3 (log-log interpolation between steps).
// Prints JSON; --csv writes the rows as CSV; bench/plot_accuracy.py draws the Pareto plot.
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bench_support.hpp"
#include "ivr/core.hpp"

using ivr::bench::median;
using nlohmann::json;

namespace {

// σ = 0 below density 0.1, then two ramps; colours change along them.
const char* kTf = R"({"type": "piecewise_linear", "points": [
    {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
    {"density": 0.1, "color": [0.2, 0.4, 1.0], "extinction": 0},
    {"density": 0.4, "color": [1.0, 0.7, 0.3], "extinction": 25},
    {"density": 1.0, "color": [1.0, 1.0, 0.9], "extinction": 60}]})";

ivr::Scene scene_with(const std::string& volume_json, int image) {
  ivr::Scene s = ivr::parse_scene(R"({"volume": )" + volume_json + R"(, "model":
      "emission_absorption", "tf": )" +
                                      kTf + R"(, "cameras": [{"eye": [1.2, 0.7, 1.5]},
      {"eye": [-1.6, 0.3, -0.4]}], "integrator": {"min_transmittance": 0}})",
                                  ".");
  for (ivr::Camera& c : s.cameras) c.width = c.height = image;
  return s;
}

// Synthetic volumes by formula over [-1, 1]³ (n³ voxels).
ivr::Volume formula_volume(int n, double (*f)(double, double, double)) {
  ivr::Volume v;
  v.nx = v.ny = v.nz = n;
  v.data.resize(std::size_t(n) * n * n);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        auto c = [&](int i) { return 2.0 * (i + 0.5) / n - 1.0; };
        v.data[(std::size_t(z) * n + y) * n + x] = float(f(c(x), c(y), c(z)));
      }
  return v;
}

double smooth_blob(double x, double y, double z) {
  return 0.8 * std::exp(-3.0 * (x * x + 1.5 * y * y + 0.7 * z * z));
}
double sharp_shell(double x, double y, double z) {
  const double r = std::sqrt(x * x + y * y + z * z);
  return r > 0.55 && r < 0.62 ? 0.9 : 0.0;  // a shell about two voxels thick at 64³
}

struct Integrator {
  std::string name;
  ivr::EmptySpace empty_space;
};

// Relative RMS and relative max of a against the reference r.
std::pair<double, double> relative_error(const std::vector<float>& a, const std::vector<float>& r) {
  double d2 = 0, r2 = 0, dmax = 0, rmax = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = double(a[i]) - double(r[i]);
    d2 += d * d, r2 += double(r[i]) * r[i];
    dmax = std::max(dmax, std::abs(d)), rmax = std::max(rmax, std::abs(double(r[i])));
  }
  return {std::sqrt(d2 / std::max(r2, 1e-300)), dmax / std::max(rmax, 1e-300)};
}

// The time at which the (time, error) curve reaches `target`, interpolated log-log between the
// two steps around it; NaN when no step reaches it.
double time_at(const std::vector<std::pair<double, double>>& time_error, double target) {
  for (std::size_t i = 0; i < time_error.size(); ++i) {
    if (time_error[i].second > target) continue;
    if (i == 0) return time_error[0].first;
    const auto [t0, e0] = time_error[i - 1];
    const auto [t1, e1] = time_error[i];
    const double w = (std::log(target) - std::log(e0)) / (std::log(e1) - std::log(e0));
    return std::exp(std::log(t0) + w * (std::log(t1) - std::log(t0)));
  }
  return NAN;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr speed-against-error benchmark"};
  std::string device_sel, out_path, csv_path, data = "../shared/data";
  int repeats = 3, image = 128;
  double ref_step = 1.0 / 32, target = 1e-3;
  bool quick = false;
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--data", data, "Folder of the shared real volumes");
  app.add_option("--repeats", repeats, "Timed runs per point (median)")->check(CLI::Range(1, 100));
  app.add_option("--image", image, "Image edge in pixels (two views)")->check(CLI::Range(8, 4096));
  app.add_option("--reference-step", ref_step, "Step of the float64 reference (voxels)")
      ->check(CLI::Range(1e-3, 1.0));
  app.add_option("--target", target, "Relative RMS error for the time-at-error summary");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  app.add_option("--csv", csv_path, "Write the rows as CSV here");
  app.add_flag("--quick", quick, "Synthetic scenes only, three steps");
  CLI11_PARSE(app, argc, argv);

  try {
    ivr::Device device(device_sel);
    std::vector<std::pair<std::string, ivr::Scene>> scenes;
    auto synthetic = [&](const char* name, ivr::Volume v) {
      ivr::Scene s = scene_with(R"({"synthetic": "sphere", "dims": [2, 2, 2]})", image);
      s.volume = std::move(v);
      ivr::set_default_box(s);
      scenes.emplace_back(name, s);
    };
    synthetic("smooth_blob", formula_volume(64, smooth_blob));
    synthetic("sharp_shell", formula_volume(64, sharp_shell));
    synthetic("marschner_lobb", ivr::synthetic_volume("marschner_lobb", 64, 64, 64));
    const std::pair<const char*, std::string> real[] = {
        {"headsq", R"({"file": "headsq_64x64x93_int16le.raw", "dims": [64, 64, 93],
            "type": "int16", "endian": "little", "range": [0, 4095], "spacing": [3.2, 3.2, 1.5]})"},
        {"neghip",
         R"({"file": "neghip_64x64x64_uint8.raw", "dims": [64, 64, 64], "type": "uint8"})"},
        {"tooth",
         R"({"file": "tooth_103x94x161_uint8.raw", "dims": [103, 94, 161], "type": "uint8"})"},
        {"c60", R"({"file": "C60Large_128x128x128_uint8.cvol"})"},
        {"mni152", R"({"file": "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz"})"}};
    for (const auto& [name, volume] : real) {
      if (quick) break;
      json v = json::parse(volume);
      const std::string path = data + "/" + v["file"].get<std::string>();
      if (!std::filesystem::exists(path)) {
        std::cerr << "skipping " << name << ": no " << path << "\n";
        continue;
      }
      v["file"] = std::filesystem::absolute(path).string();
      scenes.emplace_back(name, scene_with(v.dump(), image));
    }
    const std::vector<Integrator> integrators = {{"midpoint", ivr::EmptySpace::off},
                                                 {"midpoint+skip", ivr::EmptySpace::on}};
    const std::vector<double> steps =
        quick ? std::vector<double>{1, 0.5, 0.25} : std::vector<double>{2, 1, 0.5, 0.25, 0.125};

    json rows = json::array(), summary = json::array();
    for (const auto& [name, scene] : scenes) {
      const std::vector<float> reference =
          ivr::render(device, scene, {ivr::Precision::f64, ref_step, ivr::EmptySpace::off}).pixels;
      for (const Integrator& integ : integrators) {
        std::vector<std::pair<double, double>> curve;
        for (double step : steps) {
          ivr::RenderOptions o{ivr::Precision::f32, step, integ.empty_space};
          ivr::RenderStats stats;
          ivr::Image img = ivr::render(device, scene, o, &stats);  // warm-up, compiles
          std::vector<double> kernel;
          for (int r = 0; r < repeats; ++r) {
            img = ivr::render(device, scene, o, &stats);
            kernel.push_back(stats.kernel_seconds + stats.grid_seconds);
          }
          const auto [rms, max] = relative_error(img.pixels, reference);
          const double ms = 1e3 * median(kernel);
          curve.emplace_back(ms, rms);
          rows.push_back({{"scene", name},
                          {"integrator", integ.name},
                          {"step", step},
                          {"relative_rms", rms},
                          {"relative_max", max},
                          {"ms", ms},
                          {"samples", stats.samples}});
          std::cerr << name << " " << integ.name << " step " << step << ": rel RMS " << rms
                    << ", rel max " << max << ", " << ms << " ms\n";
        }
        summary.push_back({{"scene", name},
                           {"integrator", integ.name},
                           {"target_relative_rms", target},
                           {"ms_at_target", time_at(curve, target)}});
      }
    }
    const json result = {{"benchmark", "accuracy"},
                         {"ivr_version", IVR_VERSION_STRING},
                         {"device", device.info().name},
                         {"image", image},
                         {"views", 2},
                         {"reference", {{"precision", "f64"}, {"step", ref_step}}},
                         {"time", "median kernel (+ grid) ms over repeats"},
                         {"repeats", repeats},
                         {"rows", rows},
                         {"time_at_target", summary}};
    std::cout << result.dump(2) << "\n";
    if (!out_path.empty()) std::ofstream(out_path) << result.dump(2) << "\n";
    if (!csv_path.empty()) {
      std::ofstream csv(csv_path);
      csv << "scene,integrator,step,relative_rms,relative_max,ms,samples\n";
      for (const json& r : rows)
        csv << r["scene"].get<std::string>() << "," << r["integrator"].get<std::string>() << ","
            << r["step"] << "," << r["relative_rms"] << "," << r["relative_max"] << "," << r["ms"]
            << "," << r["samples"] << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
