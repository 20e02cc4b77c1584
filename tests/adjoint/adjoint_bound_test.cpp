// adjoint_bound_test.cpp — the deterministic (fixed-point) density gradient in one pass: the
// a-priori bound of lib/adjoint/adjoint_bound.hpp against sampled transfer functions and measured
// contributions, the scale rule, and for every model × scheme × TF kind × loss one pass, the same
// bits on every run and after any history, and agreement with the float-atomic gradient; both
// second passes forced through $IVR_FIXED_BOUND_SHIFT (a test-only knob).
#include "adjoint/adjoint_bound.hpp"
#include "scene/tf_kinds.hpp"

#include <gtest/gtest.h>

#include "runtime/variants.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "adjoint/adjoint_support.hpp"
#include "ivr/core.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A target of the scene's shape with values in [0, 1] from a fixed seed: a non-zero loss
// gradient without rendering (and compiling) anything.
Image random_target(const Scene& s, unsigned seed) {
  Image t;
  t.views = int(s.cameras.size());
  t.height = s.cameras[0].height;
  t.width = s.cameras[0].width;
  t.channels = s.channels();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  t.pixels.resize(std::size_t(t.views) * t.height * t.width * t.channels);
  for (float& p : t.pixels) p = u(rng);
  return t;
}

// Every |a − b| within 1e-5 of the largest |b| plus 1e-4 of |b| itself: the fixed point's rounding
// (at least 24 bits of the largest contribution) and the float atomics' order.
::testing::AssertionResult close_to(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return ::testing::AssertionFailure() << "sizes differ";
  const double scale = max_abs(b);
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!std::isfinite(a[i]) ||
        !(std::abs(double(a[i]) - b[i]) <= 1e-5 * scale + 1e-4 * std::abs(double(b[i]))))
      return ::testing::AssertionFailure()
             << "voxel " << i << ": " << a[i] << " vs " << b[i] << " (largest " << scale << ")";
  return ::testing::AssertionSuccess();
}

// --- the bound's pieces on the host ------------------------------------------------------------

// The extremes bound what the TF takes on a fine sampling of the range (slopes by central
// differences, which never exceed a piece's own slope), and for the linear kinds they are tight.
TEST(AdjointBound, TfExtremesBoundTheSampledTransferFunction) {
  const double ranges[][2] = {{0.15, 0.85}, {0.0, 2.0}, {0.4, 0.5}, {0.95, 1.2}, {0.3, 0.3}};
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
    for (const auto& r : ranges) {
      const Scene s = two_view_scene(Model::emission_absorption, kind);
      const TfExtremes e = tf_extremes(s.tf, r[0], r[1]);
      TfExtremes seen;
      const int n = 4000;
      const double h = 1e-7;
      for (int i = 0; i <= n; ++i) {
        const double d = r[0] + (r[1] - r[0]) * i / n;
        const reference::TfSample v = reference::transfer(s.tf, d);
        const reference::TfSample a = reference::transfer(s.tf, d - h);
        const reference::TfSample b = reference::transfer(s.tf, d + h);
        seen.sigma = std::max(seen.sigma, v.sigma);
        seen.sigma_slope = std::max(seen.sigma_slope, std::abs(b.sigma - a.sigma) / (2 * h));
        for (int c = 0; c < 3; ++c) {
          if (v.sigma > 1e-9) seen.color = std::max(seen.color, std::abs(v.emission[c] / v.sigma));
          seen.emission_slope =
              std::max(seen.emission_slope, std::abs(b.emission[c] - a.emission[c]) / (2 * h));
        }
      }
      const std::string where =
          std::string(tf_kind_name(kind)) + " [" + std::to_string(r[0]) + ", " + std::to_string(r[1]) + "]";
      // 1e-6: the central differences' rounding; the extremes themselves are exact.
      EXPECT_GE(e.sigma * (1 + 1e-6), seen.sigma) << where;
      EXPECT_GE(e.sigma_slope * (1 + 1e-6) + 1e-6, seen.sigma_slope) << where;
      EXPECT_GE(e.color * (1 + 1e-6), seen.color) << where;
      EXPECT_GE(e.emission_slope * (1 + 1e-6) + 1e-6, seen.emission_slope) << where;
      if (kind != TfKind::gaussian) {  // linear pieces: the extremes are attained
        EXPECT_LE(e.sigma, seen.sigma * (1 + 1e-4) + 1e-4) << where;
        EXPECT_LE(e.sigma_slope, seen.sigma_slope * (1 + 1e-3) + 1e-3) << where;
      }
      for (double v : {e.sigma, e.sigma_slope, e.color, e.emission_slope})
        EXPECT_TRUE(std::isfinite(v) && v >= 0) << where;
    }
}

