// adjoint_precision_test.cpp — float32 adjoint vs float64 central differences for every TF kind and
// model, run-to-run determinism of the atomic sums, the absorption model's dot-product check, the
// l1 loss, and bad targets.
#include <gtest/gtest.h>

#include "runtime/variants.hpp"

#include <cmath>
#include <cstdio>
#include <random>

#include "adjoint/adjoint_support.hpp"
#include "reference/compare.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr::test {
namespace {

// A smooth 7x6x5 volume (densities in [0.15, 0.85]) in its default non-cubic box, every TF kind,
// two perspective 6x5 views, early termination off.
Scene small_scene(Model model, TfKind kind) {
  Scene s;
  s.volume = reference::smooth_volume(7, 6, 5, 17);
  for (float& d : s.volume.data) d = 0.15f + 0.7f * d;
  set_default_box(s);
  s.model = model;
  s.tf.kind = kind;
  s.tf.extinction_scale = 4;
  s.tf.color_scale = 0.9;
  s.tf.points = {
      {0.1, {0.3, 0.2, 0.8}, 0.5}, {0.5, {0.9, 0.4, 0.1}, 5.0}, {0.9, {1, 0.9, 0.7}, 2.5}};
  s.tf.range = {0.1, 0.9};
  s.tf.entries = {{0.2, 0.1, 0.8, 0.5}, {0.8, 0.5, 0.3, 3.5}, {0.2, 0.9, 0.3, 1.0}, {1, 1, 1, 4}};
  s.tf.gaussians = {{0.4, 0.12, {0.8, 0.3, 0.2}, 4.0}, {0.7, 0.15, {0.1, 0.7, 0.9}, 3.0}};
  s.background = glm::dvec3(0.2, 0.3, 0.4);
  Camera a, b;
  a.eye = {0.4, 0.3, 1.7};
  b.eye = {-1.5, -0.3, 0.4};
  a.width = b.width = 6;
  a.height = b.height = 5;
  a.fov_y = b.fov_y = 35;
  s.cameras = {a, b};
  s.integrator.step = 0.6;
  s.integrator.min_transmittance = 0;
  return s;
}

// The float64 render of the scene with every element moved by 0.03 to 0.08, signs and sizes drawn
// from a fixed seed: no pixel equals its target (l1 is differentiable there) and no dL/dpixel is
// near 0.
Image shifted_target(const Scene& s) {
  Image t = render(device(), s, {Precision::f64});
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.03f, 0.08f);
  std::bernoulli_distribution sign(0.5);
  for (float& v : t.pixels) v += sign(rng) ? u(rng) : -u(rng);
  return t;
}

// Every 5th voxel and the largest entry of the gradient.
std::vector<std::size_t> every_fifth_and_largest(const std::vector<float>& g) {
  std::vector<std::size_t> picks;
  std::size_t largest = 0;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (i % 5 == 0) picks.push_back(i);
    if (std::abs(g[i]) > std::abs(g[largest])) largest = i;
  }
  picks.push_back(largest);
  return picks;
}

// The adjoint's density, TF and background gradients at the given precision and loss.
AdjointGradient gradient_of(const Scene& s, const Image& target, Precision p, Loss loss) {
  AdjointOptions o;
  o.precision = p;
  o.loss = loss;
  o.tf = o.background = true;
  return adjoint(device(), s, target, o);
}

// float64 central differences of the loss: density at the given voxels, every TF parameter, the
// background (the same layout as a AdjointGradient's).
struct Differences {
  std::vector<std::size_t> voxels;
  std::vector<double> density, tf, background;
};

