// adjoint_hard_cases_test.cpp — the adjoint where DiffDVR's inversion fails: float32 vs float64
// gradients and float64 vs central differences on walls, deep media, tiny steps, rays on faces and
// nodes, axis-aligned rays, a camera inside, early termination.
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>

#include "adjoint/adjoint_support.hpp"
#include "reference/compare.hpp"
#include "reference/reference.hpp"

namespace ivr::test {
namespace {

// float32 vs float64 adjoint, relative to the largest float64 entry (the bound).
constexpr double kF32Tolerance = 1e-5;
// float64 adjoint vs float64 central differences, relative to the largest entry.
constexpr double kFdTolerance = 1e-6;

// A cubic n³ volume in the default unit box with a smooth medium in [lo, hi], the
// emission–absorption model through a 3-point piecewise-linear TF whose extinctions are scaled by
// `extinction` (its last point lies beyond the data, so no sample sits on a kink), a coloured
// background, one 2x2 perspective view, early termination off.
Scene medium_scene(int n, double lo, double hi, double extinction) {
  Scene s = constant_scene(0.f, n, 2);
  const Volume v = reference::smooth_volume(n, n, n, 11);
  for (std::size_t i = 0; i < v.data.size(); ++i)
    s.volume.data[i] = float(lo + (hi - lo) * v.data[i]);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.1, 0.2, 0.3}, 0.1 * extinction},
                 {0.25, {0.9, 0.6, 0.2}, 1.0 * extinction},
                 {1.5, {0.3, 0.8, 1.0}, 3.0 * extinction}};
  s.background = glm::dvec3(0.3, 0.5, 0.7);
  Camera& c = s.cameras[0];
  c = Camera{};
  c.eye = {0.12, 0.07, 2.0};
  c.fov_y = 6;
  c.width = c.height = 2;
  return s;
}

// A target well away from the float64 render in every element, so that every dL/dpixel is far
// from 0 and the same in both precisions to ~1e-6. Emission–absorption: 0.15 to 0.3 below it
// (different per channel, so that the channels' gradients do not cancel). Absorption: 0, so that
// the loss scales with I² and its float64 differences resolve gradients of I ~ e^-30 too.
Image offset_target(const Scene& s, double step) {
  Image t = render_at(s, Precision::f64, step);
  for (std::size_t i = 0; i < t.pixels.size(); ++i)
    t.pixels[i] = s.model == Model::absorption ? 0.f : t.pixels[i] - 0.15f - 0.05f * float(i % 4);
  return t;
}

// Optical depth along every ray of the scene with its TF as it is (from the reference's
// absorption transmittance, so no float32 rounding), the largest of them.
double max_optical_depth(Scene s) {
  s.model = Model::absorption;
  s.background = glm::dvec3(1.0);
  double depth = 0;
  for (double t : reference::render(s, 1e-4)) depth = std::max(depth, -std::log(t));
  return depth;
}

// The smallest and largest chord of the scene's rays through the box.
void chords(const Scene& s, double* shortest, double* longest) {
  *shortest = INFINITY;
  *longest = 0;
  for (const Camera& c : s.cameras)
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        glm::dvec3 o, d;
        double t0, t1;
        reference::ray(c, x, y, &o, &d);
        if (!reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1)) continue;
        *shortest = std::min(*shortest, t1 - t0);
        *longest = std::max(*longest, t1 - t0);
      }
}

// The gradient (density, TF, background) of the scene against the target at one precision.
AdjointGradient gradient_at(const Scene& s, const Image& target, Precision p, double step) {
  AdjointOptions o;
  o.precision = p;
  o.step = step;
  o.tf = o.background = true;
  return adjoint(device(), s, target, o);
}

