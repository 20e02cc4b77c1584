// empty_space_support.hpp — scenes and checks shared by the empty-space skipping tests: a ball in
// a box of zeros, cameras that stress the skip, a sharp face past an empty brick, and renders and
// gradients with skipping compared with those without.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "ivr/core.hpp"
#include "test_support.hpp"

namespace ivr::test {

inline TransferFunction ramp_with_plateau() {  // σ = 0 up to density 0.2, then rising to 30 at 0.6
  TransferFunction tf;
  tf.kind = TfKind::piecewise_linear;
  tf.points = {
      {0.0, {0.1, 0.2, 0.3}, 0.0}, {0.2, {0.9, 0.5, 0.1}, 0.0}, {0.6, {1.0, 0.9, 0.8}, 30.0}};
  return tf;
}

// A ball of density rising to 1 at the centre in a box of zeros: most bricks empty.
inline Scene ball_scene(Model model, TfKind kind, int n = 48) {
  Scene s;
  s.volume.nx = s.volume.ny = s.volume.nz = n;
  s.volume.data.resize(std::size_t(n) * n * n);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        auto c = [&](int i) { return (i + 0.5) / n - 0.5; };  // in [-0.5, 0.5]
        const double r = std::sqrt(c(x) * c(x) + c(y) * c(y) + c(z) * c(z)) / 0.3;
        s.volume.data[(std::size_t(z) * n + y) * n + x] = float(std::max(0.0, 1.0 - r));
      }
  set_default_box(s);
  s.model = model;
  if (kind == TfKind::piecewise_linear) s.tf = ramp_with_plateau();
  if (kind == TfKind::identity) s.tf.extinction_scale = 40;
  if (kind == TfKind::table) {
    s.tf.kind = TfKind::table;
    s.tf.entries = {{0, 0, 0, 0}, {0.2, 0.5, 1, 0}, {1, 0.5, 0.2, 25}, {1, 1, 1, 40}};
  }
  s.integrator.step = 0.5;
  return s;
}

// The cameras that stress the skip: perspective from a corner, axis-aligned orthographic rays
// along brick faces (x = 8k cells), a camera inside the volume, a grazing diagonal.
inline std::vector<Camera> hard_cameras() {
  std::vector<Camera> c(4);
  c[0].eye = {1.1, 0.7, 1.6};
  c[1] = ortho({0, 0, 2}, {0, 1, 0}, 48, 48, 1.0);  // pixel centres on the face planes too
  c[2].eye = {0.05, -0.1, 0.2};                     // inside the box
  c[2].target = {0.4, 0.3, -0.3};
  c[3].eye = {1.5, 1.5, 0.01};
  for (Camera& cam : c) cam.width = cam.height = 48;
  return c;
}

// `saves`: also expect at least 10% fewer samples (not at steps as long as a brick, where the
// end-sample schemes find few samples inside one brick to drop).
inline void expect_same_render(const Scene& s, Precision p, int brick_size = 0, bool saves = true) {
  RenderOptions with, without;
  with.precision = without.precision = p;
  with.brick_size = brick_size;
  with.empty_space = EmptySpace::on;
  without.empty_space = EmptySpace::off;
  RenderStats a, b;
  const Image skip = render(device(), s, with, &a);
  const Image full = render(device(), s, without, &b);
  ASSERT_TRUE(a.skipped_empty);
  ASSERT_FALSE(b.skipped_empty);
  EXPECT_GT(a.empty_fraction, 0.2);
  if (saves) EXPECT_LT(double(a.samples), 0.9 * double(b.samples)) << "the skip saves samples";
  EXPECT_LE(a.samples, b.samples);
  const double tol = p == Precision::f64 ? 1e-12 : 2e-6;
  double worst = 0;
  for (std::size_t i = 0; i < skip.pixels.size(); ++i) {
    ASSERT_TRUE(std::isfinite(skip.pixels[i]));
    worst = std::max(worst, std::abs(double(skip.pixels[i]) - full.pixels[i]) /
                                (tol * (1 + std::abs(double(full.pixels[i])))));
  }
  EXPECT_LE(worst, 1.0) << name(p) << " " << a.variant;
}

// Voxels x <= 9 zero, dense from x = 10 on: mean + swing·sin(…).
inline void set_sharp_face(Scene& s, double mean, double swing) {
  const Volume& v = s.volume;
  for (int z = 0; z < v.nz; ++z)
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < v.nx; ++x)
        s.volume.data[(std::size_t(z) * v.ny + y) * v.nx + x] =
            x < 10 ? 0.f : float(mean + swing * std::sin(0.7 * x + 0.3 * y + 0.2 * z));
}

// Gradients with skipping equal those without, where gradient_may_skip allows it, and skipping is
// refused where it would change them (TF parameters; density under the identity TF).
inline void expect_same_gradient(const Scene& s, AdjointOptions o, double tol) {
  const Image target = [&] {
    Scene t = s;
    for (float& d : t.volume.data) d *= 0.93f;
    return render(device(), t, {o.precision, 0, EmptySpace::off});
  }();
  o.empty_space = EmptySpace::on;
  const AdjointGradient a = adjoint(device(), s, target, o);
  o.empty_space = EmptySpace::off;
  const AdjointGradient b = adjoint(device(), s, target, o);
  ASSERT_TRUE(a.skipped_empty);
  ASSERT_FALSE(b.skipped_empty);
  EXPECT_LT(a.samples, b.samples);
  EXPECT_NEAR(a.loss, b.loss, tol * b.loss);
  auto compare = [&](const auto& x, const auto& y, const char* what) {
    ASSERT_EQ(x.size(), y.size()) << what;
    double scale = 0;
    for (std::size_t i = 0; i < y.size(); ++i) scale = std::max(scale, std::abs(double(y[i])));
    ASSERT_GT(scale, 0) << what << " is all zero: the comparison would be vacuous";
    for (std::size_t i = 0; i < y.size(); ++i)
      ASSERT_NEAR(x[i], y[i], tol * (scale + std::abs(double(y[i])))) << what << "[" << i << "]";
  };
  if (o.density) compare(a.density, b.density, "density");
  if (o.background) compare(a.background, b.background, "background");
  if (o.camera) compare(a.camera, b.camera, "camera");
}

}  // namespace ivr::test