Differences differences(const Scene& s, const Image& target, Loss loss,
                        const std::vector<std::size_t>& voxels) {
  Differences d;
  d.voxels = voxels;
  for (std::size_t i : voxels)  // 2^-12: d ± h stays exact in float32 (nudge_voxel measures it)
    d.density.push_back(central_difference(
        s, target, 1.0 / 4096, [&](Scene& x, double h) { return nudge_voxel(x, i, h); }, 0, loss));
  const auto shape = tf_gradient_shape(s.tf);
  for (std::size_t r = 0; r < shape[0]; ++r)
    for (std::size_t c = 0; c < shape[1]; ++c)
      d.tf.push_back(central_difference(
          s, target, 1e-6, [&](Scene& x, double h) { return nudge_tf(x, r, c, h); }, 0, loss));
  for (int c = 0; c < (s.model == Model::absorption ? 1 : 3); ++c)
    d.background.push_back(central_difference(
        s, target, 1e-6, [&](Scene& x, double h) { return nudge_background(x, c, h); }, 0, loss));
  return d;
}

// The gradient against the differences, within `tolerance` of the largest entry of each group
// (no NaN/Inf). Returns the worst error relative to that entry.
double worst_against(const AdjointGradient& g, const Differences& d, double tolerance,
                     const std::string& label) {
  EXPECT_TRUE(all_finite(g)) << label;
  double worst = 0;
  const auto check = [&](double got, double want, double scale, const std::string& what) {
    worst = std::max(worst, std::abs(got - want) / scale);
    EXPECT_NEAR(got, want, tolerance * scale) << label << " " << what;
  };
  const double scale = max_abs(g.density);
  EXPECT_GT(scale, 0) << label;
  for (std::size_t k = 0; k < d.voxels.size(); ++k)
    check(g.density[d.voxels[k]], d.density[k], scale, "voxel " + std::to_string(d.voxels[k]));
  EXPECT_EQ(g.tf.size(), d.tf.size()) << label;
  for (std::size_t k = 0; k < std::min(g.tf.size(), d.tf.size()); ++k)
    check(g.tf[k], d.tf[k], max_abs(g.tf), "tf element " + std::to_string(k));
  EXPECT_EQ(g.background.size(), d.background.size()) << label;
  for (std::size_t k = 0; k < std::min(g.background.size(), d.background.size()); ++k)
    check(g.background[k], d.background[k], max_abs(g.background),
          "background " + std::to_string(k));
  return worst;
}

class AdjointFloat32VsFiniteDifferences
    : public ::testing::TestWithParam<std::tuple<TfKind, Model>> {};

// The float32 bound: 1e-3 of the largest entry against float64 differences.
TEST_P(AdjointFloat32VsFiniteDifferences, DensityTfAndBackground) {
  const auto [kind, model] = GetParam();
  const Scene s = small_scene(model, kind);
  const Image target = shifted_target(s);
  const std::string label =
      std::string(tf_kind_name(kind)) + (model == Model::absorption ? " abs" : " ea");
  const AdjointGradient g = gradient_of(s, target, Precision::f32, Loss::mse);
  const Differences d = differences(s, target, Loss::mse, every_fifth_and_largest(g.density));
  const double worst = worst_against(g, d, 1e-3, label);
  std::printf("[ measured ] f32 adjoint vs f64 differences, %s: %.2e\n", label.c_str(), worst);
}

INSTANTIATE_TEST_SUITE_P(
    Adjoint, AdjointFloat32VsFiniteDifferences,
    ::testing::Combine(::testing::Values(TfKind::identity, TfKind::piecewise_linear, TfKind::table,
                                         TfKind::gaussian),
                       ::testing::Values(Model::absorption, Model::emission_absorption)));

// The l1 loss (mean |image - target|, at points where no element equals its target): the loss
// value against the host's image_loss, the float64 gradient against differences to 1e-6 and the
// float32 one to 1e-3.
TEST(AdjointL1Loss, MatchesFiniteDifferences) {
  for (Model model : {Model::emission_absorption, Model::absorption}) {
    const Scene s = small_scene(model, TfKind::piecewise_linear);
    const Image target = shifted_target(s);
    const std::string label = model == Model::absorption ? "l1 abs" : "l1 ea";
    EXPECT_NEAR(loss_of(s, target, 0, Loss::l1),
                image_loss(render(device(), s, {Precision::f64}), target, Loss::l1), 1e-7)
        << label;  // the float32 image's rounding
    const AdjointGradient g64 = gradient_of(s, target, Precision::f64, Loss::l1);
    const Differences d = differences(s, target, Loss::l1, every_fifth_and_largest(g64.density));
    const double w64 = worst_against(g64, d, 1e-6, label);
    const double w32 =
        worst_against(gradient_of(s, target, Precision::f32, Loss::l1), d, 1e-3, label);
    std::printf("[ measured ] %s vs f64 differences: f64 %.2e, f32 %.2e\n", label.c_str(), w64,
                w32);
  }
}