// A jump (two points at one density) is never sampled inside: it adds no slope.
TEST(AdjointBound, TfJumpsAddNoSlope) {
  TransferFunction tf;
  tf.kind = TfKind::piecewise_linear;
  tf.points = {{0.0, {0, 0, 0}, 0}, {0.5, {0, 0, 0}, 0}, {0.5, {1, 1, 1}, 10}, {1.0, {1, 1, 1}, 10}};
  const TfExtremes e = tf_extremes(tf, 0, 1);
  EXPECT_EQ(e.sigma_slope, 0);
  EXPECT_EQ(e.emission_slope, 0);
  EXPECT_EQ(e.sigma, 10);
  EXPECT_EQ(e.color, 1);
}

// The scale rule: a bound sets S with bound·2^S < cap/2; a pass stands unless a ray passed the
// cap or the largest contribution kept fewer than 24 bits, and then the second pass's scale is
// the one the largest ray calls for (itself a pass that stands).
TEST(AdjointBound, ScaleRule) {
  const int cap = fixed_cap_exponent(100);  // 2^62 / 100 rounded down: 2^55
  EXPECT_EQ(cap, 55);
  EXPECT_EQ(fixed_cap_exponent(128), 55);
  EXPECT_EQ(fixed_cap_exponent(129), 54);
  EXPECT_EQ(fixed_cap_exponent(1), 62);
  for (double bound : {1e-30, 3e-7, 1.0, 0.75, 12345.0, 1e30}) {
    const int s = fixed_exponent_from_bound(bound, cap);
    EXPECT_LT(std::ldexp(bound, s), std::ldexp(1.0, cap - 1)) << bound;
    EXPECT_GE(std::ldexp(bound, s + 1), std::ldexp(1.0, cap - 1)) << bound;  // no finer one
  }
  EXPECT_EQ(fixed_exponent_from_bound(0, cap), cap - 1);
  EXPECT_EQ(fixed_exponent_from_bound(INFINITY, cap), -1100);
  const int s = fixed_exponent_from_bound(1.0, cap);
  EXPECT_EQ(s, 53);
  EXPECT_EQ(fixed_exponent_after(s, 0, 0.0, 0.0, cap), s);  // nothing added
  EXPECT_EQ(fixed_exponent_after(s, 0, 0.1, 0.5, cap), s);  // within the bound, 2^49.7
  const double tiny = std::ldexp(1.0, 23 - s);              // scaled: 2^23, one bit short
  EXPECT_EQ(fixed_exponent_after(s, 0, tiny, 8 * tiny, cap), fixed_exponent_for(8 * tiny, cap));
  EXPECT_EQ(fixed_exponent_after(s, 0, 2 * tiny, 8 * tiny, cap), s);  // 24 bits: enough
  EXPECT_EQ(fixed_exponent_after(s, 0, tiny, 1.0, cap), s);  // no finer scale holds the ray
  EXPECT_EQ(fixed_exponent_after(s, 3, 5.0, 6.0, cap), fixed_exponent_for(6.0, cap));  // failed
  EXPECT_LT(fixed_exponent_for(6.0, cap), s);
  for (double ray : {tiny, 5.0, 1e-20, 1e20}) {  // the second pass's scale stands
    const int ideal = fixed_exponent_for(ray, cap);
    EXPECT_EQ(fixed_exponent_after(ideal, 0, ray / 16, ray, cap), ideal) << ray;
    EXPECT_LT(std::ldexp(ray, ideal), std::ldexp(1.0, cap - 1)) << ray;
  }
}

TEST(AdjointBound, BadTestShiftIsNamed) {
  for (const char* bad : {"x", "3.5", "400", "-201", "7 "}) {
    ScopedEnv env("IVR_FIXED_BOUND_SHIFT", bad);
    try {
      fixed_bound_shift();
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument);
      EXPECT_TRUE(has(e.what(), "IVR_FIXED_BOUND_SHIFT must be an integer in -200 .. 200"))
          << e.what();
    }
  }
  ScopedEnv env("IVR_FIXED_BOUND_SHIFT", "-12");
  EXPECT_EQ(fixed_bound_shift(), -12);
}

// --- every model × scheme × TF kind × loss -------------------------------------------------------

struct Case {
  Model model;
  Scheme scheme;
  TfKind kind;
  Loss loss;
};

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  const Case& c = info.param;
  return std::string(c.model == Model::absorption ? "absorption" : "emission") + "_" +
         scheme_name(c.scheme) + "_" + tf_kind_name(c.kind) + "_" + (c.loss == Loss::l1 ? "l1" : "mse");
}

