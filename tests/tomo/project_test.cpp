// project_test.cpp — the projector pair: N against the double-precision reference's line
// integrals and the closed-form chord of a constant volume, and the dot-product (transpose) test
// ⟨N x, y⟩ = ⟨x, Nᵀ y⟩ on parallel, cone, inside-the-box and axis-aligned geometries.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using test::dot;
using test::uniform;

struct Geometry {
  const char* name;
  Scene (*make)();
};

Volume random_volume(int nx, int ny, int nz, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Volume v;
  v.nx = nx, v.ny = ny, v.nz = nz;
  v.data.resize(v.voxel_count());
  for (float& d : v.data) d = float(double(rng() >> 11) * 0x1.0p-53);
  return v;
}

Scene base_scene(int nx, int ny, int nz) {
  Scene s;
  s.volume = random_volume(nx, ny, nz, 7);
  s.model = Model::absorption;
  s.tf.kind = TfKind::identity;
  set_default_box(s);
  return s;
}

Camera perspective(glm::dvec3 eye, glm::dvec3 up, int w, int h, double fov) {
  Camera c;
  c.eye = eye;
  c.up = up;
  c.fov_y = fov;
  c.width = w;
  c.height = h;
  return c;
}

// Parallel beam: three oblique orthographic views of an anisotropic grid.
Scene parallel_scene() {
  Scene s = base_scene(9, 7, 5);
  s.cameras = {test::ortho({1.5, 0.7, 1.1}, {0, 0, 1}, 12, 10, 1.6),
               test::ortho({-0.3, 2.0, 0.4}, {0, 0, 1}, 12, 10, 1.6),
               test::ortho({0.2, -0.4, -1.7}, {0, 1, 0}, 12, 10, 1.6)};
  return s;
}

// Cone beam: perspective cameras outside the box.
Scene cone_scene() {
  Scene s = base_scene(8, 8, 8);
  s.cameras = {perspective({1.8, 0.9, 1.2}, {0, 0, 1}, 11, 9, 45),
               perspective({-2.0, -0.3, 0.5}, {0, 0, 1}, 11, 9, 45)};
  return s;
}

// Cameras inside the box: rays start inside and leave through every face.
Scene inside_scene() {
  Scene s = base_scene(6, 8, 7);
  s.cameras = {perspective({0.05, -0.1, 0.12}, {0, 0, 1}, 10, 10, 100),
               perspective({-0.2, 0.15, -0.05}, {0, 1, 0}, 10, 10, 70)};
  return s;
}

// Rays along the axes, through voxel centres, centre planes and box faces.
Scene axis_scene() {
  Scene s = base_scene(5, 6, 4);
  s.cameras = {test::ortho({0, 0, 2}, {0, 1, 0}, 10, 12, 1.2),
               test::ortho({2, 0, 0}, {0, 0, 1}, 10, 12, 1.2),
               test::ortho({0, -2, 0}, {0, 0, 1}, 10, 12, 1.2)};
  return s;
}

void PrintTo(const Geometry& g, std::ostream* os) {
  *os << g.name;
}

const Geometry kGeometries[] = {{"parallel", parallel_scene},
                                {"cone", cone_scene},
                                {"inside", inside_scene},
                                {"axis_aligned", axis_scene}};

std::vector<double> as_double(const Volume& v) {
  return {v.data.begin(), v.data.end()};
}

// Calls f(index, view, y, x, origin, dir) for every ray of the scene, in the projector's order.
template <class F>
void for_each_ray(const Scene& scene, F&& f) {
  const Camera& c0 = scene.cameras.front();
  std::size_t i = 0;
  for (std::size_t v = 0; v < scene.cameras.size(); ++v)
    for (int y = 0; y < c0.height; ++y)
      for (int x = 0; x < c0.width; ++x, ++i) {
        glm::dvec3 o, d;
        reference::ray(scene.cameras[v], x, y, &o, &d);
        f(i, int(v), y, x, o, d);
      }
}

class ProjectorTest : public ::testing::TestWithParam<std::tuple<Geometry, Precision>> {};

