// ray_list_projector_test.cpp — the projector pair and the solvers over ray lists: a camera's rays
// as a list project bit for bit as the camera does, ⟨N x, y⟩ = ⟨x, Nᵀ y⟩ over random finite rays,
// and CGLS recovers a volume from sightlines that end inside it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using test::device;
using test::dot;
using test::uniform;

// Sightlines from an observer inside the box to "stars" at random points of it (ending inside),
// plus a share of rays through the whole box, seeded.
RayList sightlines(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<double> points;
  for (std::size_t i = 0; i < count; ++i) {
    const double o[3] = {0.05, -0.02, 0.01};
    if (i % 4 == 3) {  // through the whole box, from outside
      points.insert(points.end(), {u(rng), u(rng), -0.9, u(rng), u(rng), 0.9});
    } else {
      points.insert(points.end(), {o[0], o[1], o[2], u(rng), u(rng), u(rng)});
    }
  }
  return make_ray_list(points.data(), count, 6);
}

Scene grid_scene(int nx, int ny, int nz) {
  Scene s;
  s.volume.nx = nx, s.volume.ny = ny, s.volume.nz = nz;
  s.volume.data.assign(s.volume.voxel_count(), 0.0f);
  s.model = Model::absorption;
  set_default_box(s);
  return s;
}

TEST(RayListProjector, CameraRaysProjectAsTheCameraDoes) {
  Scene s = grid_scene(9, 7, 6);
  s.cameras = {test::ortho({0.7, 1.2, 1.4}, {0, 0, 1}, 13, 11, 1.6)};
  Scene r = s;
  r.rays = ray_list_of_camera(s.cameras[0]);
  r.cameras.clear();
  const std::vector<double> x = uniform(s.volume.voxel_count(), 3);
  const Projector a(device(), s), b(device(), r);
  ASSERT_EQ(b.ray_count(), a.ray_count());
  const std::vector<double> pa = a.project(x), pb = b.project(x);
  EXPECT_EQ(0, std::memcmp(pa.data(), pb.data(), pa.size() * sizeof(double)));
  // Nᵀ scatters with atomics (their order is the device's): equal to rounding.
  const std::vector<double> y = uniform(a.ray_count(), 4);
  const std::vector<double> ba = a.backproject(y), bb = b.backproject(y);
  for (std::size_t i = 0; i < ba.size(); ++i)
    ASSERT_NEAR(ba[i], bb[i], 1e-5 * (1 + std::abs(ba[i]))) << "voxel " << i;
}

TEST(RayListProjector, DotProductTestOverFiniteRays) {
  Scene s = grid_scene(11, 9, 8);
  s.rays = sightlines(2000, 5);
  for (Precision p : {Precision::f64, Precision::f32}) {
    const Projector P(device(), s, p);
    const std::vector<double> x = uniform(P.voxel_count(), 11), y = uniform(P.ray_count(), 12);
    const double lhs = dot(P.project(x), y), rhs = dot(x, P.backproject(y));
    EXPECT_LE(std::abs(lhs - rhs) / std::abs(lhs), p == Precision::f64 ? 1e-12 : 1e-5)
        << test::name(p) << ": " << lhs << " vs " << rhs;
  }
}

// The line integrals of finite rays against the float64 reference's: reference::render of an
// absorption scene with the identity TF gives exp(−∫), its centre-plane pieces cut into steps of
// 1/100 voxel (midpoint rule: ~1e-7 of the integrand's curvature).
TEST(RayListProjector, LineIntegralsAgainstTheReference) {
  Scene s = grid_scene(8, 8, 8);
  s.volume = synthetic_volume("sphere", 8, 8, 8);
  s.tf.kind = TfKind::identity;
  s.rays = sightlines(300, 9);
  s.integrator.min_transmittance = 0;
  const std::vector<double> ref = reference::render(s, 0.01 * reference::min_voxel_edge(s), false);
  const Projector P(device(), s, Precision::f64);
  const std::vector<double> lines =
      P.project(std::vector<double>(s.volume.data.begin(), s.volume.data.end()));
  for (std::size_t i = 0; i < lines.size(); ++i)
    ASSERT_NEAR(std::exp(-lines[i]), ref[i], 1e-6) << "ray " << i;
}