std::vector<Case> all_cases() {
  std::vector<Case> cases;
  for (Model m : {Model::absorption, Model::emission_absorption})
    for (Scheme sc : {Scheme::midpoint, Scheme::trapezoid, Scheme::exact, Scheme::preintegrated})
      for (TfKind k :
           {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
        for (Loss l : {Loss::mse, Loss::l1}) {
          if (sc == Scheme::exact && m != Model::absorption) continue;  // absorption only
          if ((sc == Scheme::exact || sc == Scheme::preintegrated) && k == TfKind::gaussian)
            continue;  // TFs linear in density only
          cases.push_back({m, sc, k, l});
        }
  return cases;
}

class DeterministicGradient : public ::testing::TestWithParam<Case> {
 protected:
  Scene scene() const {
    const Case& c = GetParam();
    Scene s = two_view_scene(c.model, c.kind);
    s.integrator.scheme = c.scheme;
    return s;
  }
};

TEST_P(DeterministicGradient, OnePassSameBitsWhateverTheHistory) {
  const Case& c = GetParam();
  const Scene s = scene();
  const Image target = random_target(s, 11);
  AdjointOptions o;
  o.loss = c.loss;
  o.deterministic = true;
  const AdjointGradient a = adjoint(device(), s, target, o);
  ASSERT_TRUE(a.deterministic) << "PoCL has cl_khr_int64_base_atomics";
  EXPECT_EQ(a.fixed_passes, 1) << "S = " << a.fixed_exponent;
  ASSERT_TRUE(all_finite(a));
  ASSERT_GT(max_abs(a.density), 0);
  EXPECT_EQ(adjoint(device(), s, target, o).density, a.density);  // run to run

  // A session that did other things first: another target, other densities, then back.
  Session session(device(), s);
  GradientRequest request;
  request.mode = Mode::adjoint;
  request.loss = c.loss;
  request.deterministic = true;
  session.set_target(random_target(s, 12));
  session.gradient(request);
  Volume other = s.volume;
  for (float& v : other.data) v = 0.5f * v + 0.4f;
  session.set_volume(other);
  session.gradient(request);
  session.set_volume(s.volume);
  session.set_target(target);
  EXPECT_EQ(session.gradient(request)["density"].to_floats(), a.density);
  const OperationStats st = session.last_stats();
  EXPECT_EQ(st.fixed_passes, 1);
  EXPECT_EQ(st.fixed_exponent, a.fixed_exponent);
  // The bound held, with margin: the largest ray's Σ |contribution| is below it, and no single
  // contribution exceeds its ray's sum.
  EXPECT_GT(st.fixed_largest, 0);
  EXPECT_LE(st.fixed_largest, st.fixed_largest_ray);
  EXPECT_LE(st.fixed_largest_ray, 0.5 * st.fixed_bound);

  // The float atomics' gradient, to float rounding.
  o.deterministic = false;
  const AdjointGradient f = adjoint(device(), s, target, o);
  EXPECT_FALSE(f.deterministic);
  EXPECT_EQ(f.fixed_passes, 0);
  EXPECT_TRUE(close_to(a.density, f.density));
  EXPECT_DOUBLE_EQ(a.loss, f.loss);
}

// The default suite runs a covering set: every scheme under each model it supports, every TF kind
// and both losses at least twice (a case costs its own kernel build: ~5 s cold on PoCL). The whole
// matrix, 50 cases, is `ctest -L extended`.
std::vector<Case> covering_cases() {
  using M = Model;
  using S = Scheme;
  using K = TfKind;
  return {{M::absorption, S::midpoint, K::identity, Loss::mse},
          {M::absorption, S::trapezoid, K::gaussian, Loss::l1},
          {M::absorption, S::exact, K::piecewise_linear, Loss::mse},
          {M::absorption, S::preintegrated, K::table, Loss::l1},
          {M::emission_absorption, S::midpoint, K::gaussian, Loss::mse},
          {M::emission_absorption, S::trapezoid, K::piecewise_linear, Loss::l1},
          {M::emission_absorption, S::preintegrated, K::identity, Loss::l1},
          {M::emission_absorption, S::trapezoid, K::table, Loss::mse}};
}

INSTANTIATE_TEST_SUITE_P(Covering, DeterministicGradient, ::testing::ValuesIn(covering_cases()),
                         case_name);
INSTANTIATE_TEST_SUITE_P(AllCasesExtended, DeterministicGradient,
                         ::testing::ValuesIn(all_cases()), case_name);

// --- the second pass ---------------------------------------------------------------------------

// A bound far too small (contributions over the cap) and one far too large (too few bits) both
// end in a second pass at the scale the largest contribution calls for — the same scale from
// either side, so the same bits: the result depends on the inputs, not on how wrong the bound
// was. And it is the gradient still (the float atomics' to rounding), the same on every run.
TEST(AdjointBound, SecondPassFromEitherSideGivesTheSameBits) {
  Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image target = random_target(s, 5);
  AdjointOptions o;
  o.deterministic = true;
  const AdjointGradient one = adjoint(device(), s, target, o);
  ASSERT_EQ(one.fixed_passes, 1);
  AdjointGradient small, large;
  {
    ScopedEnv env("IVR_FIXED_BOUND_SHIFT", "-60");
    small = adjoint(device(), s, target, o);
    EXPECT_EQ(adjoint(device(), s, target, o).density, small.density);
  }
  {
    ScopedEnv env("IVR_FIXED_BOUND_SHIFT", "60");
    large = adjoint(device(), s, target, o);
  }
  EXPECT_EQ(small.fixed_passes, 2);
  EXPECT_EQ(large.fixed_passes, 2);
  EXPECT_EQ(small.fixed_exponent, large.fixed_exponent);
  EXPECT_GT(small.fixed_exponent, one.fixed_exponent);  // the measured scale: finer than the bound's
  EXPECT_EQ(small.density, large.density);
  EXPECT_TRUE(close_to(small.density, one.density));
  EXPECT_DOUBLE_EQ(small.loss, one.loss);
  o.deterministic = false;
  EXPECT_TRUE(close_to(small.density, adjoint(device(), s, target, o).density));
}

// --- history: what the bound reads is measured, not remembered ---------------------------------

// After an optimiser step the session knows only the step's bounds on the densities ([0, ∞)
// here); the deterministic gradient measures their range again, so it equals the one-shot
// gradient of the same densities bit for bit — and so does a gradient against a target passed per
// call (its largest element measured on the device, not taken from the host).
TEST(AdjointBound, AfterAStepAndWithAPerCallTargetTheBitsAreTheOneShots) {
  Scene s = two_view_scene(Model::emission_absorption, TfKind::table);
  const Image target = random_target(s, 3);
  Session session(device(), s);
  session.set_target(target);
  GradientRequest request;
  request.mode = Mode::adjoint;
  request.deterministic = true;
  OptimizerOptions oo;
  oo.lower = 0;
  oo.lr = 0.05;
  Optimizer adam(device(), s.volume.voxel_count(), oo);
  session.step(adam, session.gradient(request)["density"]);
  const std::vector<float> stepped = session.volume().to_floats();
  const std::vector<float> got = session.gradient(request)["density"].to_floats();
  EXPECT_EQ(session.last_stats().fixed_passes, 1);
  Scene after = s;
  after.volume.data = stepped;
  AdjointOptions o;
  o.deterministic = true;
  const AdjointGradient want = adjoint(device(), after, target, o);
  EXPECT_EQ(got, want.density);

  DeviceArray per_call(device(), session.image_shape(), DType::f32);
  per_call.upload(target.pixels.data(), target.pixels.size());
  Session fresh(device(), after);
  EXPECT_EQ(fresh.gradient(per_call, request)["density"].to_floats(), want.density);
}

// float64: one pass too, the same bits run to run and within float64's tolerance of the float
// atomics (the fixed point still resolves the largest contribution to at least 24 bits).
TEST(AdjointBound, Float64OnePass) {
  if (!device().info().fp64) GTEST_SKIP() << "no float64";
  const Scene s = two_view_scene(Model::absorption, TfKind::piecewise_linear);
  const Image target = random_target(s, 9);
  AdjointOptions o;
  o.precision = Precision::f64;
  o.deterministic = true;
  const AdjointGradient a = adjoint(device(), s, target, o);
  EXPECT_EQ(a.fixed_passes, 1);
  EXPECT_EQ(adjoint(device(), s, target, o).density, a.density);
  o.deterministic = false;
  EXPECT_TRUE(close_to(a.density, adjoint(device(), s, target, o).density));
}

// Near-opaque media (σΔ ≈ 60 per step, optical depth ≈ 10³): the bound still holds with one pass.
TEST(AdjointBound, NearOpaqueMediumOnePass) {
  Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  for (auto& p : s.tf.points) p.extinction *= 300;
  const Image target = random_target(s, 4);
  AdjointOptions o;
  o.deterministic = true;
  const AdjointGradient a = adjoint(device(), s, target, o);
  EXPECT_EQ(a.fixed_passes, 1);
  ASSERT_TRUE(all_finite(a));
  o.deterministic = false;
  EXPECT_TRUE(close_to(a.density, adjoint(device(), s, target, o).density));
}

}  // namespace
}  // namespace ivr::test