// float32 vs float64: no NaN/Inf anywhere, rays stopping at the same samples, and the max error
// of the density and TF gradients within kF32Tolerance of their largest float64 entry (plus
// FLT_MIN: entries ~e^-300 underflow in float32). The background's gradient sum_pixels dL/dI·T_end
// inherits T_end's float32 error — ~3e-5 relative behind a steep wall, where rounding a sample's
// position by 1e-7 voxel moves an optical depth of 80 per unit density — so it gets 1e-4 of
// itself. Returns the float64 gradient.
AdjointGradient expect_precisions_agree(const Scene& s, const Image& target, double step,
                                 const std::string& label, double f32_tolerance = kF32Tolerance,
                                 double background_tolerance = 1e-4) {
  const AdjointGradient g64 = gradient_at(s, target, Precision::f64, step);
  const AdjointGradient g32 = gradient_at(s, target, Precision::f32, step);
  EXPECT_TRUE(all_finite(g64)) << label << " f64";
  EXPECT_TRUE(all_finite(g32)) << label << " f32";
  EXPECT_EQ(g32.samples, g64.samples) << label << ": f32 and f64 rays stop at different samples";
  const double ed = relative_error(g32.density, g64.density);
  const double et = relative_error(g32.tf, g64.tf);
  double eb = 0;
  for (std::size_t c = 0; c < g64.background.size(); ++c)
    eb = std::max(eb, std::abs(g32.background[c] - g64.background[c]) /
                          std::max(std::abs(g64.background[c]), 1e-30));
  const double rays = double(s.cameras.size()) * s.cameras[0].width * s.cameras[0].height;
  const double floor = std::numeric_limits<float>::min();
  const auto shown = [&](double e, double scale) {  // all entries below FLT_MIN: not measurable
    char text[32];
    std::snprintf(text, sizeof text, scale < floor ? "(<FLT_MIN)" : "%.2e", e);
    return std::string(text);
  };
  std::printf(
      "[ measured ] %-34s f32 vs f64: density %s, tf %s, background %s (%.0f samples/ray)\n",
      label.c_str(), shown(ed, max_abs(g64.density)).c_str(), shown(et, max_abs(g64.tf)).c_str(),
      shown(eb, max_abs(g64.background)).c_str(), double(g64.samples) / rays);
  EXPECT_LE(ed, f32_tolerance + floor / max_abs(g64.density)) << label << " density";
  EXPECT_LE(et, f32_tolerance + floor / max_abs(g64.tf)) << label << " tf";
  EXPECT_LE(eb, background_tolerance) << label << " background";
  EXPECT_NEAR(g32.loss, g64.loss, 1e-5 * g64.loss + floor) << label;
  return g64;
}

// Voxels to difference: the largest gradient entry, entries at a few ranks below it, and (where
// there is one) a voxel the adjoint says does not matter, whose difference must vanish too.
std::vector<std::size_t> probe_voxels(const std::vector<float>& g) {
  std::vector<std::size_t> order(g.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return std::abs(g[a]) > std::abs(g[b]); });
  const std::size_t nonzero =
      std::size_t(std::count_if(g.begin(), g.end(), [](float v) { return v != 0.f; }));
  std::vector<std::size_t> picks;
  for (std::size_t rank : {std::size_t(0), nonzero / 16, nonzero / 4, nonzero / 2})
    if (rank < nonzero) picks.push_back(order[rank]);
  if (nonzero < g.size()) picks.push_back(order[nonzero]);
  return picks;
}

// float64 adjoint vs central differences of the float64 loss (density at probe voxels, every TF
// parameter, the background), within kFdTolerance of the largest entry of each group. The
// differences must not move a ray's early-termination point (central_difference checks).
void expect_matches_differences(const Scene& s, const Image& target, double step, const AdjointGradient& g,
                                const std::string& label) {
  std::uint64_t samples = 0;
  const double loss = loss_of(s, target, step, Loss::mse, &samples);
  ASSERT_EQ(samples, g.samples) << label;
  // What the loss's rounding (~16 ulp) makes of a difference with step h.
  const auto noise = [&](double h) { return 16 * DBL_EPSILON * loss / h; };
  double worst = 0;
  const double scale = max_abs(g.density);
  for (std::size_t i : probe_voxels(g.density)) {
    // 2^-20: a tiny step (sigma·step up to ~100 makes the loss curve fast) that float32
    // voxels near 1 still represent exactly.
    const double h = std::ldexp(1.0, -20);
    const double fd = central_difference(
        s, target, h, [&](Scene& x, double d) { return nudge_voxel(x, i, d); }, step);
    worst = std::max(worst, std::abs(g.density[i] - fd) / scale);
    EXPECT_NEAR(g.density[i], fd, kFdTolerance * scale + noise(h)) << label << " voxel " << i;
  }
  const auto shape = tf_gradient_shape(s.tf);
  const double tf_scale = max_abs(g.tf);
  for (std::size_t r = 0; r < shape[0]; ++r)
    for (std::size_t c = 0; c < shape[1]; ++c) {
      const double h = 1e-7 * std::max(1.0, std::abs(tf_parameter(s.tf, r, c)));
      const double fd = central_difference(
          s, target, h, [&](Scene& x, double d) { return nudge_tf(x, r, c, d); }, step);
      const double got = g.tf[r * shape[1] + c];
      worst = std::max(worst, std::abs(got - fd) / tf_scale);
      EXPECT_NEAR(got, fd, kFdTolerance * tf_scale + noise(h))
          << label << " tf row " << r << " column " << c;
    }
  for (std::size_t c = 0; c < g.background.size(); ++c) {
    const double fd = central_difference(
        s, target, 1e-6, [&](Scene& x, double d) { return nudge_background(x, int(c), d); }, step);
    EXPECT_NEAR(g.background[c], fd, kFdTolerance * std::abs(fd) + noise(1e-6))
        << label << " background " << c;
  }
  std::printf("[ measured ] %-34s f64 vs differences: %.2e\n", label.c_str(), worst);
}

