// render_hard_cases_test.cpp — the renderer on docs/design.md's hard cases: near-opaque media, 1e5
// samples per ray, grazing and axis-aligned rays, a camera inside, 1-voxel and all-zero volumes,
// density jumps and TF kinks; each judged against the CPU reference or a closed form.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "reference/compare.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using reference::all_finite;
using reference::close;
using test::name;
using test::render_at;

// test::constant_scene (default box, identity TF, one square image, no early termination) with
// a smooth anisotropic volume and a narrow perspective view instead.
Scene smooth_scene(int n, Model model, int image) {
  Scene s = test::constant_scene(0.f, 1, image);
  s.volume = reference::smooth_volume(n + 2, n, n - 1, 5);
  s.volume.spacing = {1.0, 1.2, 1.4};
  set_default_box(s);
  s.model = model;
  s.background = glm::dvec3(0.2, 0.3, 0.4);
  Camera& c = s.cameras[0];
  c = Camera{};  // perspective, looking at the origin
  c.eye = {0.3, 0.7, 1.9};
  c.fov_y = 20;
  c.width = c.height = image;
  return s;
}

// Constant medium, sigma*step = 100 per sample and optical depth 1e3 through the unit box. For
// constant sigma and colour alpha compositing is exact: C = c (1 - e^-1000) + e^-1000 B = c.
TEST(RenderHardCases, NearOpaqueConstantSaturates) {
  Scene s = test::constant_scene(1.f, 4, 4);  // ortho down -z, L = 1, h = 0.25
  s.tf.extinction_scale = 1000;
  s.tf.color_scale = 0.7;
  for (Model model : {Model::absorption, Model::emission_absorption}) {
    s.model = model;
    s.background = glm::dvec3(model == Model::absorption ? 1.0 : 0.3);
    for (Precision p : {Precision::f32, Precision::f64}) {
      const Image img = render_at(s, p, 0.4);  // 0.4 voxel = 0.1 world: sigma*step = 100
      ASSERT_TRUE(all_finite(img)) << name(p);
      for (std::size_t i = 0; i < img.pixels.size(); ++i) {
        const int c = int(i % img.channels);
        const double want = model == Model::absorption ? 0.0 : (c == 3 ? 1.0 : 0.7);
        EXPECT_NEAR(img.pixels[i], want, 1e-6) << name(p) << " element " << i;
      }
    }
  }
}

// The same depth on a varying medium, sampled finely enough (sigma*step <= 0.05) to converge:
// saturation must be reached and the colour must match the reference's front-surface colour.
TEST(RenderHardCases, NearOpaqueVaryingMatchesReference) {
  Scene s = smooth_scene(5, Model::emission_absorption, 2);
  s.tf.extinction_scale = 1000;  // depths of several hundred
  const double h = reference::min_voxel_edge(s);
  const double kernel_step = 5e-5 / h;  // world step 5e-5
  const auto want = reference::render(s, 1e-5);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image img = render_at(s, p, kernel_step);
    std::printf("[ measured ] opaque varying %s: max %.3e\n", name(p),
                reference::max_abs_diff(img, want));
    EXPECT_TRUE(close(img, want, 1e-4, 1e-4)) << name(p);
    for (int px = 0; px < 4; ++px) EXPECT_NEAR(img.pixels[px * 4 + 3], 1.0, 1e-6);
  }
  // A coarse step (sigma*step up to ~100) stays finite, saturated and a convex mix of colours.
  for (Precision p : {Precision::f32, Precision::f64}) {
    const Image img = render_at(s, p, 0.5);
    ASSERT_TRUE(all_finite(img)) << name(p);
    for (int px = 0; px < 4; ++px) {
      EXPECT_NEAR(img.pixels[px * 4 + 3], 1.0, 1e-5) << name(p);
      for (int c = 0; c < 3; ++c) {
        EXPECT_GE(img.pixels[px * 4 + c], 0.0f);
        EXPECT_LE(img.pixels[px * 4 + c], 1.0f + 1e-6f);  // colour = d <= 1
      }
    }
  }
}

