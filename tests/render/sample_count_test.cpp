// sample_count_test.cpp — the sample count (docs/integrators.md): the same n for float32 and float64 on every
// count arithmetic a device may use, a 1-ulp division error emulated on the host and in the
// kernels, and the rays built so that length / step is an integer (where any rounding moves n).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <random>

#include "ivr/adjoint.hpp"
#include "ivr/render.hpp"
#include "reference/sample_count.hpp"
#include "runtime/runtime.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using namespace test;

using reference::CountArithmetic;

// Float pairs over a wide range of exponents and every significand pattern the corrections care
// about (random, all ones, powers of two).
float random_float(std::mt19937& rng) {
  std::uniform_int_distribution<std::uint32_t> mantissa(0, (1u << 23) - 1);
  std::uniform_int_distribution<int> exponent(-30, 30), kind(0, 9);
  const int k = kind(rng);
  const std::uint32_t m = k == 0 ? (1u << 23) - 1 : k == 1 ? 0u : mantissa(rng);
  const float one_to_two = 1.f + float(m) / float(1u << 23);
  return std::ldexp(one_to_two, exponent(rng)) * (kind(rng) < 5 ? 1.f : -1.f);
}

// The fallback's division and root from a quotient 1 ulp high are the correctly rounded ones
// (kernels/sample_count.cl's IVR_COUNT_RESIDUAL; the host's copy runs the same steps).
TEST(SampleCount, ResidualCorrectionUndoesAOneUlpError) {
  std::mt19937 rng(11);
  for (int i = 0; i < 300000; ++i) {
    const float a = random_float(rng), b = random_float(rng), x = std::fabs(a);
    ASSERT_NE(reference::count_divide(a, b, CountArithmetic::one_ulp_high), a / b);
    ASSERT_EQ(reference::count_divide(a, b, CountArithmetic::one_ulp_high_corrected), a / b)
        << a << " / " << b;
    ASSERT_EQ(reference::count_sqrt(x, CountArithmetic::one_ulp_high_corrected), std::sqrt(x))
        << "sqrt " << x;
  }
}

// Cameras whose rays are built to cross the box in an integer number of steps, and random ones.
struct CountCase {
  Scene scene;
  double step_world;
};

std::vector<CountCase> count_cases() {
  std::vector<CountCase> cases;
  // Axis-aligned orthographic rays through a unit box: every chord is 1, and step = 1/k makes
  // 1/step an integer in float64 but not always in float32 (1/k is not a float).
  for (int k : {3, 5, 7, 10, 49, 50, 100, 1599}) {
    Scene s = constant_scene(0.5f, 8, 6);
    s.model = Model::absorption;
    cases.push_back({s, 1.0 / k});
  }
  // Oblique and perspective rays, random eyes and steps.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1), step(0.003, 0.2);
  for (int i = 0; i < 12; ++i) {
    Scene s = constant_scene(0.5f, 8, 7);
    Camera& c = s.cameras[0];
    c.eye = glm::normalize(glm::dvec3(u(rng), u(rng), u(rng))) * 2.5;
    c.target = {0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng)};
    c.up = std::abs(c.eye.y) < 2 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
    c.projection = i % 2 ? Projection::perspective : Projection::orthographic;
    c.fov_y = 40;
    cases.push_back({s, step(rng)});
  }
  return cases;
}

std::uint64_t defined_samples(const CountCase& c, CountArithmetic arithmetic) {
  const Camera& cam = c.scene.cameras[0];
  const reference::PackedCamera packed = reference::packed_camera(cam);
  std::uint64_t total = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      total += reference::sample_count(packed, x, y, cam.width, cam.height, c.scene.box_min,
                                       c.scene.box_max, c.step_world, arithmetic);
  return total;
}

// On the host: the count through a 1-ulp-high division and sqrt, corrected, is the count; used as
// it comes, it is not (so the cases above do reach the rounding that moves n).
TEST(SampleCount, HostDefinitionSurvivesAOneUlpDivisionError) {
  int moved = 0;
  for (const CountCase& c : count_cases()) {
    const std::uint64_t want = defined_samples(c, CountArithmetic::correctly_rounded);
    EXPECT_EQ(defined_samples(c, CountArithmetic::one_ulp_high_corrected), want) << c.step_world;
    moved += defined_samples(c, CountArithmetic::one_ulp_high) != want;
  }
  EXPECT_GT(moved, 0) << "no case is sensitive to the division's rounding";
}