std::string with_termination(const std::string& label, double min_transmittance) {
  return label + (min_transmittance > 0 ? ", stop 1e-4" : ", no stop");
}

// A wall two voxels thick (density 1 on planes z = 3 and 4 of an 8³ volume, so the samples
// between them see d = 1 exactly) in a thin medium: sigma(1)·Δ = 20 and 80 exactly for the samples
// in the wall (optical depth ~150 and ~590 across it, ramps included): light from behind is gone.
// Parallel oblique rays all cross the box from face z = 0.5 to z = -0.5: one chord, one Δ.
TEST(AdjointHardCases, ThinWall) {
  for (double sigma_step : {20.0, 80.0})
    for (double stop : {0.0, 1e-4}) {
      Scene s = medium_scene(8, 0.05, 0.2, 4.0);
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x)
          for (int z : {3, 4}) s.volume.data[(std::size_t(z) * 8 + y) * 8 + x] = 1.f;
      s.cameras = {ortho({0.3, 0.2, 2}, {0, 1, 0}, 2, 2, 0.2)};
      const double step = 0.25;
      double chord, longest;
      chords(s, &chord, &longest);
      ASSERT_NEAR(chord, longest, 1e-12);
      const double dt = chord / std::ceil(chord / (step / 8));
      // sigma(1) = e1 + (e2 - e1)·0.75 / 1.25 with e1 = 4 must be sigma_step / dt.
      s.tf.points[2].extinction = 4.0 + (sigma_step / dt - 4.0) / 0.6;
      s.integrator.min_transmittance = stop;
      char label[64];
      std::snprintf(label, sizeof label, "wall sigma*step %.0f", sigma_step);
      const Image target = offset_target(s, step);
      const AdjointGradient g = expect_precisions_agree(s, target, step, with_termination(label, stop));
      EXPECT_GT(max_abs(g.density), 0);
      expect_matches_differences(s, target, step, g, with_termination(label, stop));
    }
}

// A smooth medium with total optical depth 10, 30, 300 and 3000 along the deepest of four rays,
// sampled ~400 times per ray (docs/design.md's float32 experiment with DiffDVR's division by 1 - alpha:
// errors of 8e-4 at depth 10 and 6e5 at 30), both models, early termination off and on.
TEST(AdjointHardCases, TotalOpticalDepth) {
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (double depth : {10.0, 30.0, 300.0, 3000.0})
      for (double stop : {0.0, 1e-4}) {
        Scene s = medium_scene(8, 0.1, 0.9, 1.0);
        s.model = model;
        if (model == Model::absorption) s.background = glm::dvec3(0.8);
        const double k = depth / max_optical_depth(s);
        for (TfPoint& p : s.tf.points) p.extinction *= k;
        s.integrator.min_transmittance = stop;
        double shortest, longest;
        chords(s, &shortest, &longest);
        const double step = longest / 400 * 8;  // voxel units (h = 1/8)
        char label[64];
        std::snprintf(label, sizeof label, "depth %g %s", depth,
                      model == Model::absorption ? "abs" : "ea");
        const Image target = offset_target(s, step);
        const AdjointGradient g = expect_precisions_agree(s, target, step, with_termination(label, stop));
        // (Without termination, absorption gradients ~I² ~ e^-2·depth underflow beyond ~50.)
        if (model == Model::emission_absorption || depth < 100 || stop > 0)
          EXPECT_GT(max_abs(g.density), 0) << label;
        expect_matches_differences(s, target, step, g, with_termination(label, stop));
      }
}

