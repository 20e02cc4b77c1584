// reference_continuous_limits_test.cpp — render_continuous as the limit of the midpoint
// reference::render and of render_linear_segments (second order), render_linear_segments equal to
// it where the density is linear along every segment, near-opaque media, and a timing run.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <random>

#include "reference/compare.hpp"
#include "reference/continuous_checks.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using reference::max_diff;
using reference::near;
using reference::Pixels;
using reference::rms_diff;
using reference::x_profile_scene;

// A smooth random volume in an off-centre anisotropic box, a perspective and an oblique
// orthographic view, and one TF of each kind.
Scene smooth_scene(TfKind kind, Model model) {
  Scene s;
  s.volume = reference::smooth_volume(9, 8, 10, 11);
  s.box_min = {-0.3, -0.7, 0.1};
  s.box_max = {0.6, 0.2, 0.6};
  s.model = model;
  s.background = model == Model::absorption ? glm::dvec3(1.0) : glm::dvec3(0.1, 0.2, 0.3);
  s.integrator.min_transmittance = 0;
  const glm::dvec3 mid = 0.5 * (s.box_min + s.box_max);
  Camera p;
  p.eye = mid + glm::dvec3(0.9, 0.7, 1.3), p.target = mid, p.fov_y = 30;
  Camera o = test::ortho(mid + glm::dvec3(-1.5, 0.4, -0.7), {0, 1, 0}, 6, 5, 0.7);
  o.target = mid;
  p.width = 6, p.height = 5;
  s.cameras = {p, o};
  s.tf.kind = kind;
  switch (kind) {
    case TfKind::identity:
      s.tf.extinction_scale = 5, s.tf.color_scale = 0.8;
      break;
    case TfKind::piecewise_linear:
      s.tf.points = {{0.2, {0, 0, 0}, 0},
                     {0.45, {1, 0.5, 0}, 6},
                     {0.6, {0.2, 1, 0.3}, 2},
                     {0.85, {0.4, 0.4, 1}, 12}};
      break;
    case TfKind::table:
      s.tf.range = {0.1, 0.9};
      s.tf.entries = {{0, 0, 0, 0}, {1, 0, 0, 4}, {0, 1, 0, 1}, {0, 0, 1, 9}, {1, 1, 1, 3}};
      break;
    case TfKind::gaussian:
      s.tf.gaussians = {{0.35, 0.06, {1, 0.3, 0}, 15}, {0.7, 0.15, {0.2, 0.4, 1}, 6}};
      break;
  }
  return s;
}

// `approx(step)` converges to `exact` at second order over steps 0.4, 0.2, ..., 0.025 voxels:
// with a smooth integrand every halving divides the RMS difference by ~4; where the midpoint rule
// meets the kinks of piecewise-linear and table TFs single ratios scatter (where a kink falls
// between samples matters), so there the whole span must gain a factor >= 64 (4^4 = 256 at
// exact second order). Preintegration integrates across kinks exactly: smooth in every case.
template <class Approx>
void expect_second_order(const Scene& s, const Pixels& exact, Approx approx, bool smooth,
                         const char* what) {
  const double h = reference::min_voxel_edge(s);
  double rms[5];
  for (int k = 0; k < 5; ++k) rms[k] = rms_diff(approx(h * 0.4 / (1 << k)), exact);
  std::printf("  [%s, TF kind %d, model %d] RMS diffs %.3g .. %.3g, ratios", what, int(s.tf.kind),
              int(s.model), rms[0], rms[4]);
  for (int k = 0; k < 4; ++k) {
    std::printf(" %.2f", rms[k] / rms[k + 1]);
    EXPECT_GE(rms[k] / rms[k + 1], smooth ? 2.7 : 1.3) << what << " " << k;
    EXPECT_LE(rms[k] / rms[k + 1], smooth ? 5.5 : 12.0) << what << " " << k;
  }
  std::printf("\n");
  EXPECT_GE(rms[0] / rms[4], smooth ? 150.0 : 64.0) << what;
  EXPECT_LE(rms[0] / rms[4], 400.0) << what;
}