// Two runs scatter the same contributions in a different order — compare-and-swap adds commit in
// whichever order the CPU threads running the work-groups reach them, and float addition is not
// associative — so the sums may differ in their last bits (not bitwise equal in general), never
// by more: 1e-5 of the largest entry in float32 (sums of ~1e3 terms, 6e-8 per add), 1e-12 in
// float64. A small volume seen by 24x24 rays from two sides makes every voxel a hot spot of
// compare-and-swap adds; the loss and background are summed on the host in pixel order: equal.
TEST(AdjointDeterminism, RunsAgreeWithinTheRoundingOfAtomicSums) {
  Scene s = small_scene(Model::emission_absorption, TfKind::piecewise_linear);
  s.volume = reference::smooth_volume(3, 3, 3, 4);
  for (float& d : s.volume.data) d = 0.15f + 0.7f * d;
  set_default_box(s);
  for (Camera& c : s.cameras) c.width = c.height = 24, c.fov_y = 30;
  const Image target = shifted_target(s);
  AdjointOptions o;
  o.tf = o.background = true;
  for (Precision p : {Precision::f32, Precision::f64}) {
    o.precision = p;
    const AdjointGradient first = adjoint(device(), s, target, o);
    ASSERT_TRUE(all_finite(first));
    double worst = 0;
    bool bitwise = true;
    for (int run = 0; run < 3; ++run) {
      const AdjointGradient again = adjoint(device(), s, target, o);
      const double e = std::max(relative_error(again.density, first.density),
                                relative_error(again.tf, first.tf));
      worst = std::max(worst, e);
      bitwise = bitwise && again.density == first.density && again.tf == first.tf;
      EXPECT_EQ(again.loss, first.loss);  // per-pixel terms, summed on the host in pixel order
      EXPECT_EQ(again.background, first.background);
      EXPECT_LE(e, p == Precision::f32 ? 1e-5 : 1e-12) << name(p) << " run " << run;
    }
    std::printf("[ measured ] determinism %s: max run-to-run difference %.2e (bitwise equal: %s)\n",
                name(p), worst, bitwise ? "yes" : "no");
  }
  // No lost updates: float32 within 1e-4 of float64. Each voxel here sums ~1e3 flushes, so one
  // lost contribution would be ~1e-3 of it; float32 rounding of sums that long reaches ~1e-5.
  o.precision = Precision::f64;
  const AdjointGradient g64 = adjoint(device(), s, target, o);
  o.precision = Precision::f32;
  const AdjointGradient g32 = adjoint(device(), s, target, o);
  const double ed = relative_error(g32.density, g64.density), et = relative_error(g32.tf, g64.tf);
  std::printf("[ measured ] contended sums f32 vs f64: density %.2e, tf %.2e\n", ed, et);
  EXPECT_LE(ed, 1e-4);
  EXPECT_LE(et, 1e-4);
}