// Tiny steps: >= 1e5 samples on every ray of a 2x2 image through a medium of depth ~4.
TEST(AdjointHardCases, HundredThousandSamplesPerRay) {
  for (Model model : {Model::emission_absorption, Model::absorption}) {
    Scene s = medium_scene(6, 0.1, 0.9, 1.0);
    s.model = model;
    const double k = 4.0 / max_optical_depth(s);
    for (TfPoint& p : s.tf.points) p.extinction *= k;
    double shortest, longest;
    chords(s, &shortest, &longest);
    const double step = shortest / 1e5 * 6;
    const Image target = offset_target(s, step);
    const std::string label =
        model == Model::absorption ? "1e5 samples/ray abs" : "1e5 samples/ray ea";
    const AdjointGradient g = expect_precisions_agree(s, target, step, label);
    EXPECT_GE(g.samples, 4e5);
    expect_matches_differences(s, target, step, g, label);
  }
}

// Orthographic rays down -z lying exactly (every coordinate a dyadic fraction) on the lines
// through voxel centres, where samples hit grid nodes (step 1: every sample is a node), on voxel
// faces (cell boundaries), and on the box's own face x = 0.5 (the clamped border), on random
// non-smooth data.
TEST(AdjointHardCases, RaysAlongFacesAndThroughGridNodes) {
  Scene s = medium_scene(8, 0.1, 0.9, 3.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.1f, 0.9f);
  for (float& d : s.volume.data) d = u(rng);
  // 2x2 pixels 0.125 apart: pixel centres at eye.xy ± 0.0625 (h = 0.125, centres at odd/16).
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 2, 2, 0.25),            // all four on node lines
               ortho({0.0625, 0.0625, 2}, {0, 1, 0}, 2, 2, 0.25),  // all four on voxel faces
               ortho({0.4375, 0, 2}, {0, 1, 0}, 2, 2, 0.25),   // x = 0.375 (face), 0.5 (box face)
               ortho({0, 0.0625, 2}, {0, 1, 0}, 2, 2, 0.25)};  // x on nodes, y on faces
  for (Camera& c : s.cameras) c.target = {c.eye.x, c.eye.y, 0};
  for (double step : {1.0, 0.5, 0.3}) {
    const Image target = offset_target(s, step);
    char label[64];
    std::snprintf(label, sizeof label, "faces and nodes step %.1f", step);
    const AdjointGradient g = expect_precisions_agree(s, target, step, label);
    expect_matches_differences(s, target, step, g, label);
  }
}

// Rays along the axes (direction components exactly 0) from all six sides, orthographic and
// perspective (the centre pixel of an odd image), on random data in a non-cubic volume.
TEST(AdjointHardCases, AxisAlignedRays) {
  Scene s = medium_scene(6, 0.1, 0.9, 3.0);
  s.volume = reference::smooth_volume(6, 5, 4, 2);
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> u(0.1f, 0.9f);
  for (float& d : s.volume.data) d = u(rng);
  set_default_box(s);
  s.cameras.clear();
  const glm::dvec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int a = 0; a < 3; ++a)
    for (double side : {1.0, -1.0})
      for (Projection proj : {Projection::orthographic, Projection::perspective}) {
        Camera c;
        c.eye = 2.0 * side * axes[a];
        c.up = axes[(a + 1) % 3];
        c.projection = proj;
        c.ortho_height = 0.5;
        c.fov_y = 10;
        c.width = c.height = 3;
        s.cameras.push_back(c);
      }
  // 0.2: chords of whole voxels over a step dividing them make length / step an integer, where a
  // count from each precision's own geometry would round to n or n + 1 (docs/design.md, sample
  // counts: both take the definition's).
  const double step = 0.2;
  const Image target = offset_target(s, step);
  const AdjointGradient g = expect_precisions_agree(s, target, step, "axis-aligned");
  expect_matches_differences(s, target, step, g, "axis-aligned");
}

