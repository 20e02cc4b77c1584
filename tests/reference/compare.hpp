// compare.hpp — helpers for judging kernel images against the reference: absolute+relative
// tolerances with NaN/Inf always failing, error norms, and smooth random test volumes.
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <vector>

#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr::reference {

// |got - want| <= atol + rtol * |want| for every element; NaN/Inf fail; shapes must agree.
inline ::testing::AssertionResult close(const ivr::Image& got, const std::vector<double>& want,
                                        double atol, double rtol) {
  if (got.pixels.size() != want.size())
    return ::testing::AssertionFailure() << "size " << got.pixels.size() << " vs " << want.size();
  std::size_t bad = 0, worst = 0, nonfinite = 0;
  double worst_excess = -1, max_abs = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    const double g = got.pixels[i], e = std::abs(g - want[i]);
    if (!std::isfinite(g) || !std::isfinite(want[i])) {
      ++nonfinite;
      worst = i;
      worst_excess = INFINITY;
      continue;
    }
    max_abs = std::max(max_abs, e);
    const double excess = e - (atol + rtol * std::abs(want[i]));
    if (excess > 0) ++bad;
    if (excess > worst_excess) worst_excess = excess, worst = i;
  }
  if (bad == 0 && nonfinite == 0) return ::testing::AssertionSuccess();
  const int c = got.channels, w = got.width, h = got.height;
  std::ostringstream m;
  m.precision(10);
  m << bad << " elements out of tolerance (atol " << atol << ", rtol " << rtol << "), " << nonfinite
    << " NaN/Inf; max |diff| " << max_abs << "; worst at (view " << worst / c / w / h << ", y "
    << worst / c / w % h << ", x " << worst / c % w << ", c " << worst % c << "): got "
    << got.pixels[worst] << ", want " << want[worst];
  return ::testing::AssertionFailure() << m.str();
}

inline ::testing::AssertionResult all_finite(const ivr::Image& image) {
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    if (!std::isfinite(image.pixels[i]))
      return ::testing::AssertionFailure() << "element " << i << " is " << image.pixels[i];
  return ::testing::AssertionSuccess();
}

inline double max_abs_diff(const ivr::Image& got, const std::vector<double>& want) {
  double m = 0;
  for (std::size_t i = 0; i < want.size(); ++i)
    m = std::max(m, std::abs(double(got.pixels[i]) - want[i]));
  return m;
}

inline double rms_diff(const ivr::Image& got, const std::vector<double>& want) {
  double s = 0;
  for (std::size_t i = 0; i < want.size(); ++i) s += std::pow(double(got.pixels[i]) - want[i], 2);
  return std::sqrt(s / double(want.size()));
}

// A smooth random field in [0, 1]: a few low-frequency cosines over the grid, fixed by the seed.
inline ivr::Volume smooth_volume(int nx, int ny, int nz, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  struct Wave {
    double kx, ky, kz, phase, amp;
  };
  std::vector<Wave> waves;
  for (int i = 0; i < 4; ++i)
    waves.push_back({u(rng) * 1.5, u(rng) * 1.5, u(rng) * 1.5, u(rng) * 6.283185307179586, u(rng)});
  ivr::Volume v;
  v.nx = nx, v.ny = ny, v.nz = nz;
  std::vector<double> f;
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        double s = 0;
        for (const Wave& w : waves)
          s +=
              w.amp * std::cos(6.283185307179586 * (w.kx * x / nx + w.ky * y / ny + w.kz * z / nz) +
                               w.phase);
        f.push_back(s);
      }
  double lo = f[0], hi = f[0];
  for (double s : f) lo = std::min(lo, s), hi = std::max(hi, s);
  for (double s : f) v.data.push_back(float((s - lo) / (hi - lo)));
  return v;
}

}  // namespace ivr::reference