TEST(ReferenceContinuous, IsTheLimitOfTheMidpointReference) {
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
    for (Model model : {Model::absorption, Model::emission_absorption}) {
      const Scene s = smooth_scene(kind, model);
      expect_second_order(
          s, reference::render_continuous(s),
          [&](double step) { return reference::render(s, step); },
          kind == TfKind::identity || kind == TfKind::gaussian, "midpoint");
    }
}

TEST(ReferenceContinuous, IsTheLimitOfLinearSegments) {
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
    for (Model model : {Model::absorption, Model::emission_absorption}) {
      const Scene s = smooth_scene(kind, model);
      expect_second_order(
          s, reference::render_continuous(s),
          [&](double step) { return reference::render_linear_segments(s, step); }, true,
          "linear segments");
    }
}

// The sub-division is already converged: 8 times finer changes results by rounding only.
TEST(ReferenceContinuous, RefinementChangesNothing) {
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
    for (Model model : {Model::absorption, Model::emission_absorption}) {
      const Scene s = smooth_scene(kind, model);
      const Pixels a = reference::render_continuous(s);
      EXPECT_TRUE(
          near(a, reference::render_continuous(s, false, 8), 1e-14, 1e-14, "refinement x8"));
    }
}

// Where the density is linear along every segment, linear segments are the continuous integral.
TEST(ReferenceContinuous, LinearSegmentsExactWhereTheDensityIsLinear) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<float> vx(8);
  for (float& v : vx) v = u(rng);
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
    for (Model model : {Model::absorption, Model::emission_absorption}) {
      // (a) Any x-profile, rays along x, samples on every voxel-centre plane (steps h/2, h/6;
      // the slack keeps ceil() from adding a segment): each segment lies between two centres.
      Scene s = x_profile_scene(vx);
      const Scene tfs = smooth_scene(kind, model);
      s.tf = tfs.tf, s.model = model, s.background = tfs.background;
      s.cameras = {test::ortho({-2, 0, 0}, {0, 1, 0}, 5, 4, 0.9)};
      const double h = 1.0 / 8;
      Pixels exact = reference::render_continuous(s);
      for (int m : {2, 6})
        EXPECT_TRUE(
            near(reference::render_linear_segments(s, h / m * (1 + 1e-9)), exact, 1e-13, 1e-13))
            << int(kind) << " " << int(model) << " " << m;
      // Not vacuous: steps that straddle voxel centres differ. (Not h/3 or 0.4 h: there every
      // centre sits at the same fraction of its segment, and under the identity TF the trapezoid
      // errors, proportional to the slope changes, telescope to 0.)
      EXPECT_GT(max_diff(reference::render_linear_segments(s, 0.37 * h), exact), 1e-6)
          << int(kind) << " " << int(model);
      // (b) A volume linear in x, perspective rays that never reach the clamped x half-voxels:
      // the density is linear along each whole ray, so any step is exact (one segment included).
      std::vector<float> ramp(8);
      for (int i = 0; i < 8; ++i) ramp[i] = 0.125f + 0.09375f * i;
      Scene r = x_profile_scene(ramp);
      r.tf = s.tf, r.model = model, r.background = s.background;
      Camera c;
      c.eye = {0.02, -2, 0.03}, c.target = {0.02, 0, 0.03}, c.up = {0, 0, 1}, c.fov_y = 16;
      c.width = 5, c.height = 4;
      r.cameras = {c};
      exact = reference::render_continuous(r);
      for (double step : {0.37 * h, 2.3 * h, 10.0})
        EXPECT_TRUE(near(reference::render_linear_segments(r, step), exact, 1e-13, 1e-13))
            << int(kind) << " " << int(model) << " " << step;
    }
}