// 1e5 samples per ray on a tiny image: f64 keeps the reference's accuracy; f32 accumulates
// rounding over 1e5 steps (measured up to 6e-5 for emission-absorption, well below the
// worst case 1e5 * 6e-8), bounded here at 2e-4 + 1e-4 relative.
TEST(RenderHardCases, TinyStepsHundredThousandSamples) {
  for (Model model : {Model::absorption, Model::emission_absorption}) {
    Scene s = smooth_scene(5, model, 2);
    s.tf.extinction_scale = 4;
    s.tf.color_scale = 1.3;
    // The step puts >= 1e5 samples on the shortest of the four chords.
    double shortest = 1e9;
    for (int px = 0; px < 4; ++px) {
      glm::dvec3 o, d;
      double t0, t1;
      reference::ray(s.cameras[0], px % 2, px / 2, &o, &d);
      ASSERT_TRUE(reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1));
      shortest = std::min(shortest, t1 - t0);
    }
    const double step = shortest / 1e5 / reference::min_voxel_edge(s);
    const auto want = reference::render(s, shortest / 4e5);
    for (Precision p : {Precision::f64, Precision::f32}) {
      RenderStats stats;
      const Image img = render_at(s, p, step, &stats);
      std::printf("[ measured ] tiny steps %s %s: max %.3e, samples/ray %.3g\n",
                  model == Model::absorption ? "abs" : "ea", name(p),
                  reference::max_abs_diff(img, want), double(stats.samples) / 4);
      EXPECT_GE(stats.samples, 4e5);
      if (p == Precision::f64)
        EXPECT_TRUE(close(img, want, 1e-7, 1e-6));
      else
        EXPECT_TRUE(close(img, want, 2e-4, 1e-4));
    }
  }
}

// Ortho rays down -z whose origins lie 1e-6 inside and outside the +x face: the inside ray runs
// its whole length through the clamped border half-voxel, the outside one sees the background.
TEST(RenderHardCases, RaysGrazingAFace) {
  Scene s = smooth_scene(5, Model::emission_absorption, 1);
  s.tf.extinction_scale = 3;
  const double eps = 1e-6;
  Camera c;
  c.projection = Projection::orthographic;
  c.eye = {s.box_max.x, 0.05, 2};  // pixel centres at x = box_max.x -/+ eps
  c.target = {s.box_max.x, 0.05, 0};
  c.ortho_height = 2 * eps;
  c.width = 2;
  c.height = 1;
  s.cameras = {c};
  const auto want = reference::render(s, 1e-4);
  ASSERT_GT(want[3], 0.1);  // the inside ray does cross the medium
  ASSERT_EQ(want[7], 0.0);  // the outside one misses
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image img = render_at(s, p, 0.01);
    EXPECT_TRUE(close(img, want, 2e-6, 2e-5)) << name(p);
  }
}

// Perspective rays fanning across a silhouette edge (the +x+y edge, seen from where only the +x
// face is visible): columns on one side cut the corner with chords from zero up, the rest miss.
TEST(RenderHardCases, RaysGrazingAnEdge) {
  Scene s = smooth_scene(5, Model::emission_absorption, 7);
  s.tf.extinction_scale = 5;
  Camera& c = s.cameras[0];
  const glm::dvec3 edge(s.box_max.x, s.box_max.y, 0.03);  // a point on the +x+y edge
  c.eye = edge + glm::dvec3(1.5, -0.3, 0.15);
  c.target = edge;
  c.up = {0, 0, 1};
  c.fov_y = 3;
  const auto want = reference::render(s, 1e-4);
  int hit = 0, miss = 0;
  for (std::size_t i = 3; i < want.size(); i += 4) (want[i] > 0 ? hit : miss)++;
  ASSERT_GT(hit, 5);
  ASSERT_GT(miss, 5);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image img = render_at(s, p, 0.01);
    std::printf("[ measured ] edge %s: max %.3e\n", name(p), reference::max_abs_diff(img, want));
    EXPECT_TRUE(close(img, want, 2e-6, 1e-4)) << name(p);
  }
}

// Rays along the axes (direction components exactly 0) from both sides, orthographic and
// perspective (the centre pixel of an odd image), on non-smooth random data.
TEST(RenderHardCases, AxisAlignedRays) {
  Scene s = smooth_scene(5, Model::emission_absorption, 3);
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (float& d : s.volume.data) d = u(rng);
  s.tf.extinction_scale = 3;
  s.cameras.clear();
  const glm::dvec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int a = 0; a < 3; ++a)
    for (double side : {1.0, -1.0})
      for (Projection proj : {Projection::orthographic, Projection::perspective}) {
        Camera c;
        c.eye = 2.0 * side * axes[a];
        c.target = {0, 0, 0};
        c.up = axes[(a + 1) % 3];
        c.projection = proj;
        c.ortho_height = 0.5;
        c.fov_y = 10;
        c.width = c.height = 3;
        s.cameras.push_back(c);
      }
  const auto want = reference::render(s, 2e-4);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image img = render_at(s, p, 0.005);
    std::printf("[ measured ] axis-aligned %s: max %.3e\n", name(p),
                reference::max_abs_diff(img, want));
    EXPECT_TRUE(close(img, want, 1e-5, 1e-4)) << name(p);
  }
}