// Eyes inside the box (perspective and orthographic): integration starts at the eye.
TEST(AdjointHardCases, CameraInsideTheVolume) {
  Scene s = medium_scene(7, 0.1, 0.9, 3.0);
  Camera& c = s.cameras[0];
  c.eye = {0.1, -0.05, 0.15};
  c.target = {-0.3, 0.1, -1};
  c.fov_y = 60;
  c.width = c.height = 4;
  Camera o = c;
  o.projection = Projection::orthographic;
  o.ortho_height = 0.2;
  s.cameras.push_back(o);
  const double step = 0.1;
  const Image target = offset_target(s, step);
  const AdjointGradient g = expect_precisions_agree(s, target, step, "camera inside");
  expect_matches_differences(s, target, step, g, "camera inside");
  // Every ray heads to -z from z <= 0.16, so plane z = 6 (trilinear support z > 0.29) gets nothing.
  for (int y = 0; y < 7; ++y)
    for (int x = 0; x < 7; ++x) EXPECT_EQ(g.density[(std::size_t(6) * 7 + y) * 7 + x], 0.f);
}

// With early termination the gradient is that of the truncated sum that was rendered: voxels
// beyond every ray's stopping point get exactly 0 (and changing them changes nothing), and the
// rest match the differences of the loss with termination on (checked not to move the stops).
TEST(AdjointHardCases, EarlyTerminationGradientIsThatOfTheRender) {
  Scene s = medium_scene(8, 0.1, 0.9, 1.0);
  const double k = 40.0 / max_optical_depth(s);  // T reaches 1e-4 about a quarter of the way in
  for (TfPoint& p : s.tf.points) p.extinction *= k;
  s.integrator.min_transmittance = 1e-4;
  const double step = 0.5;
  const Image target = offset_target(s, step);
  const AdjointGradient g = gradient_at(s, target, Precision::f64, step);
  ASSERT_TRUE(all_finite(g));
  Scene full = s;
  full.integrator.min_transmittance = 0;
  const AdjointGradient all = gradient_at(full, target, Precision::f64, step);
  EXPECT_LT(g.samples * 2, all.samples);  // the rays did stop early
  // The back planes (z = 0, 1: the rays enter at z = 0.5 and stop before z = 0) are untouched.
  for (int z : {0, 1})
    for (int i = 0; i < 64; ++i) EXPECT_EQ(g.density[std::size_t(z) * 64 + i], 0.f) << z;
  EXPECT_GT(max_abs(all.density), 0);
  expect_matches_differences(s, target, step, g, "early termination");
  // And the difference with termination off is a different gradient (the test would notice).
  EXPECT_GT(relative_error(g.density, all.density), 1e-3);
}

// --- Every integrator on the hard cases ------------------------------------------------------
// The same checks (float32 vs float64, float64 vs central differences) for the trapezoid and
// preintegrated schemes (emission–absorption) and the exact one (absorption).

Scene with_scheme(Scene s, Scheme scheme) {
  s.integrator.scheme = scheme;
  if (scheme == Scheme::exact) {
    s.model = Model::absorption;
    s.background = glm::dvec3(0.8);
  }
  return s;
}

// Samples at segment ends (trapezoid, preintegrated) also sit on the wall's ramps, where float32's
// rounding of a sample's position (~5e-7 voxel at u ~ 8) moves its density by ~4e-7 and its
// optical depth by σΔ·4e-7 ~ 3e-5 at σΔ = 80: the float32 gradient inherits that (the midpoint's
// samples all see d = 1 inside the wall, so its test holds 1e-5). The exact (absorption) scheme's
// wall is 40× thinner: its gradients scale with I² ~ e^−2τ, which float32 storage would flush.
void wall_case(Scheme scheme, double sigma_step, double stop) {
  if (scheme == Scheme::exact) sigma_step /= 40;
  Scene s = medium_scene(8, 0.05, 0.2, 4.0);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
      for (int z : {3, 4}) s.volume.data[(std::size_t(z) * 8 + y) * 8 + x] = 1.f;
  s.cameras = {ortho({0.3, 0.2, 2}, {0, 1, 0}, 2, 2, 0.2)};
  const double step = 0.25, dt = 1.0 / std::ceil(1.0 / (step / 8));
  s.tf.points[2].extinction = 4.0 + (sigma_step / dt - 4.0) / 0.6;  // σ(1)·dt = sigma_step
  s.integrator.min_transmittance = stop;
  s = with_scheme(s, scheme);
  const std::string label =
      std::string(scheme_name(scheme)) + " wall " + std::to_string(int(sigma_step));
  const Image target = offset_target(s, step);
  const AdjointGradient g = expect_precisions_agree(s, target, step, with_termination(label, stop),
                                             scheme == Scheme::exact ? kF32Tolerance : 1e-4);
  EXPECT_GT(max_abs(g.density), 0) << label;
  expect_matches_differences(s, target, step, g, with_termination(label, stop));
}

