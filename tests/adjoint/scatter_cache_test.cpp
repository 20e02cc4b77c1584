// scatter_cache_test.cpp — the work-group's local table that sums scatter adds before the global
// atomics (kernels/scatter_cache.cl), forced on and off: the back-projector stays the exact
// transpose of the projector and agrees with the uncached Nᵀ to rounding, the density gradient
// agrees with the uncached one (float32 and float64) and the deterministic one bit for bit, a
// table too small for the group's voxels (evicting, or not aggregating) still gives the right
// answer, and the switch itself.
#include "adjoint/scatter_cache.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "adjoint/adjoint_support.hpp"
#include "ivr/tomo.hpp"

namespace ivr::test {
namespace {

Volume random_volume(int nx, int ny, int nz, std::uint32_t seed) {
  Volume v;
  v.nx = nx, v.ny = ny, v.nz = nz;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.2, 0.8);
  for (std::size_t i = 0; i < v.voxel_count(); ++i) v.data.push_back(float(u(rng)));
  return v;
}

// Work-groups of neighbouring rays that share voxels: two perspective views of 21x19 (not whole
// 8x8 tiles: padding items) close enough that corner rays miss the box, and one orthographic view.
Scene shared_voxel_scene(Model model, Scheme scheme) {
  Scene s;
  s.volume = random_volume(12, 10, 11, 5);
  set_default_box(s);
  s.model = model;
  s.tf.kind = model == Model::absorption ? TfKind::identity : TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.2, 0.3, 0.9}, 1.0}, {1.0, {0.9, 0.5, 0.1}, 5.0}};
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  Camera c;
  c.width = 21;
  c.height = 19;
  c.fov_y = 40;
  c.eye = {1.2, 0.7, 0.9};
  s.cameras.push_back(c);
  c.eye = {-0.4, -1.3, 0.8};
  s.cameras.push_back(c);
  s.cameras.push_back(ortho({0.3, 0.2, -1.8}, {0, 1, 0}, 21, 19, 1.4));
  s.integrator.scheme = scheme;
  s.integrator.step = 0.6;
  s.integrator.min_transmittance = 0;
  return s;
}

// |got − want| ≤ relative·|want| + absolute·max |want| element by element (the table changes the
// order of each voxel's float additions, so agreement is to rounding, not bit for bit).
::testing::AssertionResult agree(const std::vector<double>& got, const std::vector<double>& want,
                                 double relative, double absolute) {
  if (got.size() != want.size()) return ::testing::AssertionFailure() << "sizes differ";
  const double scale = max_abs(want);
  if (!(scale > 0)) return ::testing::AssertionFailure() << "the reference is zero";
  for (std::size_t i = 0; i < got.size(); ++i)
    if (!(std::abs(got[i] - want[i]) <= relative * std::abs(want[i]) + absolute * scale))
      return ::testing::AssertionFailure() << "element " << i << ": " << got[i] << " against "
                                           << want[i] << " (largest " << scale << ")";
  return ::testing::AssertionSuccess();
}

std::vector<double> as_doubles(const std::vector<float>& v) {
  return {v.begin(), v.end()};
}

// Nᵀ y with the cache forced on or off (and, for a tiny table, extra build options); checks the
// dot-product test ⟨N x, y⟩ = ⟨x, Nᵀ y⟩ on the way.
std::vector<double> backprojection(const Scene& scene, Precision p, const char* cache,
                                   const char* build_options = "") {
  ScopedEnv force("IVR_SCATTER_CACHE", cache);
  ScopedEnv options("IVR_BUILD_OPTIONS", build_options);
  const Projector P(device(), scene, p);
  const std::vector<double> x = uniform(P.voxel_count(), 21), y = uniform(P.ray_count(), 22);
  const std::vector<double> nty = P.backproject(y);
  const double lhs = dot(P.project(x), y), rhs = dot(x, nty);
  EXPECT_LE(std::abs(lhs - rhs) / std::max(std::abs(lhs), std::abs(rhs)),
            p == Precision::f64 ? 1e-12 : 1e-5)
      << name(p) << " cache " << cache << " " << build_options << ": <Nx,y> = " << lhs
      << ", <x,N^T y> = " << rhs;
  return nty;
}

class ScatterCacheBackproject : public ::testing::TestWithParam<Precision> {};