TEST(RayListProjector, CglsRecoversAVolumeFromSightlines) {
  Scene s = grid_scene(8, 8, 8);
  const Volume truth = synthetic_volume("sphere", 8, 8, 8);
  s.rays = sightlines(6000, 21);
  const Projector P(device(), s, Precision::f64);
  const std::vector<double> x(truth.data.begin(), truth.data.end());
  const std::vector<double> lines = P.project(x);
  TomoOptions o;
  o.precision = Precision::f64;
  o.iterations = 200;
  const TomoResult r = tomo(device(), s, lines, o);
  ASSERT_FALSE(r.history.empty());
  EXPECT_LT(r.history.back().residual, 1e-5);
  double err = 0, norm = 0;
  for (std::size_t i = 0; i < x.size(); ++i)
    err += std::pow(r.volume_f64[i] - x[i], 2), norm += x[i] * x[i];
  EXPECT_LT(std::sqrt(err / norm), 1e-3);
}

// SIRT with a prior over sightlines, where rays clip some voxels' corners (Nᵀ1 ~ 1e-12 there):
// the prior's step is bounded by its curvature, so the iterate stays near the truth (it blew up
// to ~1e8, or NaN with Tikhonov, when the column weights were 1/(Nᵀ1) alone).
TEST(RayListProjector, SirtWithAPriorStaysBounded) {
  Scene s = grid_scene(16, 16, 16);
  const Volume truth = synthetic_volume("sphere", 16, 16, 16);
  s.rays = sightlines(8000, 31);
  const Projector P(device(), s, Precision::f64);
  const std::vector<double> x(truth.data.begin(), truth.data.end());
  const std::vector<double> lines = P.project(x);
  double norm = 0;
  for (double v : x) norm += v * v;
  const char* names[3] = {"none", "tv", "tikhonov"};
  double errors[3] = {0, 0, 0};
  for (int prior = 0; prior < 3; ++prior) {
    TomoOptions o;
    o.solver = Solver::sirt;
    o.precision = Precision::f64;
    o.iterations = 60;
    o.nonneg = true;
    if (prior == 1) o.tv = 1e-3;
    if (prior == 2) o.tikhonov = 1e-3;
    const TomoResult r = tomo(device(), s, lines, o);
    double err = 0, largest = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      ASSERT_TRUE(std::isfinite(r.volume_f64[i])) << names[prior] << " voxel " << i;
      err += std::pow(r.volume_f64[i] - x[i], 2);
      largest = std::max(largest, std::abs(r.volume_f64[i]));
    }
    errors[prior] = std::sqrt(err / norm);
    EXPECT_LT(largest, 3.0) << names[prior];
    EXPECT_LT(r.history.back().residual, 0.2 * r.history.front().residual) << names[prior];
  }
  // The priors cost SIRT little here (noise-free data): within 25 % of its error without one.
  EXPECT_LT(errors[0], 0.7);
  for (int prior = 1; prior < 3; ++prior)
    EXPECT_LT(errors[prior], 1.25 * errors[0]) << names[prior] << " " << errors[prior] << " vs "
                                               << errors[0];
}

TEST(RayListProjector, WrongLineCountsNameTheRayList) {
  Scene s = grid_scene(4, 4, 4);
  s.rays = sightlines(10, 1);
  try {
    tomo(device(), s, std::vector<double>(9, 0.0), TomoOptions{});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_TRUE(test::has(e.what(), "ray list has 10 rays")) << e.what();
  }
}

}  // namespace
}  // namespace ivr
