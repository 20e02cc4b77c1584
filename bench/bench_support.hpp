// bench_support.hpp — what the benchmark runners share: medians, wall-clock timing, and the
// target image rendered from a smoothly perturbed volume (so that d loss / d pixel is non-zero).
#pragma once
#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::bench {

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
