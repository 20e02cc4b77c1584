// empty_space_bench.cpp — empty-space skipping: render time with the skip against without it, on
// the real volumes with large empty regions (neghip 54 % zeros, MNI152 78 %) and on the
// benchmarks' Marschner–Lobb scene (no empty bricks: what automatic costs there), for every
// integrator (exact: the scenes under the absorption model). Medians of
// interleaved repeats, samples, empty-brick fraction, grid build time, and the largest pixel
// difference between the two renders; then the adjoint gradient (d mse / d density) with and
// without skipping. Prints one JSON document.
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench_scene.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"

using ivr::bench::median;
using ivr::bench::wall_seconds;
using nlohmann::json;

namespace {

// σ = 0 below `threshold`, rising to 40 at `threshold + 0.4`: the usual way empty space is made.
const char* kTf = R"({"type": "piecewise_linear", "points": [
    {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
    {"density": %T, "color": [0.2, 0.4, 1.0], "extinction": 0},
    {"density": %U, "color": [1.0, 0.7, 0.3], "extinction": 40}]})";

ivr::Scene real_scene(const std::string& volume_json, double threshold, int image) {
  std::string tf = kTf;
  tf.replace(tf.find("%T"), 2, std::to_string(threshold));
  tf.replace(tf.find("%U"), 2, std::to_string(threshold + 0.4));
  ivr::Scene s = ivr::parse_scene(R"({"volume": )" + volume_json + R"(, "model":
      "emission_absorption", "tf": )" +
                                      tf + R"(, "cameras": [{"eye": [1.2, 0.7, 1.5]},
      {"eye": [-1.6, 0.3, -0.4]}]})",
                                  ".");
  for (ivr::Camera& c : s.cameras) c.width = c.height = image;
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr empty-space skipping benchmark"};
  std::string device_sel, out_path, data = "../shared/data";
  int repeats = 7, image = 256;
  std::string schemes_text = "midpoint,trapezoid,preintegrated,exact";
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--data", data, "Folder of the shared real volumes");
  app.add_option("--repeats", repeats, "Timed runs per configuration (median)")
      ->check(CLI::Range(1, 100));
  app.add_option("--image", image, "Image edge in pixels (two views)")->check(CLI::Range(8, 4096));
  app.add_option("--schemes", schemes_text,
                 "Comma-separated integrators (exact renders the scenes' absorption model)");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  CLI11_PARSE(app, argc, argv);

  try {
    ivr::Device device(device_sel);
    struct Case {
      std::string name;
      ivr::Scene scene;
    };
    std::vector<Case> cases;
    const std::string neghip = data + "/neghip_64x64x64_uint8.raw";
    const std::string mni = data + "/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz";
    if (std::filesystem::exists(neghip))
      cases.push_back({"neghip", real_scene(R"({"file": ")" + neghip +
                                                R"(", "dims": [64, 64, 64], "type": "uint8"})",
                                            0.1, image)});
    if (std::filesystem::exists(mni))
      cases.push_back({"mni152", real_scene(R"({"file": ")" + mni + R"("})", 0.1, image)});
    cases.push_back({"marschner_lobb_128", ivr::bench::bench_scene(128, image)});

    std::vector<ivr::Scheme> schemes;
    {
      std::stringstream in(schemes_text);
      for (std::string name; std::getline(in, name, ',');)
        schemes.push_back(ivr::parse_scheme(name));
    }
    json configs = json::array();
    for (ivr::Scheme scheme : schemes)
      for (Case c : cases)
        for (double step : {0.5, 0.25}) {
          c.scene.integrator.scheme = scheme;
          if (scheme == ivr::Scheme::exact) c.scene.model = ivr::Model::absorption;
          ivr::RenderOptions on{ivr::Precision::f32, step}, off = on, automatic = on;
          on.empty_space = ivr::EmptySpace::on;
          off.empty_space = ivr::EmptySpace::off;
          ivr::RenderStats s_on, s_off, s_auto;
          ivr::Image i_on = ivr::render(device, c.scene, on, &s_on);  // warm-up, compiles
          ivr::Image i_off = ivr::render(device, c.scene, off, &s_off);
          ivr::render(device, c.scene, automatic, &s_auto);
          std::vector<double> k_on, k_off, w_on, w_off, w_auto;
          for (int r = 0; r < repeats; ++r) {  // interleaved against load from elsewhere
            w_on.push_back(wall_seconds([&] { i_on = ivr::render(device, c.scene, on, &s_on); }));
            k_on.push_back(s_on.kernel_seconds);
            w_off.push_back(
                wall_seconds([&] { i_off = ivr::render(device, c.scene, off, &s_off); }));
            k_off.push_back(s_off.kernel_seconds);
            w_auto.push_back(
                wall_seconds([&] { ivr::render(device, c.scene, automatic, &s_auto); }));
          }
          double diff = 0;
          for (std::size_t i = 0; i < i_on.pixels.size(); ++i)
            diff = std::max(diff, std::abs(double(i_on.pixels[i]) - i_off.pixels[i]));
          const json j = {{"volume", c.name},
                          {"scheme", ivr::scheme_name(scheme)},
                          {"step", step},
                          {"image", image},
                          {"empty_fraction", s_on.empty_fraction},
                          {"grid_ms", 1e3 * s_on.grid_seconds},
                          {"samples_on", s_on.samples},
                          {"samples_off", s_off.samples},
                          {"kernel_ms_on", 1e3 * median(k_on)},
                          {"kernel_ms_off", 1e3 * median(k_off)},
                          {"total_ms_on", 1e3 * median(w_on)},
                          {"total_ms_off", 1e3 * median(w_off)},
                          {"total_ms_auto", 1e3 * median(w_auto)},
                          {"auto_skipped", s_auto.skipped_empty},
                          {"speedup_kernel", median(k_off) / median(k_on)},
                          {"speedup_total", median(w_off) / median(w_on)},
                          {"max_pixel_difference", diff}};
          std::cerr << c.name << " " << ivr::scheme_name(scheme) << " step " << step << ": empty "
                    << s_on.empty_fraction << ", kernel " << 1e3 * median(k_off) << " -> "
                    << 1e3 * median(k_on) << " ms (" << j["speedup_kernel"].get<double>()
                    << "x), total " << j["speedup_total"].get<double>() << "x, auto "
                    << (s_auto.skipped_empty ? "on" : "off") << ", max diff " << diff << "\n";
          configs.push_back(j);
        }
    // The gradient (d mse / d density, adjoint) with and without skipping, at step 0.5.
    json gradients = json::array();
    for (ivr::Scheme scheme : schemes)
      for (Case c : cases) {
        c.scene.integrator.scheme = scheme;
        if (scheme == ivr::Scheme::exact) c.scene.model = ivr::Model::absorption;
        const ivr::Image target = ivr::bench::perturbed_target(device, c.scene, 0.5);
        ivr::AdjointOptions on, off;
        on.step = off.step = 0.5;
        on.empty_space = ivr::EmptySpace::on;
        off.empty_space = ivr::EmptySpace::off;
        ivr::AdjointGradient g_on = ivr::adjoint(device, c.scene, target, on);  // warm-up, compiles
        ivr::AdjointGradient g_off = ivr::adjoint(device, c.scene, target, off);
        std::vector<double> k_on, k_off;
        for (int r = 0; r < repeats; ++r) {
          g_on = ivr::adjoint(device, c.scene, target, on);
          k_on.push_back(g_on.kernel_seconds);
          g_off = ivr::adjoint(device, c.scene, target, off);
          k_off.push_back(g_off.kernel_seconds);
        }
        double scale = 0, diff = 0;
        for (std::size_t i = 0; i < g_off.density.size(); ++i) {
          scale = std::max(scale, double(std::abs(g_off.density[i])));
          diff = std::max(diff, double(std::abs(g_on.density[i] - g_off.density[i])));
        }
        const json j = {{"volume", c.name},
                        {"scheme", ivr::scheme_name(scheme)},
                        {"step", 0.5},
                        {"skipped", g_on.skipped_empty},
                        {"kernel_ms_on", 1e3 * median(k_on)},
                        {"kernel_ms_off", 1e3 * median(k_off)},
                        {"speedup_kernel", median(k_off) / median(k_on)},
                        {"max_difference_relative_to_max", scale > 0 ? diff / scale : 0.0}};
        std::cerr << c.name << " " << ivr::scheme_name(scheme)
                  << " gradient: " << 1e3 * median(k_off) << " -> " << 1e3 * median(k_on) << " ms ("
                  << j["speedup_kernel"].get<double>() << "x), max diff / max "
                  << j["max_difference_relative_to_max"].get<double>() << "\n";
        gradients.push_back(j);
      }
    const json result = {{"benchmark", "empty_space"},   {"ivr_version", IVR_VERSION_STRING},
                         {"device", device.info().name}, {"repeats", repeats},
                         {"statistic", "median"},        {"configs", configs},
                         {"gradients", gradients}};
    ivr::bench::emit_json(result, out_path);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