TEST_P(ScatterCacheBackproject, StaysTheTransposeAndAgreesWithTheUncached) {
  const Precision p = GetParam();
  if (p == Precision::f64 && !device().info().fp64) GTEST_SKIP() << "no fp64";
  const bool f64 = p == Precision::f64;
  const Scene scene = shared_voxel_scene(Model::absorption, Scheme::exact);
  const std::vector<double> off = backprojection(scene, p, "0");
  EXPECT_TRUE(agree(backprojection(scene, p, "1"), off, f64 ? 1e-13 : 1e-5, f64 ? 1e-15 : 1e-6))
      << name(p);
  // 4 slots for every group's hundreds of voxels: the table is full at once, and nearly every add
  // evicts another voxel's sum (the packed float32 table) or goes to global memory directly.
  EXPECT_TRUE(agree(backprojection(scene, p, "1", "-DIVR_SCATTER_SLOTS=4"), off, f64 ? 1e-13 : 1e-5,
                    f64 ? 1e-15 : 1e-6))
      << name(p) << " with 4 slots";
  if (!f64)  // the keyed layout, which float32 takes on devices without 64-bit atomics
    EXPECT_TRUE(agree(backprojection(scene, p, "1", "-DIVR_SCATTER_KEYED -DIVR_SCATTER_SLOTS=4"),
                      off, 1e-5, 1e-6))
        << "keyed float32 with 4 slots";
}

INSTANTIATE_TEST_SUITE_P(Precisions, ScatterCacheBackproject,
                         ::testing::Values(Precision::f32, Precision::f64),
                         [](const auto& info) { return std::string(name(info.param)); });

// The gradient with the cache forced on or off.
AdjointGradient gradient_with(const Scene& s, const Image& target, const AdjointOptions& o,
                       const char* cache, const char* build_options = "") {
  ScopedEnv force("IVR_SCATTER_CACHE", cache);
  ScopedEnv options("IVR_BUILD_OPTIONS", build_options);
  return adjoint(device(), s, target, o);
}

struct AdjointCase {
  const char* name;
  Model model;
  Scheme scheme;  // each scheme's adjoint march takes the table (kernels/adjoint_*.cl)
};
void PrintTo(const AdjointCase& c, std::ostream* os) {
  *os << c.name;
}

class ScatterCacheAdjoint : public ::testing::TestWithParam<AdjointCase> {};

TEST_P(ScatterCacheAdjoint, DensityGradientAgreesWithTheUncached) {
  const AdjointCase c = GetParam();
  const Scene s = shared_voxel_scene(c.model, c.scheme);
  const Image target = perturbed_target(s);
  AdjointOptions o;
  o.tf = true;
  for (Precision p : {Precision::f32, Precision::f64}) {
    o.precision = p;
    const bool f64 = p == Precision::f64;
    const double relative = f64 ? 1e-11 : 1e-4, absolute = f64 ? 1e-13 : 1e-6;
    const AdjointGradient off = gradient_with(s, target, o, "0");
    ASSERT_TRUE(all_finite(off));
    ASSERT_GT(max_abs(off.density), 0);
    for (const char* slots : {"", "-DIVR_SCATTER_SLOTS=4", "-DIVR_SCATTER_KEYED"}) {
      if (f64 && has(slots, "KEYED")) continue;  // float64 is keyed anyway
      // The table's variants (slots, keys) are the scheme's business only through the default
      // table, which every scheme takes; the variants run under midpoint (each is a build).
      if (c.scheme != Scheme::midpoint && *slots) continue;
      const AdjointGradient on = gradient_with(s, target, o, "1", slots);
      EXPECT_TRUE(agree(as_doubles(on.density), as_doubles(off.density), relative, absolute))
          << c.name << " " << name(p) << " " << slots;
      EXPECT_NEAR(on.loss, off.loss, 1e-6 * std::abs(off.loss)) << c.name << " " << name(p);
      // The TF gradient keeps its own accumulator: only the order of its atomic adds varies.
      EXPECT_LE(relative_error(on.tf, off.tf), f64 ? 1e-12 : 1e-5) << c.name << " " << name(p);
    }
  }
}

