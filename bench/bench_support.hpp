// bench_support.hpp — what the benchmark runners share: medians, wall-clock timing, seeded vectors
// and their dot product, the target image rendered from a smoothly perturbed volume (so that
// d loss / d pixel is non-zero), and the JSON result printed and written.
#pragma once
#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::bench {

// Prints a benchmark's JSON document and, where `path` is given, writes it there too: a file that
// cannot be written is an error naming it, not a result silently missing.
inline void emit_json(const nlohmann::json& doc, const std::string& path) {
  const std::string text = doc.dump(2) + "\n";
  std::cout << text;
  if (path.empty()) return;
  std::ofstream out(path);
  out << text;
  if (!out) throw Error(Status::io, "cannot write the results to " + path);
}

// n values uniform in [0, 1) from a fixed seed (the dot-product tests' vectors).
inline std::vector<double> uniform(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> v(n);
  for (double& x : v) x = double(rng() >> 11) * 0x1.0p-53;
  return v;
}

// ⟨a, b⟩ summed in long double.
inline double dot(const std::vector<double>& a, const std::vector<double>& b) {
  long double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += (long double)a[i] * b[i];
  return double(s);
}

inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

template <class F>
double wall_seconds(F&& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The scene rendered with densities scaled by 0.9..1.1 along a slow wave.
inline Image perturbed_target(Device& device, const Scene& scene, double step) {
  Scene s = scene;
  const Volume& v = s.volume;
  for (int z = 0; z < v.nz; ++z)
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < v.nx; ++x) {
        float& d = s.volume.data[(std::size_t(z) * v.ny + y) * v.nx + x];
        const double wave = std::sin(6.0 * x / v.nx) * std::cos(4.0 * y / v.ny + 2.0 * z / v.nz);
        d = float(std::clamp(d * (1.0 + 0.1 * wave), 0.0, 1.0));
      }
  return render(device, s, RenderOptions{Precision::f32, step});
}

}  // namespace ivr::bench