TEST_P(ProjectorTest, IsTheExactTransposeOfItsBackProjector) {
  const auto [geometry, precision] = GetParam();
  if (precision == Precision::f64 && !test::device().info().fp64) GTEST_SKIP() << "no fp64";
  const Scene scene = geometry.make();
  const Projector P(test::device(), scene, precision);
  // x and y positive, so that neither inner product cancels and the relative mismatch is rounding.
  const std::vector<double> x = uniform(P.voxel_count(), 11), y = uniform(P.ray_count(), 12);
  const double lhs = dot(P.project(x), y), rhs = dot(x, P.backproject(y));
  const double mismatch = std::abs(lhs - rhs) / std::max(std::abs(lhs), std::abs(rhs));
  EXPECT_GT(lhs, 0);
  EXPECT_LE(mismatch, precision == Precision::f64 ? 1e-12 : 1e-5)
      << geometry.name << " " << test::name(precision) << ": <Nx,y> = " << lhs
      << ", <x,N^T y> = " << rhs;
}

TEST_P(ProjectorTest, MatchesTheReferenceLineIntegrals) {
  const auto [geometry, precision] = GetParam();
  if (precision == Precision::f64 && !test::device().info().fp64) GTEST_SKIP() << "no fp64";
  const Scene scene = geometry.make();
  const Projector P(test::device(), scene, precision);
  const std::vector<double> lines = P.project(as_double(scene.volume));
  const double rel = precision == Precision::f64 ? 1e-11 : 2e-6;
  // float32: positions round by ~1e-7 of the box, so short corner chords carry ~1e-7 absolute.
  const double abs = precision == Precision::f64 ? 1e-13 : 1e-6;
  int nonzero = 0;
  for_each_ray(scene, [&](std::size_t i, int v, int y, int x, glm::dvec3 o, glm::dvec3 d) {
    const double expected = reference::optical_depth(scene, o, d);
    nonzero += expected > 0;
    ASSERT_TRUE(std::isfinite(lines[i])) << test::where(precision, v, y, x);
    EXPECT_NEAR(lines[i], expected, abs + rel * std::abs(expected))
        << geometry.name << " " << test::where(precision, v, y, x);
  });
  EXPECT_GT(nonzero, int(P.ray_count() / 4)) << geometry.name << ": most rays must meet the box";
}

TEST_P(ProjectorTest, OfAConstantVolumeIsSigmaTimesTheChord) {
  const auto [geometry, precision] = GetParam();
  if (precision == Precision::f64 && !test::device().info().fp64) GTEST_SKIP() << "no fp64";
  const Scene scene = geometry.make();
  const Projector P(test::device(), scene, precision);
  const double sigma = 0.7;
  const std::vector<double> lines = P.project(std::vector<double>(P.voxel_count(), sigma));
  const double rel = precision == Precision::f64 ? 1e-13 : 1e-6;
  for_each_ray(scene, [&](std::size_t i, int v, int y, int x, glm::dvec3 o, glm::dvec3 d) {
    double t0 = 0, t1 = 0;
    const double chord =
        reference::clip_to_box(scene.box_min, scene.box_max, o, d, &t0, &t1) ? t1 - t0 : 0.0;
    EXPECT_NEAR(lines[i], sigma * chord, rel * (1 + sigma * chord))
        << geometry.name << " " << test::where(precision, v, y, x);
  });
}

INSTANTIATE_TEST_SUITE_P(Geometries, ProjectorTest,
                         ::testing::Combine(::testing::ValuesIn(kGeometries),
                                            ::testing::Values(Precision::f32, Precision::f64)),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param).name) + "_" +
                                  test::name(std::get<1>(info.param));
                         });

TEST(Projector, RefusesArraysOfTheWrongSize) {
  const Scene scene = parallel_scene();
  const Projector P(test::device(), scene);
  EXPECT_THROW(P.project(std::vector<double>(P.voxel_count() + 1)), Error);
  EXPECT_THROW(P.backproject(std::vector<double>(P.ray_count() - 1)), Error);
}

TEST(Projector, RefusesScenesWithoutCameras) {
  Scene scene = parallel_scene();
  scene.cameras.clear();
  try {
    Projector P(test::device(), scene);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument);
    EXPECT_NE(std::string(e.what()).find("camera"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ivr