// Eyes inside the box: integration starts at the eye, not at the (behind-the-eye) entry point.
TEST(RenderHardCases, CameraInsideTheVolume) {
  Scene s = smooth_scene(5, Model::emission_absorption, 5);
  s.tf.extinction_scale = 4;
  s.cameras[0].eye = {0.1, -0.05, 0.15};
  s.cameras[0].target = {-0.3, 0.1, -1};
  s.cameras[0].fov_y = 60;
  Camera ortho = s.cameras[0];
  ortho.projection = Projection::orthographic;
  ortho.ortho_height = 0.2;
  s.cameras.push_back(ortho);
  const auto want = reference::render(s, 1e-4);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image img = render_at(s, p, 0.005);
    EXPECT_TRUE(close(img, want, 2e-6, 5e-5)) << name(p);
  }
  // Looking the other way must see a different part of the medium.
  Scene back = s;
  back.cameras.resize(1);
  back.cameras[0].target = 2.0 * back.cameras[0].eye - s.cameras[0].target;
  const auto other = reference::render(back, 1e-4);
  EXPECT_GT(std::abs(other[3] - want[3]) + std::abs(other[0] - want[0]), 1e-3);
}

// One voxel: the density is that value everywhere in the (anisotropic) box, so an ortho view
// along z sees C = c (1 - e^{-sigma L}) + e^{-sigma L} B with L the box depth.
TEST(RenderHardCases, OneVoxelVolume) {
  Scene s;
  s.volume.nx = s.volume.ny = s.volume.nz = 1;
  s.volume.data = {0.6f};
  s.box_min = {-0.15, -0.5, -0.25};
  s.box_max = {0.15, 0.5, 0.25};
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::identity;
  s.tf.extinction_scale = 5;  // sigma = 3, sigma L = 1.5
  s.tf.color_scale = 1.5;     // colour = 0.9
  s.background = glm::dvec3(0.1, 0.2, 0.3);
  Camera c;
  c.projection = Projection::orthographic;
  c.eye = {0, 0, 3};
  c.ortho_height = 0.2;
  c.width = c.height = 2;
  s.cameras = {c};
  s.integrator.min_transmittance = 0;
  const double T = std::exp(-1.5);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image img = render_at(s, p, 0.5);
    ASSERT_TRUE(all_finite(img));
    for (int px = 0; px < 4; ++px) {
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(img.pixels[px * 4 + ch], 0.9 * (1 - T) + T * (*s.background)[ch], 2e-6)
            << name(p);
      EXPECT_NEAR(img.pixels[px * 4 + 3], 1 - T, 2e-6) << name(p);
    }
  }
  // And a perspective view through faces and edges against the reference.
  s.cameras[0].projection = Projection::perspective;
  s.cameras[0].eye = {0.5, 0.6, 1.2};
  s.cameras[0].fov_y = 50;
  s.cameras[0].width = s.cameras[0].height = 6;
  const auto want = reference::render(s, 1e-4);
  for (Precision p : {Precision::f64, Precision::f32})
    EXPECT_TRUE(close(render_at(s, p, 0.5), want, 2e-6, 2e-6)) << name(p);
}

// An all-zero volume (with TFs whose sigma(0) = 0) renders the background exactly.
TEST(RenderHardCases, AllZeroVolumeIsExactlyBackground) {
  Scene s = smooth_scene(5, Model::emission_absorption, 4);
  for (float& d : s.volume.data) d = 0;
  for (Model model : {Model::absorption, Model::emission_absorption})
    for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear}) {
      s.model = model;
      s.background = model == Model::absorption ? glm::dvec3(0.7) : glm::dvec3(0.1, 0.2, 0.3);
      s.tf.kind = kind;
      s.tf.points = {{0.0, {1, 1, 1}, 0}, {0.5, {1, 0, 0}, 10}};
      for (Precision p : {Precision::f32, Precision::f64}) {
        const Image img = render_at(s, p, 0.5);
        ASSERT_TRUE(all_finite(img));
        for (std::size_t i = 0; i < img.pixels.size(); ++i) {
          const int c = int(i % img.channels);
          const float want = c == 3 ? 0.f : float((*s.background)[c]);
          ASSERT_EQ(img.pixels[i], want) << name(p) << " element " << i;
        }
      }
    }
}