// Near-opaque media: sigma * voxel up to 100 and total depths up to ~1e3, then sigma * voxel up
// to 1e6: finite everywhere, the exact references agree, and the emission comes from the entry.
TEST(ReferenceContinuous, OpaqueMediaStayFiniteAndAccurate) {
  Scene s = test::constant_scene(0.f, 6, 4);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.6f, 1.f);
  for (float& v : s.volume.data) v = u(rng);
  s.model = Model::emission_absorption;
  s.tf.extinction_scale = 600;  // sigma * h = 100 at density 1
  s.tf.color_scale = 1.3;
  s.background = glm::dvec3(0.2, 0.5, 0.9);
  Camera diag;
  diag.eye = {1.6, 1.5, 1.7}, diag.fov_y = 25, diag.width = diag.height = 4;
  s.cameras = {diag, test::ortho({0.3, -2, 0.4}, {0, 0, 1}, 4, 4, 0.8),
               test::ortho({2, 2, 2}, {0, 1, 0}, 4, 4, 0.2)};
  const Pixels exact = reference::render_continuous(s);
  double max_depth = 0;
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) {
      glm::dvec3 o, d;
      reference::ray(s.cameras[2], x, y, &o, &d);
      max_depth = std::max(max_depth, reference::optical_depth(s, o, d));
    }
  std::printf("  [opaque] largest optical depth %.4g\n", max_depth);
  EXPECT_GT(max_depth, 700);
  for (double v : exact) EXPECT_TRUE(std::isfinite(v));
  for (std::size_t p = 0; p < exact.size() / 4; ++p) EXPECT_NEAR(exact[p * 4 + 3], 1, 1e-12);
  const double h = 1.0 / 6;
  double diff[4];
  for (int k = 0; k < 4; ++k)
    diff[k] = rms_diff(reference::render_linear_segments(s, h / (32 << k)), exact);
  std::printf("  [opaque, linear segments vs continuous] RMS %.3g %.3g %.3g %.3g\n", diff[0],
              diff[1], diff[2], diff[3]);
  for (int k = 0; k < 3; ++k) EXPECT_LT(diff[k + 1], diff[k]) << k;
  EXPECT_GT(diff[0] / diff[3], 16.0);  // second order over three halvings: ~64
  EXPECT_LT(diff[3], 1e-5);
  // sigma * voxel ~ 1e6: the first 1e-6 voxel decides; C = colour(d at entry) to ~1e-6.
  s.tf.extinction_scale = 6e6;
  for (Model model : {Model::emission_absorption, Model::absorption}) {
    s.model = model;
    const Pixels img = reference::render_continuous(s),
                 lin = reference::render_linear_segments(s, h);
    for (std::size_t i = 0; i < img.size(); ++i) {
      EXPECT_TRUE(std::isfinite(img[i]) && std::isfinite(lin[i])) << i;
      if (model == Model::absorption) {
        EXPECT_EQ(img[i], 0.0);
      }
    }
    if (model == Model::absorption) continue;
    for (int v = 0; v < 3; ++v)
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
          glm::dvec3 o, d;
          reference::ray(s.cameras[v], x, y, &o, &d);
          double t0, t1;
          ASSERT_TRUE(reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1));
          const double colour = 1.3 * reference::density(s, o + t0 * d + 1e-9 * d);
          const std::size_t p = ((v * 4 + y) * 4 + x) * 4;
          EXPECT_NEAR(img[p], colour, 1e-5);
          EXPECT_NEAR(img[p + 3], 1.0, 1e-15);
        }
  }
}

// Timing, not run by default (--gtest_also_run_disabled_tests): a 128 x 128 image of a 128^3
// Marschner-Lobb volume for every TF kind (the table with 256 entries) and both models.
TEST(ReferenceContinuous, DISABLED_Timing128) {
  const Volume volume = synthetic_volume("marschner_lobb", 128, 128, 128);
  for (TfKind kind : {TfKind::piecewise_linear, TfKind::table, TfKind::identity, TfKind::gaussian})
    for (Model model : {Model::absorption, Model::emission_absorption}) {
      Scene s = smooth_scene(kind, model);
      s.volume = volume;
      set_default_box(s);
      if (kind == TfKind::table) {
        s.tf.entries.clear();
        for (int i = 0; i < 256; ++i)
          s.tf.entries.push_back({0.5 + 0.5 * std::sin(i * 0.1), 0.5 + 0.5 * std::cos(i * 0.07),
                                  0.5, 8 * (1 + std::sin(i * 0.13))});
      }
      Camera c;
      c.eye = {1.2, 0.9, 1.6}, c.fov_y = 35, c.width = c.height = 128;
      s.cameras = {c};
      const auto start = std::chrono::steady_clock::now();
      const Pixels img = reference::render_continuous(s);
      const double sec =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("  TF kind %d model %d: render_continuous %.2f s\n", int(kind), int(model), sec);
      for (double v : img) ASSERT_TRUE(std::isfinite(v));
    }
}

}  // namespace
}  // namespace ivr
