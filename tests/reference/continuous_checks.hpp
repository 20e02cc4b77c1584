// continuous_checks.hpp — helpers shared by the tests of the high-accuracy references
// (reference_continuous_test.cpp, reference_continuous_limits_test.cpp): element-wise
// comparisons of double images that print their worst difference, and x-profile volumes.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "ivr/scene.hpp"
#include "test_support.hpp"

namespace ivr::reference {

using Pixels = std::vector<double>;

// |got - want| <= atol + rtol |want| for every element, NaN/Inf fail; prints the worst |diff|.
inline ::testing::AssertionResult near(const Pixels& got, const Pixels& want, double atol,
                                       double rtol, const char* what = "") {
  if (got.size() != want.size())
    return ::testing::AssertionFailure() << "size " << got.size() << " vs " << want.size();
  double worst = 0;
  std::size_t bad = 0, at = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const double e = std::abs(got[i] - want[i]);
    if (!std::isfinite(got[i]) || !std::isfinite(want[i]) || e > atol + rtol * std::abs(want[i]))
      ++bad, at = i;
    if (e > worst) worst = e;
  }
  if (*what) std::printf("  [%s] max |diff| %.3g\n", what, worst);
  if (bad == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << bad << " bad elements (atol " << atol << ", rtol " << rtol << "), e.g. [" << at
         << "] got " << got[at] << " want " << want[at] << "; max |diff| " << worst;
}

inline double max_diff(const Pixels& a, const Pixels& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

// RMS over all elements of a - b.
inline double rms_diff(const Pixels& a, const Pixels& b) {
  double q = 0;
  for (std::size_t i = 0; i < a.size(); ++i) q += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(q / double(a.size()));
}

// A volume whose voxels depend on x only (values vx[i]), in the default unit cube.
inline Scene x_profile_scene(const std::vector<float>& vx) {
  const int n = int(vx.size());
  Scene s = test::constant_scene(0.f, n, 4);
  s.volume.data.clear();
  for (int k = 0; k < n * n; ++k) s.volume.data.insert(s.volume.data.end(), vx.begin(), vx.end());
  return s;
}

}  // namespace ivr::reference