// Data with a jump (a half-empty volume with a dense block and a single hot voxel) through a TF
// with kinks and a jump (two points at one density). The integrand is discontinuous along the
// ray, so the step error is first order there: a fine step, and an error that must keep falling.
TEST(RenderHardCases, DensityJumpsAndTfKinks) {
  Scene s = smooth_scene(6, Model::emission_absorption, 6);
  const Volume& v = s.volume;
  for (int z = 0; z < v.nz; ++z)
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < v.nx; ++x)
        s.volume.data[(std::size_t(z) * v.ny + y) * v.nx + x] = x < v.nx / 2 ? 0.f : 0.8f;
  s.volume.data[(std::size_t(2) * v.ny + 3) * v.nx + 1] = 1.f;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.2, {0.2, 0.2, 0.9}, 0},
                 {0.5, {1, 0.3, 0.1}, 6},
                 {0.5, {0.1, 1, 0.2}, 1},
                 {0.9, {1, 1, 1}, 4}};
  s.cameras[0].fov_y = 40;
  const auto want = reference::render(s, 2e-5);
  double prev = 0;
  for (double step : {0.02, 0.005}) {
    for (Precision p : {Precision::f64, Precision::f32}) {
      const Image img = render_at(s, p, step);
      const double err = reference::max_abs_diff(img, want);
      std::printf("[ measured ] jumps %s step %.3f: max %.3e\n", name(p), step, err);
      EXPECT_TRUE(close(img, want, 2e-5 + 2e-3 * step, 0)) << name(p) << " step " << step;
      if (p == Precision::f64) {
        if (prev > 0) EXPECT_LT(err, prev / 2);
        prev = err;
      }
    }
  }
}

// A constant medium is integrated exactly by any quadrature whose steps add up to the chord
// (alpha compositing telescopes): checks the entry/exit handling at coarse steps that do not
// divide the chords, from rays of many lengths, against the closed forms.
TEST(RenderHardCases, ConstantMediumExactAtAnyStep) {
  Scene s = test::constant_scene(0.5f, 5, 6);
  s.box_min = {-0.5, -0.3, -0.4};  // anisotropic: h_min = 0.12 (y)
  s.box_max = {0.5, 0.3, 0.4};
  s.tf.extinction_scale = 4;  // sigma = 2
  s.tf.color_scale = 1.4;     // colour = 0.7
  s.cameras[0] = Camera{};
  s.cameras[0].eye = {0.7, 0.5, 1.4};
  s.cameras[0].fov_y = 50;
  s.cameras[0].width = s.cameras[0].height = 6;
  const glm::dvec3 bg(0.1, 0.2, 0.3);
  for (Model model : {Model::absorption, Model::emission_absorption}) {
    s.model = model;
    s.background = model == Model::absorption ? glm::dvec3(0.9) : bg;
    for (double step : {0.37, 1.3, 3.1})
      for (Precision p : {Precision::f64, Precision::f32}) {
        const Image img = render_at(s, p, step);
        ASSERT_TRUE(all_finite(img));
        for (int y = 0; y < 6; ++y)
          for (int x = 0; x < 6; ++x) {
            glm::dvec3 o, d;
            double t0 = 0, t1 = 0;
            reference::ray(s.cameras[0], x, y, &o, &d);
            const double T = reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1)
                                 ? std::exp(-2 * (t1 - t0))
                                 : 1.0;
            const float* px = &img.pixels[(y * 6 + x) * img.channels];
            const double tol = p == Precision::f64 ? 1e-6 : 1e-5;
            if (model == Model::absorption) {
              EXPECT_NEAR(px[0], 0.9 * T, tol) << name(p) << " step " << step << " pixel " << x;
            } else {
              for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(px[c], 0.7 * (1 - T) + T * bg[c], tol) << name(p) << " step " << step;
              EXPECT_NEAR(px[3], 1 - T, tol) << name(p) << " step " << step;
            }
          }
      }
  }
}

// The step is in units of the smallest voxel edge: the sample count matches the chords / step.
TEST(RenderHardCases, StepIsInUnitsOfTheSmallestVoxelEdge) {
  Scene s = smooth_scene(6, Model::absorption, 5);  // 8x6x5 voxels, spacing 1, 1.2, 1.4
  const double h = reference::min_voxel_edge(s);
  ASSERT_LT(h, std::min(s.voxel_size().y, s.voxel_size().z));
  for (double step : {0.25, 1.0}) {
    double expected = 0;
    int rays = 0;
    for (int y = 0; y < 5; ++y)
      for (int x = 0; x < 5; ++x) {
        glm::dvec3 o, d;
        double t0, t1;
        reference::ray(s.cameras[0], x, y, &o, &d);
        if (reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1))
          expected += (t1 - t0) / (step * h), ++rays;
      }
    RenderStats stats;
    EXPECT_TRUE(all_finite(render_at(s, Precision::f32, step, &stats)));
    // Any midpoint scheme takes ceil(L / step) samples per ray, or one more or less.
    EXPECT_GE(double(stats.samples), expected - rays) << step;
    EXPECT_LE(double(stats.samples), expected + 2 * rays) << step;
  }
}

}  // namespace
}  // namespace ivr
