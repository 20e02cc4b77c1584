// render_bench.cpp — forward-render benchmark: ivr vs the native C++/OpenMP marcher on the same
// scenes (128³/256³ volumes, 256²/512² images, steps 0.5/0.25), medians of repeated runs, speed
// next to the error against a fine-step float64 reference. Prints one JSON document.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bench_scene.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"
#include "reference/native_marcher.hpp"

using nlohmann::json;

namespace {

using ivr::bench::median;
using ivr::bench::wall_seconds;

// RMS and max of |a - b| over the colour channels (alpha is compared too).
json compare(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0, worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = std::abs(double(a[i]) - double(b[i]));
    sum += d * d;
    worst = std::max(worst, d);
  }
  return {{"rms", std::sqrt(sum / double(a.size()))}, {"max", worst}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr forward-render benchmark against the native C++/OpenMP marcher"};
  std::string device_sel, out_path;
  int repeats = 5;
  double ref_step = 1.0 / 16;
  bool quick = false;
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--repeats", repeats, "Timed runs per configuration (median reported)")
      ->check(CLI::Range(1, 100));
  app.add_option("--reference-step", ref_step,
                 "Step of the float64 reference in voxels (0: skip the error)");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  app.add_flag("--quick", quick, "Only the 128³ volume and 256² image");
  CLI11_PARSE(app, argc, argv);

  try {
    ivr::Device device(device_sel);
    json configs = json::array();
    std::vector<double> kernel_ratios, total_ratios;
    for (int n : quick ? std::vector<int>{128} : std::vector<int>{128, 256}) {
      for (int image : quick ? std::vector<int>{256} : std::vector<int>{256, 512}) {
        const ivr::Scene scene = ivr::bench::bench_scene(n, image);
        std::vector<float> reference;
        if (ref_step > 0) {
          ivr::RenderOptions ro{ivr::Precision::f64, ref_step};
          reference = ivr::render(device, scene, ro).pixels;
        }
        for (double step : {0.5, 0.25}) {
          ivr::RenderOptions options{ivr::Precision::f32, step};
          ivr::RenderStats stats;
          ivr::Image img = ivr::render(device, scene, options, &stats);  // warm-up, compiles
          std::vector<float> native;
          std::size_t native_samples = ivr::bench::native_render(scene, step, native);  // warm-up
          // Interleaved, so that a burst of load from elsewhere on this shared machine hits both.
          std::vector<double> kernel_s, total_s, native_s;
          for (int r = 0; r < repeats; ++r) {
            total_s.push_back(
                wall_seconds([&] { img = ivr::render(device, scene, options, &stats); }));
            kernel_s.push_back(stats.kernel_seconds);
            native_s.push_back(wall_seconds(
                [&] { native_samples = ivr::bench::native_render(scene, step, native); }));
          }
          const double k = median(kernel_s), t = median(total_s), nat = median(native_s);
          json c = {{"volume", n},
                    {"image", image},
                    {"step", step},
                    {"samples", stats.samples},
                    {"native_samples", native_samples},
                    {"ivr",
                     {{"kernel_ms", 1e3 * k},
                      {"total_ms", 1e3 * t},
                      {"samples_per_s", stats.samples / k}}},
                    {"native", {{"ms", 1e3 * nat}, {"samples_per_s", native_samples / nat}}},
                    {"speed_ratio_kernel", nat / k},
                    {"speed_ratio_total", nat / t},
                    {"ivr_vs_native", compare(img.pixels, native)}};
          if (!reference.empty())
            c["error_vs_reference"] = {{"ivr", compare(img.pixels, reference)},
                                       {"native", compare(native, reference)},
                                       {"reference_step", ref_step}};
          kernel_ratios.push_back(nat / k);
          total_ratios.push_back(nat / t);
          std::cerr << "volume " << n << "³ image " << image << "² step " << step << ": ivr "
                    << 1e3 * k << " ms (kernel), " << 1e3 * t << " ms (total); native " << 1e3 * nat
                    << " ms; ratio " << nat / k << "\n";
          configs.push_back(c);
        }
      }
    }
    auto geomean = [](const std::vector<double>& v) {
      double s = 0;
      for (double x : v) s += std::log(x);
      return std::exp(s / double(v.size()));
    };
    const json result = {
        {"benchmark", "render"},
        {"ivr_version", IVR_VERSION_STRING},
        {"device", device.info().name},
        {"platform", device.info().platform},
        {"repeats", repeats},
        {"statistic", "median"},
        {"configs", configs},
        {"geomean_speed_ratio_kernel", geomean(kernel_ratios)},
        {"geomean_speed_ratio_total", geomean(total_ratios)},
        {"min_speed_ratio_kernel", *std::min_element(kernel_ratios.begin(), kernel_ratios.end())}};
    ivr::bench::emit_json(result, out_path);
  } catch (const ivr::Error& e) {
    std::cerr << "ivr_render_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