// The midpoint march takes one sample per segment: without early termination or skipping, the
// samples of a render are Σ n over the rays, which must be the definition's for both precisions,
// every count arithmetic the device offers, and a float32 division 1 ulp high in the kernels.
TEST(SampleCount, KernelsTakeTheDefinedCountInBothPrecisions) {
  const DeviceInfo& info = device().info();
  std::vector<std::string> arithmetics = {"residual"};
  if (fp64_count_usable(info)) arithmetics.push_back("fp64");
  if (info.correctly_rounded_divide_sqrt) arithmetics.push_back("option");
  const std::vector<CountCase> cases = count_cases();
  for (const std::string& arithmetic : arithmetics)
    for (const char* emulate : {"", "-DIVR_EMULATE_DIVISION_ERROR=1"}) {
      ScopedEnv count("IVR_COUNT_ARITHMETIC", arithmetic);
      ScopedEnv options("IVR_BUILD_OPTIONS", emulate);
      for (const CountCase& c : cases) {
        const double h = c.scene.voxel_size().x;
        const std::uint64_t want = defined_samples(c, CountArithmetic::correctly_rounded);
        for (Precision p : {Precision::f32, Precision::f64}) {
          if (p == Precision::f64 && !info.fp64) continue;
          RenderStats stats;
          render_at(c.scene, p, c.step_world / h, &stats);
          EXPECT_EQ(stats.samples, want)
              << name(p) << ", count " << arithmetic << " " << emulate << ", step "
              << c.step_world;
        }
      }
    }
}

// A device whose float32 division and sqrt are 1 ulp off (emulated) renders and differentiates
// bit for bit as this one: every per-ray quotient and root goes through rounded.cl, whose residual
// path undoes the error. (Per-sample quotients — TF slopes, compositing — are not emulated.)
TEST(SampleCount, ADivisionOneUlpOffMovesNoRayAndNoResult) {
  Scene s = constant_scene(0.5f, 12, 9);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (float& d : s.volume.data) d = u(rng);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.2, 0.4, 0.9}, 0.5}, {0.6, {0.9, 0.5, 0.1}, 6.0}, {1.0, {1, 1, 1}, 2.0}};
  s.integrator.min_transmittance = 0.05;
  Camera& c = s.cameras[0];
  c.projection = Projection::perspective;
  c.eye = {1.3, 0.7, 2.1};
  c.fov_y = 35;
  const Image target = render_at(s, Precision::f64, 0.37);
  for (Precision p : {Precision::f32, Precision::f64}) {
    if (p == Precision::f64 && !device().info().fp64) continue;
    AdjointOptions o;
    o.precision = p;
    o.step = 0.37;
    o.deterministic = true;
    const Image want = render_at(s, p, 0.37);
    const AdjointGradient want_g = adjoint(device(), s, target, o);
    ScopedEnv count("IVR_COUNT_ARITHMETIC", "residual");
    ScopedEnv emulate("IVR_BUILD_OPTIONS", "-DIVR_EMULATE_DIVISION_ERROR=1");
    EXPECT_EQ(render_at(s, p, 0.37).pixels, want.pixels) << name(p);
    const AdjointGradient g = adjoint(device(), s, target, o);
    EXPECT_EQ(g.density, want_g.density) << name(p);
    EXPECT_EQ(g.samples, want_g.samples) << name(p);
    EXPECT_EQ(g.loss, want_g.loss) << name(p);
  }
}

TEST(SampleCount, ForcingAnArithmeticTheDeviceLacksIsAClearError) {
  const DeviceInfo& info = device().info();
  Scene s = constant_scene(0.5f);
  ScopedEnv bad("IVR_COUNT_ARITHMETIC", "exact");
  try {
    render_at(s, Precision::f32, 1);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "IVR_COUNT_ARITHMETIC must be auto, fp64, option or residual"))
        << e.what();
  }
  if (!info.correctly_rounded_divide_sqrt) {
    ScopedEnv lacking("IVR_COUNT_ARITHMETIC", "option");
    EXPECT_THROW(render_at(s, Precision::f32, 1), Error);
  }
}

}  // namespace
}  // namespace ivr
