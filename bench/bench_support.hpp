// bench_support.hpp — what the benchmark runners share: medians, wall-clock timing, seeded vectors
// and their dot product (reference/random.hpp), the target image rendered from a smoothly perturbed volume (so that
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
#include "reference/random.hpp"

namespace ivr::bench {

using reference::dot;
using reference::uniform;

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
