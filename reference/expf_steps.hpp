// expf_steps.hpp — kernels/exp.cl's float32 e^x on the host, step for step (the same fused
// multiply-adds in the same order), so that tests can measure its error against std::exp over
// many more arguments than a device run takes, and check the device's results bit for bit.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace ivr::reference {

inline float expf_steps(float x) {
  const float xc = std::fmin(std::fmax(x, -104.0f), 88.8f);
  const float n = std::floor(std::fma(xc, 1.44269504088896341f, 0.5f));
  float r = std::fma(n, -0.693359375f, xc);
  r = std::fma(n, 2.12194440e-4f, r);
  float p = std::fma(1.9875691500e-4f, r, 1.3981999507e-3f);
  p = std::fma(p, r, 8.3334519073e-3f);
  p = std::fma(p, r, 4.1665795894e-2f);
  p = std::fma(p, r, 1.6666665459e-1f);
  p = std::fma(p, r, 5.0000001201e-1f);
  const float rr = r * r;
  p = 1.0f + std::fma(p, rr, r);
  const int k = int(n);
  const bool low = k < -126, high = k > 127;
  const std::uint32_t bits = std::uint32_t(k + (low ? 100 : 0) - (high ? 1 : 0) + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  const float second = high ? 2.0f : (low ? 7.88860905e-31f : 1.0f);
  const float first = p * scale;
  float e = first * second;
  if (x < -104.0f) e = 0.0f;
  if (x > 88.72283905206835f) e = std::numeric_limits<float>::infinity();
  if (std::isnan(x)) e = x + x;
  return e;
}

}  // namespace ivr::reference
