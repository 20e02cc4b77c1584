// linalg_test.cpp — the solvers' device vector operations (kernels/linalg.cl): reductions against
// the host, non-negativity, safe reciprocals, and the TV difference operator against its
// transpose (dot-product test) and against hand-computed differences.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tomo/linalg.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

Scene grid_scene(int nx, int ny, int nz) {
  Scene s;
  s.volume.nx = nx, s.volume.ny = ny, s.volume.nz = nz;
  s.volume.data.assign(s.volume.voxel_count(), 0.0f);
  set_default_box(s);
  s.cameras = {test::ortho({0, 0, 2}, {0, 1, 0}, 4, 4, 1.0)};
  return s;
}

std::vector<double> signed_uniform(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> v(n);
  for (double& x : v) x = 2.0 * double(rng() >> 11) * 0x1.0p-53 - 1.0;
  return v;
}

double host_dot(const std::vector<double>& a, const std::vector<double>& b) {
  long double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += (long double)a[i] * b[i];
  return double(s);
}

class LinalgTest : public ::testing::TestWithParam<Precision> {
 protected:
  void SetUp() override {
    if (GetParam() == Precision::f64 && !test::device().info().fp64) GTEST_SKIP() << "no fp64";
  }
};

TEST_P(LinalgTest, ReductionsMatchTheHost) {
  Projector P(test::device(), grid_scene(37, 23, 11), GetParam());
  Projector::Impl& p = P.impl();
  DeviceVectors V(p);
  const std::vector<double> a = signed_uniform(p.voxels, 1), b = signed_uniform(p.voxels, 2);
  const cl::Buffer da = p.upload(a, "a"), db = p.upload(b, "b");
  const double tol = GetParam() == Precision::f64 ? 1e-13 : 1e-5;
  EXPECT_NEAR(V.dot(p.voxels, da, db), host_dot(a, b), tol * std::sqrt(double(p.voxels)));
  EXPECT_NEAR(V.norm(p.voxels, da), std::sqrt(host_dot(a, a)), tol * host_dot(a, a));
  double negative = 0;
  for (double x : a) negative -= std::min(x, 0.0);
  EXPECT_NEAR(V.clamp_nonneg(p.voxels, da), negative, tol * negative * 10);
  for (double x : p.download(da, p.voxels)) ASSERT_GE(x, 0.0);
  std::vector<double> r = {2.0, 0.0, -1.0, 0.5};
  const cl::Buffer dr = p.upload(r, "r");
  V.safe_reciprocal(4, dr);
  EXPECT_EQ(p.download(dr, 4), (std::vector<double>{0.5, 0.0, 0.0, 2.0}));
}

TEST_P(LinalgTest, TvDifferencesAndTheirTransposeAreAMatchedPair) {
  const int nx = 9, ny = 6, nz = 5;
  Projector P(test::device(), grid_scene(nx, ny, nz), GetParam());
  Projector::Impl& p = P.impl();
  DeviceVectors V(p);
  const std::vector<double> x = signed_uniform(p.voxels, 3), g = signed_uniform(3 * p.voxels, 4);
  std::vector<double> sw = signed_uniform(p.voxels, 5);
  for (double& w : sw) w = 0.5 + std::abs(w);
  const cl::Buffer dx = p.upload(x, "x"), dg = p.upload(g, "g"), dsw = p.upload(sw, "sw");
  const cl::Buffer Dx = p.vector(3 * p.voxels, "Dx"), DTg = p.vector(p.voxels, "DTg");
  V.tv_forward(dx, dsw, Dx);
  V.fill(DTg, p.voxels, 0.0);
  V.tv_adjoint(1.0, dg, dsw, DTg);
  const std::vector<double> fwd = p.download(Dx, 3 * p.voxels), adj = p.download(DTg, p.voxels);
  const double lhs = host_dot(fwd, g), rhs = host_dot(x, adj);
  EXPECT_NEAR(lhs, rhs, (GetParam() == Precision::f64 ? 1e-12 : 1e-5) * (1 + std::abs(lhs)));
  // Forward differences, 0 on the upper faces, times the weight.
  auto at = [&](int i, int j, int k) { return std::size_t((k * ny + j) * nx + i); };
  const double tol = GetParam() == Precision::f64 ? 1e-14 : 1e-6;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const std::size_t v = at(i, j, k);
        EXPECT_NEAR(fwd[3 * v], i + 1 < nx ? sw[v] * (x[at(i + 1, j, k)] - x[v]) : 0.0, tol);
        EXPECT_NEAR(fwd[3 * v + 1], j + 1 < ny ? sw[v] * (x[at(i, j + 1, k)] - x[v]) : 0.0, tol);
        EXPECT_NEAR(fwd[3 * v + 2], k + 1 < nz ? sw[v] * (x[at(i, j, k + 1)] - x[v]) : 0.0, tol);
      }
  // Weights: sqrt(λ)·(|D x|² + ε²)^(−1/4); on a constant volume that is sqrt(λ/ε).
  const cl::Buffer ones = p.vector(p.voxels, "ones"), w = p.vector(p.voxels, "w");
  V.fill(ones, p.voxels, 3.0);
  V.tv_weights(0.01, 4.0, ones, w);
  for (double value : p.download(w, p.voxels)) EXPECT_NEAR(value, std::sqrt(4.0 / 0.01), 1e-4);
}

INSTANTIATE_TEST_SUITE_P(Precisions, LinalgTest,
                         ::testing::Values(Precision::f32, Precision::f64),
                         [](const auto& info) { return std::string(test::name(info.param)); });

}  // namespace
}  // namespace ivr
