// random.hpp — seeded vectors and their dot product, shared by the tests and the benchmarks (the
// dot-product tests of a linear operator and its transpose).
#pragma once
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

namespace ivr::reference {

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

}  // namespace ivr::reference
