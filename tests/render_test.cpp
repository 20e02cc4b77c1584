// render_test.cpp — the OpenCL forward renderer against the independent CPU reference: every TF
// kind × optical model × projection, convergence order, early termination and real CT volumes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <tuple>

#include "reference/compare.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using reference::close;

TransferFunction make_tf(TfKind kind) {
  TransferFunction tf;
  tf.kind = kind;
  switch (kind) {
    case TfKind::identity:
      tf.extinction_scale = 6;
      tf.color_scale = 1.5;
      break;
    case TfKind::piecewise_linear:  // the data spans [0, 1]: both constant ends are exercised
      tf.points = {{0.1, {0.1, 0.1, 0.3}, 0.5}, {0.35, {0.9, 0.4, 0.1}, 5},
                   {0.6, {0.2, 0.8, 0.3}, 2}, {0.85, {1, 1, 1}, 9}};
      break;
    case TfKind::table:
      tf.range = {0.1, 0.9};
      tf.entries = {{0.1, 0.2, 0.9, 1}, {0.8, 0.2, 0.1, 6}, {0.3, 0.9, 0.3, 3},
                    {0.9, 0.9, 0.2, 8}, {1.0, 0.5, 0.5, 4}};
      break;
    case TfKind::gaussian:
      tf.gaussians = {{0.3, 0.12, {1, 0.3, 0.1}, 6}, {0.7, 0.1, {0.2, 0.5, 1}, 8}};
      break;
  }
  return tf;
}

// Three views of one anisotropic 9x7x5 volume; W != H so that the aspect ratio matters.
Scene smooth_scene(TfKind kind, Model model, Projection projection) {
  Scene s;
  s.volume = reference::smooth_volume(9, 7, 5, 11);
  s.volume.spacing = {1.0, 1.3, 1.7};
  set_default_box(s);
  s.model = model;
  s.tf = make_tf(kind);
  if (model == Model::emission_absorption) s.background = glm::dvec3(0.1, 0.2, 0.3);
  const glm::dvec3 eyes[3] = {{0.4, 0.5, 2.3}, {-2.2, 0.3, 0.6}, {1.2, -1.6, -1.3}};
  for (const glm::dvec3& eye : eyes) {
    Camera c;
    c.eye = eye;
    c.target = {0.02, -0.03, 0.01};
    c.fov_y = 38;
    c.projection = projection;
    c.ortho_height = 1.3;
    c.width = 10;
    c.height = 8;
    s.cameras.push_back(c);
  }
  s.integrator.min_transmittance = 0;
  return s;
}

Image render_at(const Scene& scene, Precision precision, double step, RenderStats* stats = nullptr) {
  RenderOptions o;
  o.precision = precision;
  o.step = step;
  return render(test::device(), scene, o, stats);
}

// Kernel step (voxels) for the accuracy comparisons: fine enough that its O(step^2) error, TF and
// trilinear kinks included, stays below the f64 tolerance; the reference goes 4x finer still.
constexpr double kFineStep = 0.001;
constexpr double kReferenceStep = 0.0005;

using Case = std::tuple<TfKind, Model, Projection>;
class RenderVsReference : public ::testing::TestWithParam<Case> {};

TEST_P(RenderVsReference, MatchesInF64AndF32) {
  const auto [kind, model, projection] = GetParam();
  const Scene s = smooth_scene(kind, model, projection);
  const auto want = reference::render(s, kReferenceStep * reference::min_voxel_edge(s));

  const Image f64 = render_at(s, Precision::f64, kFineStep);
  ASSERT_EQ(f64.views, 3);
  ASSERT_EQ(f64.height, 8);
  ASSERT_EQ(f64.width, 10);
  ASSERT_EQ(f64.channels, s.channels());
  std::printf("[ measured ] f64 max|diff| %.3g\n", reference::max_abs_diff(f64, want));
  // f64 output is stored as float32, so 1e-6 relative sits well above the storage rounding.
  EXPECT_TRUE(close(f64, want, 1e-7, 1e-6));

  // float32 kernel: thousands of samples per ray accumulate rounding of ~1e-7 each.
  const Image f32 = render_at(s, Precision::f32, kFineStep);
  std::printf("[ measured ] f32 max|diff| %.3g\n", reference::max_abs_diff(f32, want));
  EXPECT_TRUE(close(f32, want, 1e-5, 1e-4));

  // The views really differ (each camera is used, not the first one three times).
  const std::size_t per_view = want.size() / 3;
  double d01 = 0, d02 = 0;
  for (std::size_t i = 0; i < per_view; ++i) {
    d01 = std::max(d01, std::abs(want[i] - want[per_view + i]));
    d02 = std::max(d02, std::abs(want[i] - want[2 * per_view + i]));
  }
  EXPECT_GT(d01, 0.05);
  EXPECT_GT(d02, 0.05);
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  const char* kinds[] = {"identity", "piecewise_linear", "table", "gaussian"};
  return std::string(kinds[int(std::get<0>(info.param))]) +
         (std::get<1>(info.param) == Model::absorption ? "_absorption" : "_ea") +
         (std::get<2>(info.param) == Projection::perspective ? "_perspective" : "_orthographic");
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, RenderVsReference,
    ::testing::Combine(::testing::Values(TfKind::identity, TfKind::piecewise_linear, TfKind::table,
                                         TfKind::gaussian),
                       ::testing::Values(Model::absorption, Model::emission_absorption),
                       ::testing::Values(Projection::perspective, Projection::orthographic)),
    case_name);