// The fixed-point gradient does not go through the table: the same bits with the cache forced
// on, whatever its size.
TEST_P(ScatterCacheAdjoint, DeterministicGradientIsBitIdentical) {
  const AdjointCase c = GetParam();
  const Scene s = shared_voxel_scene(c.model, c.scheme);
  const Image target = perturbed_target(s);
  AdjointOptions o;
  o.deterministic = true;
  o.precision = Precision::f64;
  const AdjointGradient off = gradient_with(s, target, o, "0");
  ASSERT_TRUE(off.deterministic) << "PoCL has cl_khr_int64_base_atomics";
  for (const char* slots : {"", "-DIVR_SCATTER_SLOTS=4"}) {
    const AdjointGradient on = gradient_with(s, target, o, "1", slots);
    EXPECT_EQ(on.density, off.density) << c.name << " " << slots;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Schemes, ScatterCacheAdjoint,
    ::testing::Values(AdjointCase{"midpoint", Model::emission_absorption, Scheme::midpoint},
                      AdjointCase{"trapezoid", Model::emission_absorption, Scheme::trapezoid},
                      AdjointCase{"exact", Model::absorption, Scheme::exact}),
    [](const auto& info) { return std::string(info.param.name); });

// The switch reaches both kernels: with the cache on, a table size that is no power of two stops
// the build (the kernel's #error); off, the same option is ignored. The gradient's stats name
// the table where it was used.
TEST(ScatterCacheSwitch, ReachesTheKernels) {
  const Scene s = shared_voxel_scene(Model::absorption, Scheme::exact);
  const Image target = perturbed_target(s);
  for (const bool on : {false, true}) {
    ScopedEnv force("IVR_SCATTER_CACHE", on ? "1" : "0");
    Session session(device(), s);
    session.set_target(target);
    GradientRequest r;
    r.mode = Mode::adjoint;
    session.gradient(r);
    const std::string variant = session.last_stats().variant;
    EXPECT_EQ(has(variant, "scatter_cache"), on) << variant;
  }
  const char* bad = "-DIVR_SCATTER_SLOTS=3";
  EXPECT_NO_THROW(gradient_with(s, target, {}, "0", bad));
  try {
    gradient_with(s, target, {}, "1", bad);
    ADD_FAILURE() << "the adjoint built without the table";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "IVR_SCATTER_SLOTS must be a power of two")) << e.what();
  }
  ScopedEnv options("IVR_BUILD_OPTIONS", bad);
  const std::vector<double> lines(std::size_t(3) * 21 * 19, 1.0);
  {
    ScopedEnv force("IVR_SCATTER_CACHE", "0");
    EXPECT_NO_THROW(Projector(device(), s, Precision::f32).backproject(lines));
  }
  ScopedEnv force("IVR_SCATTER_CACHE", "1");
  try {
    Projector(device(), s, Precision::f32).backproject(lines);
    ADD_FAILURE() << "the back-projector built without the table";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "IVR_SCATTER_SLOTS must be a power of two")) << e.what();
  }
}

// The default on devices this machine does not have: off (until a GPU measures it);
// $IVR_SCATTER_CACHE forces it, and a forced table that does not fit, or a value that is not
// auto, 0 or 1, is one clear error.
TEST(ScatterCacheSwitch, DefaultAndForcedOnEveryKindOfDevice) {
  ScopedEnv neutral("IVR_SCATTER_CACHE", "auto");
  DeviceInfo gpu, cpu;
  gpu.name = "a GPU";
  gpu.type = "gpu";
  cpu.name = "a CPU";
  cpu.type = "cpu";
  const std::uint64_t kib48 = 48 * 1024;
  EXPECT_FALSE(scatter_cache_for(gpu, kib48, 8, 8 * 1024));
  EXPECT_FALSE(scatter_cache_for(cpu, 2 << 20, 4, 0));
  {
    ScopedEnv force("IVR_SCATTER_CACHE", "1");
    EXPECT_TRUE(scatter_cache_for(cpu, 2 << 20, 4, 0));
    EXPECT_TRUE(scatter_cache_for(gpu, kib48, 8, 8 * 1024));
    try {
      scatter_cache_for(gpu, 4096, 8, 0);
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_TRUE(has(e.what(), "IVR_SCATTER_CACHE=1: the scatter cache")) << e.what();
      EXPECT_TRUE(has(e.what(), "a GPU's 4096 bytes of local memory")) << e.what();
    }
  }
  {
    ScopedEnv force("IVR_SCATTER_CACHE", "0");
    EXPECT_FALSE(scatter_cache_for(gpu, kib48, 8, 0));
  }
  ScopedEnv force("IVR_SCATTER_CACHE", "yes");
  try {
    scatter_cache_for(gpu, kib48, 8, 0);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "IVR_SCATTER_CACHE must be auto, 0 or 1, got 'yes'")) << e.what();
  }
}

}  // namespace
}  // namespace ivr::test
