// bricked_project_test.cpp — the projector pair brick by brick (kernels/project.cl project_brick,
// backproject_brick; lib/brick/bricked_project.cpp) equals the in-core pair, and stays an exact
// transpose pair, for bricks of one cell to many, cone and parallel beams, a ray list.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ivr/tomo.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

Scene projector_scene() {
  Scene s;
  s.volume.nx = 10, s.volume.ny = 7, s.volume.nz = 12;
  set_default_box(s);
  s.model = Model::absorption;
  Camera c;
  c.eye = {0.4, 0.9, 1.8}, c.fov_y = 45, c.width = 9, c.height = 8;
  Camera inside = c;
  inside.eye = {0.05, -0.05, 0.1}, inside.target = {1, 0.2, -0.3};
  s.cameras = {c, inside, ortho({0, 0, 2}, {0, 1, 0}, 9, 8, s.box_max.y - s.box_min.y),
               ortho({-2, 0.0, 0}, {0, 1, 0}, 9, 8, 0.9)};
  return s;
}

std::vector<double> randoms(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

void expect_close(const std::vector<double>& a, const std::vector<double>& b, double tol,
                  const std::string& what) {
  ASSERT_EQ(a.size(), b.size());
  double scale = 1e-30;
  for (double x : a) scale = std::max(scale, std::abs(x));
  int bad = 0;
  for (std::size_t i = 0; i < a.size() && bad < 5; ++i)
    if (!std::isfinite(b[i]) || std::abs(a[i] - b[i]) > tol * scale)
      ADD_FAILURE() << what << " [" << i << "]: " << a[i] << " vs " << b[i], ++bad;
}

void check_scene(const Scene& s, const std::string& label) {
  for (Precision p : {Precision::f64, Precision::f32}) {
    if (p == Precision::f64 && !device().info().fp64) continue;
    const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
    const Projector in_core(device(), s, p);
    ASSERT_EQ(in_core.bricks(), 1);
    const std::vector<double> x = randoms(in_core.voxel_count(), 1);
    const std::vector<double> y = randoms(in_core.ray_count(), 2);
    const std::vector<double> nx = in_core.project(x), nty = in_core.backproject(y);
    for (const char* edge : {"1", "3", "5"}) {
      ScopedEnv brick("IVR_VOLUME_BRICK", edge);
      const Projector bricked(device(), s, p);
      EXPECT_GT(bricked.bricks(), 1) << edge;
      const std::string what = label + " " + name(p) + " bricks of " + edge;
      const std::vector<double> bx = bricked.project(x), bty = bricked.backproject(y);
      expect_close(nx, bx, tol, what + ": N x");
      expect_close(nty, bty, tol, what + ": Nᵀ y");
      if (p == Precision::f64) {  // the bricked pair is a transpose pair by itself
        const double lhs = dot(bx, y), rhs = dot(x, bty);
        EXPECT_NEAR(lhs, rhs, 1e-12 * std::max(std::abs(lhs), 1.0)) << what;
      }
    }
  }
}

TEST(BrickedProjector, EqualsInCoreAndStaysATransposePair) { check_scene(projector_scene(), "cameras"); }

TEST(BrickedProjector, RayList) {
  Scene s = projector_scene();
  std::vector<double> rows;
  const std::vector<double> r = randoms(64 * 6, 9);
  for (int i = 0; i < 64; ++i)
    rows.insert(rows.end(), {r[6 * i] * 0.8, r[6 * i + 1] * 0.3, r[6 * i + 2] * 0.8, r[6 * i + 3],
                             r[6 * i + 4], r[6 * i + 5] + 0.1, i % 2 ? 0.0 : -INFINITY,
                             i % 3 ? 0.7 : INFINITY});
  s.rays = make_ray_list(rows.data(), 64, 8);
  s.cameras.clear();
  check_scene(s, "ray list");
}

}  // namespace
}  // namespace ivr::test

namespace ivr::test {
namespace {

// Every solver with the projector in bricks (host vectors: lib/tomo/host_solvers.hpp) takes the
// in-core device solver's iterates — CGLS, SIRT and LSQR, with Tikhonov, with x ≥ 0 and with TV
// (re-weighted every 3 iterations, so twice in 6). In float64 (where the device has it) the host
// solvers keep double iterates; in float32 float ones, like the device's float32 iterates.
TEST(BrickedTomo, SolversEqualTheInCoreSolvers) {
  const Scene s = projector_scene();
  std::vector<Precision> precisions{Precision::f32};
  if (device().info().fp64) precisions.push_back(Precision::f64);
  for (const Precision p : precisions) {
    const Projector N(device(), s, p);
    std::vector<double> truth = randoms(N.voxel_count(), 4);
    for (double& v : truth) v = std::abs(v);
    const std::vector<double> lines = N.project(truth);
    for (const Solver solver : {Solver::cgls, Solver::sirt, Solver::lsqr})
      for (const std::string regulariser : {"tikhonov", "nonneg", "tv"}) {
        SCOPED_TRACE(std::string(p == Precision::f64 ? "f64 " : "f32 ") + solver_name(solver) +
                     " " + regulariser);
        TomoOptions o;
        o.solver = solver;
        o.precision = p;
        o.iterations = 6;
        o.nonneg = regulariser == "nonneg";
        o.tikhonov = regulariser == "tikhonov" ? 1e-3 : 0.0;
        o.tv = regulariser == "tv" ? 1e-3 : 0.0;
        o.tv_reweight = 3;
        const TomoResult in_core = tomo(device(), s, lines, o);
        ScopedEnv brick("IVR_VOLUME_BRICK", "4");
        const TomoResult bricked = tomo(device(), s, lines, o);
        EXPECT_EQ(in_core.bricks, 1);
        EXPECT_GT(bricked.bricks, 1);
        EXPECT_EQ(bricked.volume_f64.empty(), p == Precision::f32);
        ASSERT_EQ(bricked.history.size(), in_core.history.size());
        for (std::size_t k = 0; k < in_core.history.size(); ++k)
          EXPECT_NEAR(bricked.history[k].residual, in_core.history[k].residual,
                      (p == Precision::f64 ? 1e-9 : 1e-4) + 1e-6 * in_core.history[k].residual)
              << "iteration " << k + 1;
        const std::vector<double> a(in_core.volume.begin(), in_core.volume.end()),
            b(bricked.volume.begin(), bricked.volume.end());
        expect_close(a, b, p == Precision::f64 ? 1e-6 : 1e-3, regulariser);
      }
  }
}

}  // namespace
}  // namespace ivr::test