// Second-order convergence of the midpoint scheme on a smooth volume + smooth TF: the f64 error
// against a near-exact reference must shrink by >= 3x per halving of the step (4x in theory).
void expect_second_order(const Scene& s, const char* what) {
  const auto want = reference::render(s, kReferenceStep * reference::min_voxel_edge(s));
  double prev_rms = 0, prev_max = 0;
  for (double step : {1.0, 0.5, 0.25, 0.125}) {
    const Image img = render_at(s, Precision::f64, step);
    ASSERT_TRUE(reference::all_finite(img));
    const double rms = reference::rms_diff(img, want), mx = reference::max_abs_diff(img, want);
    std::printf("[ measured ] %s step %.3f: rms %.3e max %.3e", what, step, rms, mx);
    if (prev_rms > 0) {
      std::printf("  ratios rms %.2f max %.2f", prev_rms / rms, prev_max / mx);
      EXPECT_GE(prev_rms / rms, 3.0) << what << " step " << step;
      EXPECT_GE(prev_max / mx, 3.0) << what << " step " << step;
    }
    std::printf("\n");
    prev_rms = rms, prev_max = mx;
  }
}

TEST(RenderConvergence, SecondOrderGaussianEmissionAbsorption) {
  expect_second_order(smooth_scene(TfKind::gaussian, Model::emission_absorption, Projection::perspective),
                      "gaussian ea");
}

TEST(RenderConvergence, SecondOrderIdentityAbsorption) {
  expect_second_order(smooth_scene(TfKind::identity, Model::absorption, Projection::orthographic),
                      "identity absorption");
}

// Early termination: once T < t the rest of the ray can add at most T * max(colour, background)
// to the colour and T to A, so the result stays within t * that of the full integral, and rays
// that never get that dark are untouched.
TEST(RenderEarlyTermination, SkipsSamplesWithinTheBound) {
  Scene s = smooth_scene(TfKind::identity, Model::emission_absorption, Projection::perspective);
  s.tf.extinction_scale = 60;  // optical depths of tens: most rays saturate
  s.tf.color_scale = 0.8;      // colour = 0.8 d <= 0.8
  const double t = 1e-3;
  RenderStats full_stats, early_stats;
  const Image full = render_at(s, Precision::f64, 0.05, &full_stats);
  s.integrator.min_transmittance = t;
  const Image early = render_at(s, Precision::f64, 0.05, &early_stats);
  ASSERT_TRUE(reference::all_finite(early));
  std::printf("[ measured ] samples full %llu, early %llu\n", (unsigned long long)full_stats.samples,
              (unsigned long long)early_stats.samples);
  EXPECT_LT(double(early_stats.samples), 0.7 * double(full_stats.samples));
  EXPECT_GT(early_stats.samples, 0u);
  const double bound = t * std::max(0.8, 0.3);  // max colour, max background channel
  int terminated = 0;
  for (std::size_t p = 0; p < full.pixels.size(); p += 4) {
    const bool dark = 1.0 - full.pixels[p + 3] < t;
    terminated += dark;
    for (int c = 0; c < 4; ++c) {
      const double diff = std::abs(double(early.pixels[p + c]) - full.pixels[p + c]);
      EXPECT_LE(diff, (c == 3 ? t : bound) + 1e-7) << "pixel " << p / 4 << " channel " << c;
      if (!dark) EXPECT_LE(diff, 1e-7) << "pixel " << p / 4 << " never reached T < t";
    }
  }
  EXPECT_GT(terminated, 20);  // the case is really exercised
  // The reference with the same rule agrees on the early-terminated image too.
  const auto want = reference::render(s, kReferenceStep * 20 * reference::min_voxel_edge(s), true);
  EXPECT_TRUE(close(early, want, 2 * bound, 0));
}

}  // namespace
}  // namespace ivr