// Absorption with the identity TF: log I = log I_in - a·N v is linear in the voxels. For a random
// direction dv, the adjoint's <dL/dv, dv> equals the directional central difference (L(v + e dv) -
// L(v - e dv)) / 2e of the float64 mse loss. Densities lie on a 2^-16 grid and e·dv on it too, so
// the perturbed volumes are exact in float32.
TEST(AdjointDotProduct, AbsorptionDirectionalDerivative) {
  Scene s = small_scene(Model::absorption, TfKind::identity);
  s.volume = reference::smooth_volume(9, 8, 7, 23);
  for (float& d : s.volume.data) d = float(std::round((0.15 + 0.7 * d) * 65536) / 65536);
  set_default_box(s);
  s.cameras.push_back(ortho({0.3, 1.8, 0.4}, {0, 0, 1}, 6, 5, 0.9));
  const Image target = shifted_target(s);
  AdjointOptions o;
  o.precision = Precision::f64;
  const AdjointGradient g = adjoint(device(), s, target, o);
  ASSERT_TRUE(all_finite(g));
  std::mt19937 rng(31);
  std::uniform_int_distribution<int> k(-8, 8);
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<int> dv(s.volume.data.size());
    for (int& x : dv) x = k(rng);
    const double e = 1.0 / 65536;
    double adjoint = 0, scale = 0;
    Scene plus = s, minus = s;
    for (std::size_t i = 0; i < dv.size(); ++i) {
      adjoint += double(g.density[i]) * dv[i];
      scale += std::abs(double(g.density[i]) * dv[i]);
      plus.volume.data[i] = float(s.volume.data[i] + e * dv[i]);
      minus.volume.data[i] = float(s.volume.data[i] - e * dv[i]);
      ASSERT_EQ(double(plus.volume.data[i]) - s.volume.data[i], e * dv[i]);
      ASSERT_EQ(s.volume.data[i] - double(minus.volume.data[i]), e * dv[i]);
    }
    const double fd = (loss_of(plus, target) - loss_of(minus, target)) / (2 * e);
    std::printf("[ measured ] dot product trial %d: <g, dv> %.12e, difference %.12e, rel %.2e\n",
                trial, adjoint, fd, std::abs(adjoint - fd) / scale);
    // g.density is float32 (6e-8 of each entry); the rest is the difference's O(e²) term.
    EXPECT_NEAR(adjoint, fd, 1e-6 * scale) << "trial " << trial;
  }
}

// Targets of the wrong shape or with NaN/Inf: invalid_argument naming the problem, whatever the
// precision.
TEST(AdjointBadInput, TargetOfTheWrongShape) {
  const Scene s = small_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image good = render(device(), s);  // (2, 5, 6, 4)
  const auto expect_shape_error = [&](Image t, const std::string& what) {
    for (Precision p : {Precision::f32, Precision::f64}) {
      AdjointOptions o;
      o.precision = p;
      try {
        adjoint(device(), s, t, o);
        ADD_FAILURE() << what << ": no error (" << name(p) << ")";
      } catch (const Error& e) {
        EXPECT_EQ(e.status(), Status::invalid_argument) << what;
        const std::string m = e.what();
        EXPECT_NE(m.find("target"), std::string::npos) << m;
        EXPECT_NE(m.find("(2, 5, 6, 4)"), std::string::npos) << what << ": " << m;
      }
    }
  };
  Image t = good;
  t.views = 1;
  t.pixels.resize(t.pixels.size() / 2);
  expect_shape_error(t, "one view of two");
  t = good;
  std::swap(t.width, t.height);
  expect_shape_error(t, "width and height swapped");
  t = good;
  t.channels = 1;
  t.pixels.resize(t.pixels.size() / 4);
  expect_shape_error(t, "one channel of four");
  t = good;
  t.pixels.pop_back();
  expect_shape_error(t, "one element short");
  t = Image{};
  expect_shape_error(t, "empty");
}

TEST(AdjointBadInput, TargetNotFinite) {
  const Scene s = small_scene(Model::absorption, TfKind::identity);
  const Image good = render(device(), s);
  for (float bad : {NAN, INFINITY, -INFINITY})
    for (Precision p : {Precision::f32, Precision::f64}) {
      Image t = good;
      t.pixels[37] = bad;
      AdjointOptions o;
      o.precision = p;
      try {
        adjoint(device(), s, t, o);
        ADD_FAILURE() << bad << ": no error (" << name(p) << ")";
      } catch (const Error& e) {
        EXPECT_EQ(e.status(), Status::invalid_argument);
        const std::string m = e.what();
        EXPECT_NE(m.find("not finite"), std::string::npos) << m;
        EXPECT_NE(m.find("37"), std::string::npos) << "names the element: " << m;
      }
    }
}

}  // namespace
}  // namespace ivr::test
