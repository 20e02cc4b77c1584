// integrators_test.cpp — the integrators against their definitions and the continuous integral:
// preintegrated = the exact integral of the linear-density segments, exact = the continuous
// absorption integral at any step, trapezoid and preintegrated converge at second order.
#include <gtest/gtest.h>

#include <random>

#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A random 7x6x5 volume in an off-centre anisotropic box, two perspective views.
Scene random_scene(Model model, TfKind kind, Scheme scheme) {
  Scene s;
  s.volume.nx = 7, s.volume.ny = 6, s.volume.nz = 5;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) s.volume.data.push_back(float(u(rng)));
  s.box_min = {-0.4, -0.35, -0.2};
  s.box_max = {0.45, 0.3, 0.35};
  s.model = model;
  s.tf.kind = kind;
  s.tf.extinction_scale = 6;
  s.tf.color_scale = 0.9;
  s.tf.points = {{0.2, {0.1, 0.3, 0.9}, 0.0},
                 {0.45, {0.9, 0.5, 0.1}, 9.0},
                 {0.55, {0.2, 0.9, 0.3}, 2.0},
                 {0.8, {1, 1, 0.8}, 14.0}};
  s.tf.range = {0.15, 0.85};
  s.tf.entries = {{0.1, 0.2, 0.9, 0.0},
                  {0.9, 0.6, 0.2, 8.0},
                  {0.3, 0.8, 0.4, 1.5},
                  {1, 1, 1, 12},
                  {0.5, 0.5, 0.5, 3}};
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  Camera a, b;
  a.eye = {0.3, 0.4, 1.6};
  b.eye = {-1.4, 0.2, 0.5};
  a.width = b.width = 9;
  a.height = b.height = 8;
  a.fov_y = b.fov_y = 38;
  s.cameras = {a, b};
  s.integrator.scheme = scheme;
  s.integrator.min_transmittance = 0;
  return s;
}

double max_abs_diff(const std::vector<float>& a, const std::vector<double>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(double(a[i]) - b[i]));
  return m;
}

TEST(Preintegrated, IsTheExactIntegralOfLinearSegments) {
  for (Model model : {Model::absorption, Model::emission_absorption})
    for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table})
      for (double step : {0.37, 1.3}) {
        const Scene s = random_scene(model, kind, Scheme::preintegrated);
        const double h = reference::min_voxel_edge(s);
        const std::vector<double> want = reference::render_linear_segments(s, step * h);
        for (Precision p : {Precision::f64, Precision::f32}) {
          const Image got = render_at(s, p, step);
          const double e = max_abs_diff(got.pixels, want);
          EXPECT_LT(e, p == Precision::f64 ? 1e-6 : 2e-5)
              << name(p) << " model " << int(model) << " tf " << int(kind) << " step " << step;
          std::printf("model %d tf %d step %g %s: %.3g\n", int(model), int(kind), step, name(p), e);
        }
      }
}

}  // namespace
}  // namespace ivr::test

namespace ivr::test {
namespace {

TEST(Exact, IsTheContinuousAbsorptionIntegralAtAnyStep) {
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table}) {
    const Scene s = random_scene(Model::absorption, kind, Scheme::exact);
    const std::vector<double> want = reference::render_continuous(s);
    for (Precision p : {Precision::f64, Precision::f32})
      for (double step : {0.37, 5.0}) {
        const Image got = render_at(s, p, step);
        double e = 0;
        for (std::size_t i = 0; i < want.size(); ++i)
          e = std::max(e, std::abs(double(got.pixels[i]) - want[i]) / std::max(want[i], 1e-3));
        EXPECT_LT(e, p == Precision::f64 ? 1e-6 : 1e-5) << name(p) << " tf " << int(kind);
        std::printf("tf %d step %g %s: rel %.3g\n", int(kind), step, name(p), e);
      }
  }
}


// The exact scheme's traversal where it is easiest to get wrong: rays along the axes, lying in
// centre planes and on the lines where they meet (through every node), starting inside the box,
// on random data with a TF whose knots sit at voxel values.
TEST(Exact, AxisAlignedRaysRaysInCentrePlanesThroughNodesAndInside) {
  Scene s = random_scene(Model::absorption, TfKind::piecewise_linear, Scheme::exact);
  s.box_min = {-0.5, -0.5, -0.5};
  s.box_max = {0.5, 0.5, 0.5};
  s.volume = Volume{};
  s.volume.nx = s.volume.ny = s.volume.nz = 8;
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> u(0, 8);
  for (int i = 0; i < 512; ++i) s.volume.data.push_back(float(u(rng)) / 8.f);  // knots at k/8 hit
  s.tf.points = {{0.25, {0, 0, 0}, 0.0}, {0.5, {0, 0, 0}, 9.0}, {0.75, {0, 0, 0}, 3.0}};
  // h = 1/8: centre planes at odd multiples of 1/16. 2x2 pixels 1/8 apart around the eye.
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 2, 2, 0.25),              // on node lines
               ortho({0.0625, 0.0625, 2}, {0, 1, 0}, 2, 2, 0.25),    // on cell faces
               ortho({-2, 0.0625, 0}, {0, 0, 1}, 2, 2, 0.25),        // along x, in planes
               ortho({0.0625, -2, 0.0625}, {0, 0, 1}, 2, 2, 0.25)};  // along y
  s.cameras[0].target = {0, 0, 0}, s.cameras[1].target = {0.0625, 0.0625, 0};
  s.cameras[2].target = {0, 0.0625, 0}, s.cameras[3].target = {0.0625, 0, 0.0625};
  Camera inside;  // perspective from inside the box
  inside.eye = {0.1, -0.05, 0.15};
  inside.target = {-0.3, 0.1, -1};
  inside.fov_y = 60;
  inside.width = inside.height = 2;
  s.cameras.push_back(inside);
  const std::vector<double> want = reference::render_continuous(s);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Image got = render_at(s, p, 0.5);
    double e = 0;
    for (std::size_t i = 0; i < want.size(); ++i)
      e = std::max(e, std::abs(double(got.pixels[i]) - want[i]) / std::max(want[i], 1e-3));
    EXPECT_LT(e, p == Precision::f64 ? 1e-6 : 1e-5) << name(p);
  }
}

}  // namespace
}  // namespace ivr::test
