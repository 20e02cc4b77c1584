// accuracy_suite.cpp — the speed-against-error suite's volumes, transfer functions and scenes.
#include "accuracy_suite.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

namespace ivr::bench {

namespace {

// Synthetic volumes by formula over [-1, 1]³ (n³ voxels).
Volume formula_volume(int n, double (*f)(double, double, double)) {
  Volume v;
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

double empty_share(const Volume& v) {
  std::size_t below = 0;
  for (float d : v.data) below += d < 0.1f ? 1 : 0;
  return double(below) / double(v.data.size());
}

}  // namespace

std::vector<SuiteLook> suite_looks() {
  return {{"ramps", Model::emission_absorption, R"({"type": "piecewise_linear", "points": [
          {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
          {"density": 0.1, "color": [0.2, 0.4, 1.0], "extinction": 0},
          {"density": 0.4, "color": [1.0, 0.7, 0.3], "extinction": 25},
          {"density": 1.0, "color": [1.0, 1.0, 0.9], "extinction": 60}]})"},
          {"band", Model::emission_absorption, R"({"type": "piecewise_linear", "points": [
          {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
          {"density": 0.1, "color": [0.2, 0.4, 1.0], "extinction": 0},
          {"density": 0.30, "color": [0.3, 0.5, 1.0], "extinction": 1.6},
          {"density": 0.33, "color": [1.0, 0.6, 0.2], "extinction": 80},
          {"density": 0.36, "color": [1.0, 0.9, 0.7], "extinction": 2.1},
          {"density": 1.0, "color": [1.0, 1.0, 1.0], "extinction": 7}]})"},
          {"absorption", Model::absorption, R"({"type": "piecewise_linear", "points": [
          {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
          {"density": 0.1, "color": [0, 0, 0], "extinction": 0},
          {"density": 0.4, "color": [0, 0, 0], "extinction": 3},
          {"density": 1.0, "color": [0, 0, 0], "extinction": 8}]})"}};
}

std::vector<SuiteVolume> suite_volumes(const std::string& data, bool quick) {
  std::vector<SuiteVolume> out;
  out.push_back({"smooth_blob", formula_volume(64, smooth_blob)});
  out.push_back({"sharp_shell", formula_volume(64, sharp_shell)});
  out.push_back({"marschner_lobb", synthetic_volume("marschner_lobb", 64, 64, 64)});
  const std::pair<const char*, std::string> real[] = {
      {"headsq", R"({"file": "headsq_64x64x93_int16le.raw", "dims": [64, 64, 93],
          "type": "int16", "endian": "little", "range": [0, 4095], "spacing": [3.2, 3.2, 1.5]})"},
      {"neghip", R"({"file": "neghip_64x64x64_uint8.raw", "dims": [64, 64, 64], "type": "uint8"})"},
      {"tooth",
       R"({"file": "tooth_103x94x161_uint8.raw", "dims": [103, 94, 161], "type": "uint8"})"},
      {"c60", R"({"file": "C60Large_128x128x128_uint8.cvol"})"},
      {"mni152", R"({"file": "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz"})"}};
  for (const auto& [name, volume] : real) {
    if (quick) break;
    nlohmann::json v = nlohmann::json::parse(volume);
    const std::string path = data + "/" + v["file"].get<std::string>();
    if (!std::filesystem::exists(path)) {
      std::cerr << "skipping " << name << ": no " << path << "\n";
      continue;
    }
    v["file"] = std::filesystem::absolute(path).string();
    out.push_back({name, parse_volume(v.dump(), ".")});
  }
  for (SuiteVolume& v : out) v.empty = empty_share(v.volume);
  return out;
}

Scene suite_scene(const SuiteVolume& volume, const SuiteLook& look, int image) {
  Scene s = parse_scene(std::string(R"({"volume": {"synthetic": "sphere", "dims": [2, 2, 2]},
      "model": ")") + (look.model == Model::absorption ? "absorption" : "emission_absorption") +
                            R"(", "tf": )" + look.tf_json + R"(, "cameras": [
      {"eye": [1.2, 0.7, 1.5]}, {"eye": [-1.6, 0.3, -0.4]}],
      "integrator": {"min_transmittance": 0}})",
                        ".");
  s.volume = volume.volume;
  set_default_box(s);
  for (Camera& c : s.cameras) c.width = c.height = image;
  return s;
}

RelativeError relative_error(const std::vector<float>& a, const std::vector<double>& r) {
  double d2 = 0, r2 = 0, dmax = 0, rmax = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = double(a[i]) - r[i];
    d2 += d * d, r2 += r[i] * r[i];
    dmax = std::max(dmax, std::abs(d)), rmax = std::max(rmax, std::abs(r[i]));
  }
  return {std::sqrt(d2 / std::max(r2, 1e-300)), dmax / std::max(rmax, 1e-300)};
}

double time_at(std::vector<std::pair<double, double>> curve, double target) {
  std::sort(curve.begin(), curve.end());
  for (std::size_t i = 0; i < curve.size(); ++i) {
    if (curve[i].second > target) continue;
    if (i == 0) return curve[0].first;
    const auto [t0, e0] = curve[i - 1];
    const auto [t1, e1] = curve[i];
    const double w = (std::log(target) - std::log(e0)) / (std::log(e1) - std::log(e0));
    return std::exp(std::log(t0) + w * (std::log(t1) - std::log(t0)));
  }
  return NAN;
}

}  // namespace ivr::bench