// The background's float32 gradient inherits the float32 error of e^−τ, ~τ·FLT_EPSILON relative.
// Absorption gradients scale with I² ~ e^−2τ: the exact scheme's deepest case is 300.
void depth_case(Scheme scheme, double depth, double stop) {
  Scene s = with_scheme(medium_scene(8, 0.1, 0.9, 1.0), scheme);
  const double k = depth / max_optical_depth(s);
  for (TfPoint& p : s.tf.points) p.extinction *= k;
  s.integrator.min_transmittance = stop;
  double shortest, longest;
  chords(s, &shortest, &longest);
  const double step = longest / 400 * 8;
  const std::string label =
      std::string(scheme_name(scheme)) + " depth " + std::to_string(int(depth));
  const Image target = offset_target(s, step);
  const AdjointGradient g =
      expect_precisions_agree(s, target, step, with_termination(label, stop), kF32Tolerance,
                              std::max(1e-4, 4 * FLT_EPSILON * depth));
  if (s.model == Model::emission_absorption || depth < 100 || stop > 0)
    EXPECT_GT(max_abs(g.density), 0) << label;
  expect_matches_differences(s, target, step, g, with_termination(label, stop));
}

void grid_lines_case(Scheme scheme, double step) {
  Scene s = medium_scene(8, 0.1, 0.9, 3.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.1f, 0.9f);
  for (float& d : s.volume.data) d = u(rng);
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 2, 2, 0.25),
               ortho({0.0625, 0.0625, 2}, {0, 1, 0}, 2, 2, 0.25),
               ortho({0.4375, 0, 2}, {0, 1, 0}, 2, 2, 0.25)};
  for (Camera& c : s.cameras) c.target = {c.eye.x, c.eye.y, 0};
  s = with_scheme(s, scheme);
  const std::string label = std::string(scheme_name(scheme)) + " faces and nodes";
  const Image target = offset_target(s, step);
  const AdjointGradient g = expect_precisions_agree(s, target, step, label);
  expect_matches_differences(s, target, step, g, label);
}

void tiny_steps_case(Scheme scheme) {
  Scene s = with_scheme(medium_scene(6, 0.1, 0.9, 1.0), scheme);
  const double k = 4.0 / max_optical_depth(s);
  for (TfPoint& p : s.tf.points) p.extinction *= k;
  double shortest, longest;
  chords(s, &shortest, &longest);
  const double step = shortest / 1e5 * 6;
  const std::string label = std::string(scheme_name(scheme)) + " 1e5 samples/ray";
  const Image target = offset_target(s, step);
  const AdjointGradient g = expect_precisions_agree(s, target, step, label);
  expect_matches_differences(s, target, step, g, label);
}

const Scheme kNewSchemes[] = {Scheme::trapezoid, Scheme::preintegrated, Scheme::exact};

TEST(AdjointHardCases, EveryIntegratorOnAWallADeepMediumAndGridLines) {
  for (Scheme scheme : kNewSchemes) {
    wall_case(scheme, 80, 0);
    depth_case(scheme, scheme == Scheme::exact ? 30 : 3000, scheme == Scheme::exact ? 0 : 1e-4);
    grid_lines_case(scheme, 0.5);
  }
}

TEST(ExtendedAdjointHardCases, EveryIntegratorEveryCase) {
  for (Scheme scheme : kNewSchemes) {
    for (double sigma_step : {20.0, 80.0})
      for (double stop : {0.0, 1e-4}) wall_case(scheme, sigma_step, stop);
    for (double depth : {10.0, 30.0, 300.0, 3000.0})
      for (double stop : {0.0, 1e-4})
        if (scheme != Scheme::exact || (depth <= 300 && stop == 0)) depth_case(scheme, depth, stop);
    for (double step : {1.0, 0.3}) grid_lines_case(scheme, step);
    tiny_steps_case(scheme);
  }
}

}  // namespace
}  // namespace ivr::test
