// exp_test.cpp — kernels/exp.cl's float32 e^x: its host copy (reference/expf_steps.hpp) within
// 1 ulp of e^x (std::exp in float64, rounded) over 2^26 arguments spread over every float from
// the underflow to the overflow threshold, exact at 0, 0 and +inf beyond the ends, NaN for NaN,
// monotonic; and
// the device's scalar, 8-wide and 16-wide forms equal to the host copy bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <random>
#include <vector>

#include "reference/expf_steps.hpp"
#include "runtime/kernel_sources.hpp"
#include "runtime/runtime.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

float from_bits(std::uint32_t b) {
  float f;
  std::memcpy(&f, &b, sizeof f);
  return f;
}

// |got − e^x| in units of the last place of e^x rounded to float (subnormal spacing below).
double ulp_error(float x, float got) {
  const double exact = std::exp(double(x));
  const float rounded = float(exact);
  const float next = std::nextafter(rounded, std::numeric_limits<float>::infinity());
  const double ulp = double(next) - double(rounded);
  return std::abs(double(got) - exact) / ulp;
}

TEST(Exp, HostCopyIsWithinOneUlpAndExactAtTheEnds) {
  EXPECT_EQ(reference::expf_steps(0.0f), 1.0f);
  EXPECT_EQ(reference::expf_steps(-0.0f), 1.0f);
  EXPECT_EQ(reference::expf_steps(-105.0f), 0.0f);
  EXPECT_EQ(reference::expf_steps(-1e30f), 0.0f);
  EXPECT_EQ(reference::expf_steps(89.0f), std::numeric_limits<float>::infinity());
  EXPECT_TRUE(std::isfinite(reference::expf_steps(88.72f)));
  EXPECT_TRUE(std::isnan(reference::expf_steps(std::nanf(""))));
  double worst = 0, worst_negative = 0;
  float worst_x = 0;
  // Every 64th float bit pattern of both signs within (-103.97, 88.72): normal and subnormal
  // results alike (the relative error of a subnormal result is measured in its own spacing).
  for (std::uint32_t b = 0; b < 0x7f800000u; b += 64)
    for (float x : {from_bits(b), -from_bits(b)}) {
      if (!(x > -103.9f && x < 88.72f)) continue;
      const double e = ulp_error(x, reference::expf_steps(x));
      if (e > worst) worst = e, worst_x = x;
      if (x < 0) worst_negative = std::max(worst_negative, e);
    }
  EXPECT_LE(worst, 1.0) << "at x = " << worst_x;
  std::cout << "exp: worst " << worst << " ulp (at " << worst_x << "), over x < 0 "
            << worst_negative << " ulp\n";
  // Monotonic over a fine grid of the optical depths the marches decay by.
  float last = reference::expf_steps(0.0f);
  for (float tau = 1e-4f; tau < 60.0f; tau *= 1.0001f) {
    const float e = reference::expf_steps(-tau);
    ASSERT_LE(e, last) << tau;
    last = e;
  }
}

TEST(Exp, DeviceFormsEqualTheHostCopyBitForBit) {
  Device::Impl& dev = device().impl();
  const std::string source = assemble_kernel("exp.cl") + R"(
    __kernel void exps(__global const float* x, __global float* one, __global float* eight,
                       __global float* sixteen) {
      const int i = get_global_id(0);
      one[i] = ivr_expf(x[i]);
      if (i % 8 == 0) vstore8(ivr_expf8(vload8(i / 8, x)), i / 8, eight);
      if (i % 16 == 0) vstore16(ivr_expf16(vload16(i / 16, x)), i / 16, sixteen);
    })";
  cl::Program program(dev.context, source);
  try {
    program.build({dev.device});
  } catch (const cl::Error&) {
    FAIL() << program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(dev.device);
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> wide(-110.0f, 95.0f), depth(0.0f, 30.0f);
  std::vector<float> x(1 << 20);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = i % 2 ? wide(rng) : -depth(rng);
  x[0] = 0, x[1] = -104.0f, x[2] = -103.5f, x[3] = 88.72f, x[4] = 88.73f, x[5] = -87.4f;
  x[6] = std::nanf("");
  const std::size_t bytes = x.size() * sizeof(float);
  cl::Buffer in(dev.context, cl_mem_flags(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR), bytes,
                x.data());
  cl::Buffer one(dev.context, CL_MEM_WRITE_ONLY, bytes), eight(dev.context, CL_MEM_WRITE_ONLY, bytes),
      sixteen(dev.context, CL_MEM_WRITE_ONLY, bytes);
  cl::Kernel k(program, "exps");
  k.setArg(0, in);
  k.setArg(1, one);
  k.setArg(2, eight);
  k.setArg(3, sixteen);
  dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(x.size()));
  std::vector<float> a(x.size()), b(x.size()), c(x.size());
  dev.queue.enqueueReadBuffer(one, CL_TRUE, 0, bytes, a.data());
  dev.queue.enqueueReadBuffer(eight, CL_TRUE, 0, bytes, b.data());
  dev.queue.enqueueReadBuffer(sixteen, CL_TRUE, 0, bytes, c.data());
  int mismatches = 0;
  for (std::size_t i = 0; i < x.size() && mismatches < 5; ++i) {
    const float want = reference::expf_steps(x[i]);
    for (float got : {a[i], b[i], c[i]})
      if (std::isnan(want) ? !std::isnan(got) : std::memcmp(&got, &want, sizeof got) != 0) {
        ++mismatches;
        ADD_FAILURE() << "exp(" << x[i] << "): device " << got << ", host " << want;
        break;
      }
  }
}

}  // namespace
}  // namespace ivr::test
