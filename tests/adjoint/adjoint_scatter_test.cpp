// adjoint_scatter_test.cpp — the voxel scatter of the adjoint march: rays crossing cells up and
// down every axis, across faces, edges and corners, and with steps longer than a voxel (the
// kernel's general path), checked voxel by voxel against central differences in float64; and the
// atomics the scatter uses.
#include <gtest/gtest.h>

#include "runtime/runtime.hpp"

#include <cmath>
#include <random>

#include "adjoint/adjoint_support.hpp"

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

  AdjointOptions o;
  o.precision = Precision::f64;
  const AdjointGradient g = adjoint(device(), s, target, o);
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
  const AdjointGradient g32 = adjoint(device(), s, target, o);
  EXPECT_LE(relative_error(g32.density, g.density), 1e-4) << "step " << step;
}

// 0.3: several samples per cell, faces, edges and corners crossed one sample apart; 1.7: most
// steps jump over a cell.
INSTANTIATE_TEST_SUITE_P(Steps, AdjointScatter, ::testing::Values(0.3, 1.7));

// The scatter's atomics: the device's float atomic add where it reports cl_ext_float_atomics,
// else inline PTX on NVIDIA's OpenCL, else a compare-and-swap loop; $IVR_ATOMICS forces any the
// device offers ($IVR_FLOAT_ATOMICS=0, the older switch, the loop). Every one agrees with the
// default within the rounding of the atomic sums. Also the kernel built as OpenCL C 3.0 with
// IVR_FLOAT_ATOMICS=1 (the native add where the compiler has the feature, the loop where not).
TEST(AdjointAtomics, ReportedAndEveryOfferedPathAgrees) {
  const Scene s = walk_scene(0.3);
  const Image target = render(device(), s, {Precision::f64});
  const DeviceInfo& info = device().info();
  const bool opencl3 = info.version.rfind("OpenCL 3.", 0) == 0;
  AdjointOptions o;
  o.tf = true;
  for (Precision p : {Precision::f32, Precision::f64}) {
    o.precision = p;
    const bool f64 = p == Precision::f64;
    const double tolerance = f64 ? 1e-12 : 1e-5;
    const AdjointGradient g = adjoint(device(), s, target, o);
    const bool ext = f64 ? info.double_atomic_add : info.float_atomic_add;
    const bool ptx = info.nv_compute_capability >= (f64 ? 60 : 20);
    EXPECT_EQ(g.atomics, ext ? "cl_ext_float_atomics" : ptx ? "ptx" : "compare-and-swap")
        << name(p);
    std::vector<std::pair<std::string, std::string>> forced = {{"cas", "compare-and-swap"}};
    if (ext) forced.push_back({"ext", "cl_ext_float_atomics"});
    if (ptx) forced.push_back({"ptx", "ptx"});
    for (const auto& [value, reported] : forced) {
      ScopedEnv force("IVR_ATOMICS", value);
      const AdjointGradient c = adjoint(device(), s, target, o);
      EXPECT_EQ(c.atomics, reported);
      EXPECT_LE(relative_error(c.density, g.density), tolerance) << name(p) << " " << value;
      EXPECT_LE(relative_error(c.tf, g.tf), tolerance) << name(p) << " " << value;
    }
    {
      ScopedEnv cas("IVR_FLOAT_ATOMICS", "0");
      EXPECT_EQ(adjoint(device(), s, target, o).atomics, "compare-and-swap");
    }
    if (opencl3) {
      ScopedEnv build("IVR_BUILD_OPTIONS", "-cl-std=CL3.0 -DIVR_FLOAT_ATOMICS=1");
      const AdjointGradient c = adjoint(device(), s, target, o);
      EXPECT_LE(relative_error(c.density, g.density), tolerance) << name(p);
      EXPECT_LE(relative_error(c.tf, g.tf), tolerance) << name(p);
    }
  }
}

// Forcing a path the device lacks, or one that does not exist, is one clear error.
TEST(AdjointAtomics, ForcingAnAbsentPathIsAClearError) {
  const Scene s = walk_scene(0.3);
  const Image target = render(device(), s, {Precision::f32});
  const DeviceInfo& info = device().info();
  if (info.nv_compute_capability < 20) {
    ScopedEnv force("IVR_ATOMICS", "ptx");
    try {
      adjoint(device(), s, target, {});
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_TRUE(has(e.what(), "IVR_ATOMICS=ptx: " + info.name + " has no inline-PTX float32"))
          << e.what();
    }
  }
  ScopedEnv force("IVR_ATOMICS", "fast");
  try {
    adjoint(device(), s, target, {});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "IVR_ATOMICS must be auto, ext, ptx or cas, got 'fast'")) << e.what();
  }
}

// The choice itself, on devices this machine does not have: cl_ext_float_atomics first, then
// NVIDIA's PTX by compute capability (float64 adds need sm_60), then the loop.
TEST(AdjointAtomics, SelectionOrderOnEveryKindOfDevice) {
  ScopedEnv neutral("IVR_ATOMICS", "auto");
  DeviceInfo plain;
  plain.name = "plain";
  EXPECT_EQ(atomic_add_for(plain, false), AtomicAdd::compare_and_swap);
  DeviceInfo ext = plain;
  ext.float_atomic_add = true;
  EXPECT_EQ(atomic_add_for(ext, false), AtomicAdd::ext_float_atomics);
  EXPECT_EQ(atomic_add_for(ext, true), AtomicAdd::compare_and_swap);
  DeviceInfo hopper = plain;
  hopper.nv_compute_capability = 90;
  EXPECT_EQ(atomic_add_for(hopper, false), AtomicAdd::ptx);
  EXPECT_EQ(atomic_add_for(hopper, true), AtomicAdd::ptx);
  DeviceInfo maxwell = plain;
  maxwell.nv_compute_capability = 52;
  EXPECT_EQ(atomic_add_for(maxwell, false), AtomicAdd::ptx);
  EXPECT_EQ(atomic_add_for(maxwell, true), AtomicAdd::compare_and_swap);
  DeviceInfo both = hopper;
  both.float_atomic_add = both.double_atomic_add = true;
  EXPECT_EQ(atomic_add_for(both, true), AtomicAdd::ext_float_atomics);
  {
    ScopedEnv force("IVR_ATOMICS", "cas");
    EXPECT_EQ(atomic_add_for(both, false), AtomicAdd::compare_and_swap);
  }
  {
    ScopedEnv force("IVR_ATOMICS", "ptx");
    EXPECT_EQ(atomic_add_for(both, false), AtomicAdd::ptx);
    EXPECT_THROW(atomic_add_for(maxwell, true), Error);
  }
  EXPECT_STREQ(atomic_add_name(AtomicAdd::ptx), "ptx");
}

}  // namespace
}  // namespace ivr::test
