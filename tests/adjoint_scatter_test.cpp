// adjoint_scatter_test.cpp — the voxel scatter of the adjoint march: rays crossing cells up and
// down every axis, across faces, edges and corners, and with steps longer than a voxel (the
// kernel's general path), checked voxel by voxel against central differences in float64; and the
// atomics the scatter uses.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "adjoint_support.hpp"

namespace ivr::test {
namespace {

// A random 5x4x6 volume seen by 14 perspective views: the 8 box diagonals
// (every sign combination of the three axes, so every crossing direction) and the 6 axis
// directions, slightly tilted so that rays also cross faces of the other axes.
Scene walk_scene(double step) {
  Scene s;
  s.volume.nx = 5;
  s.volume.ny = 4;
  s.volume.nz = 6;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.2, 0.8);
  for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) s.volume.data.push_back(float(u(rng)));
  set_default_box(s);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  // One linear segment over all densities: no control point for a difference to straddle.
  s.tf.points = {{0.0, {0.2, 0.3, 0.9}, 1.0}, {1.0, {0.9, 0.5, 0.1}, 6.0}};
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  Camera c;
  c.width = 5;
  c.height = 4;
  c.fov_y = 30;
  for (int sx : {-1, 1})
    for (int sy : {-1, 1})
      for (int sz : {-1, 1}) {
        c.eye = 1.4 * glm::dvec3(sx, sy, sz);
        s.cameras.push_back(c);
      }
  const glm::dvec3 axes[6] = {{2, 0.1, 0.15},  {-2, 0.15, -0.1}, {0.1, 2, 0.2},
                              {-0.2, -2, 0.1}, {0.15, -0.1, 2},  {0.1, 0.2, -2}};
  for (const glm::dvec3& eye : axes) {
    c.eye = eye;
    c.up = std::abs(eye.y) > 1 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    s.cameras.push_back(c);
  }
  s.integrator.step = step;
  s.integrator.min_transmittance = 0;
  return s;
}

class AdjointScatter : public ::testing::TestWithParam<double> {};

TEST_P(AdjointScatter, EveryVoxelMatchesCentralDifferences) {
  const double step = GetParam();
  const Scene s = walk_scene(step);
  Scene perturbed = s;
  for (std::size_t i = 0; i < perturbed.volume.data.size(); ++i)
    perturbed.volume.data[i] = float(perturbed.volume.data[i] * (1.0 + 0.25 * std::cos(3.0 * i)));
  const Image target = render(device(), perturbed, {Precision::f64});

  GradientOptions o;
  o.precision = Precision::f64;
  const Gradient g = gradient(device(), s, target, o);
  ASSERT_TRUE(all_finite(g));
  const double scale = max_abs(g.density);
  ASSERT_GT(scale, 0);
  for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) {
    const double fd = central_difference(s, target, 1.0 / 4096,
                                         [&](Scene& x, double h) { return nudge_voxel(x, i, h); });
    EXPECT_NEAR(g.density[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd))
        << "voxel " << i << " at step " << step;
  }

  // float32 scatters the same way: within float32 rounding of the float64 gradient.
  o.precision = Precision::f32;
  const Gradient g32 = gradient(device(), s, target, o);
  EXPECT_LE(relative_error(g32.density, g.density), 1e-4) << "step " << step;
}

// 0.3: several samples per cell, faces, edges and corners crossed one sample apart; 1.7: most
// steps jump over a cell.
INSTANTIATE_TEST_SUITE_P(Steps, AdjointScatter, ::testing::Values(0.3, 1.7));

// The scatter's atomics: the device's float atomic add where it reports cl_ext_float_atomics,
// else a compare-and-swap loop; $IVR_FLOAT_ATOMICS=0 forces the loop. The kernel built as OpenCL
// C 3.0 with IVR_FLOAT_ATOMICS=1 (the native add where the compiler has the feature, the loop
// where it does not) agrees with the default build within the rounding of the atomic sums.
TEST(AdjointAtomics, ReportedAndEveryBuildAgrees) {
  const Scene s = walk_scene(0.3);
  const Image target = render(device(), s, {Precision::f64});
  const bool opencl3 = device().info().version.rfind("OpenCL 3.", 0) == 0;
  GradientOptions o;
  o.tf = true;
  for (Precision p : {Precision::f32, Precision::f64}) {
    o.precision = p;
    const double tolerance = p == Precision::f32 ? 1e-5 : 1e-12;
    const Gradient g = gradient(device(), s, target, o);
    const bool native =
        p == Precision::f32 ? device().info().float_atomic_add : device().info().double_atomic_add;
    EXPECT_EQ(g.atomics, native ? "cl_ext_float_atomics" : "compare-and-swap") << name(p);
    {
      ScopedEnv cas("IVR_FLOAT_ATOMICS", "0");
      const Gradient c = gradient(device(), s, target, o);
      EXPECT_EQ(c.atomics, "compare-and-swap");
      EXPECT_LE(relative_error(c.density, g.density), tolerance) << name(p);
      EXPECT_LE(relative_error(c.tf, g.tf), tolerance) << name(p);
    }
    if (opencl3) {
      ScopedEnv build("IVR_BUILD_OPTIONS", "-cl-std=CL3.0 -DIVR_FLOAT_ATOMICS=1");
      const Gradient c = gradient(device(), s, target, o);
      EXPECT_LE(relative_error(c.density, g.density), tolerance) << name(p);
      EXPECT_LE(relative_error(c.tf, g.tf), tolerance) << name(p);
    }
  }
}

}  // namespace
}  // namespace ivr::test
