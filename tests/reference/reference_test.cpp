// reference_test.cpp — checks the CPU reference itself against closed forms, so that the kernels
// can be judged by it: Beer–Lambert, constant emission, a linear ramp, trilinear/clamping rules.
#include "reference/reference.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <random>

#include "test_support.hpp"

namespace ivr {
namespace {

// A small scene of arbitrary data with an anisotropic, off-centre box (no default-box symmetry).
Scene random_scene(int nx, int ny, int nz, unsigned seed) {
  Scene s;
  s.volume.nx = nx, s.volume.ny = ny, s.volume.nz = nz;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < nx * ny * nz; ++i) s.volume.data.push_back(u(rng));
  s.box_min = {-0.3, -0.7, 0.1};
  s.box_max = {0.6, 0.2, 0.6};
  return s;
}

// Centre of voxel (i, j, k) in world units.
glm::dvec3 centre(const Scene& s, double i, double j, double k) {
  return s.box_min + glm::dvec3(i + 0.5, j + 0.5, k + 0.5) * s.voxel_size();
}

TEST(Reference, TrilinearAtCentresEqualsVoxels) {
  const Scene s = random_scene(5, 4, 3, 1);
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 5; ++i)
        EXPECT_NEAR(reference::density(s, centre(s, i, j, k)), s.volume.at(i, j, k), 1e-12);
}

TEST(Reference, TrilinearBetweenCentresAverages) {
  const Scene s = random_scene(5, 4, 3, 2);
  // Half-way along x: the mean of two neighbours; the middle of a cell of 8 centres: their mean.
  EXPECT_NEAR(reference::density(s, centre(s, 1.5, 2, 1)),
              0.5 * (double(s.volume.at(1, 2, 1)) + s.volume.at(2, 2, 1)), 1e-12);
  double mean = 0;
  for (int c = 0; c < 8; ++c) mean += s.volume.at(2 + (c & 1), 1 + (c >> 1 & 1), c >> 2 & 1);
  EXPECT_NEAR(reference::density(s, centre(s, 2.5, 1.5, 0.5)), mean / 8, 1e-12);
  // A quarter of the way along y weights the neighbours 3:1.
  EXPECT_NEAR(reference::density(s, centre(s, 3, 0.25, 2)),
              0.75 * s.volume.at(3, 0, 2) + 0.25 * s.volume.at(3, 1, 2), 1e-12);
}

TEST(Reference, ClampsInTheBorderHalfVoxel) {
  const Scene s = random_scene(5, 4, 3, 3);
  const glm::dvec3 h = s.voxel_size();
  // Between the -x face and the first centre plane: the value of the edge centre beside it.
  for (double f : {0.0, 0.1, 0.25, 0.49}) {
    glm::dvec3 p = centre(s, 0, 2, 1);
    p.x = s.box_min.x + f * h.x;
    EXPECT_NEAR(reference::density(s, p), s.volume.at(0, 2, 1), 1e-12) << f;
    p = centre(s, 3, 3, 2);
    p.y = s.box_max.y - f * h.y;
    p.z = s.box_max.z - f * h.z;
    EXPECT_NEAR(reference::density(s, p), s.volume.at(3, 3, 2), 1e-12) << f;
  }
  // Clamped along x only, still interpolated along y.
  glm::dvec3 p = centre(s, 4, 1.5, 1);
  p.x = s.box_max.x - 0.2 * h.x;
  EXPECT_NEAR(reference::density(s, p), 0.5 * (double(s.volume.at(4, 1, 1)) + s.volume.at(4, 2, 1)),
              1e-12);
  // The box corner takes the corner voxel.
  EXPECT_NEAR(reference::density(s, s.box_min), s.volume.at(0, 0, 0), 1e-12);
}

TEST(Reference, ZeroOutsideTheBox) {
  const Scene s = random_scene(5, 4, 3, 4);
  const double eps = 1e-9;
  const glm::dvec3 mid = 0.5 * (s.box_min + s.box_max);
  for (int a = 0; a < 3; ++a) {
    glm::dvec3 p = mid;
    p[a] = s.box_min[a] - eps;
    EXPECT_EQ(reference::density(s, p), 0.0);
    p[a] = s.box_max[a] + eps;
    EXPECT_EQ(reference::density(s, p), 0.0);
    p[a] = s.box_max[a] + 10;
    EXPECT_EQ(reference::density(s, p), 0.0);
  }
  EXPECT_GT(reference::density(s, mid), 0.0);
}

TEST(Reference, CameraRays) {
  Camera c;
  c.eye = {1, 2, 3};
  c.target = {1, 2, -1};
  c.up = {0, 1, 0};
  c.fov_y = 90;
  c.width = 4;
  c.height = 2;
  glm::dvec3 o, d;
  // Pixel (0, 0), top left: sx = -0.75, sy = 0.5; tan(45°) = 1, W/H = 2; right = +x, up' = +y.
  reference::ray(c, 0, 0, &o, &d);
  EXPECT_NEAR(glm::length(o - c.eye), 0.0, 1e-15);
  const glm::dvec3 want = glm::normalize(glm::dvec3(-1.5, 0.5, -1));
  EXPECT_NEAR(glm::length(d - want), 0.0, 1e-14);
  c.projection = Projection::orthographic;
  c.ortho_height = 2;
  reference::ray(c, 3, 1, &o, &d);  // sx = 0.75, sy = -0.5: offset (0.75*1*2, -0.5*1)
  EXPECT_NEAR(glm::length(o - glm::dvec3(2.5, 1.5, 3)), 0.0, 1e-14);
  EXPECT_NEAR(glm::length(d - glm::dvec3(0, 0, -1)), 0.0, 1e-15);
}

TEST(Reference, TransferFunctions) {
  TransferFunction tf;
  tf.kind = TfKind::identity;
  tf.extinction_scale = 4;
  tf.color_scale = 0.5;
  auto s = reference::transfer(tf, 0.6);
  EXPECT_NEAR(s.sigma, 2.4, 1e-14);
  EXPECT_NEAR(s.emission.y, 2.4 * 0.3, 1e-14);

  tf.kind = TfKind::piecewise_linear;
  tf.points = {{0.2, {1, 0, 0}, 2}, {0.6, {0, 1, 0}, 10}};
  EXPECT_NEAR(reference::transfer(tf, 0.0).sigma, 2, 1e-14);   // constant below the first point
  EXPECT_NEAR(reference::transfer(tf, 0.9).sigma, 10, 1e-14);  // and beyond the last
  s = reference::transfer(tf, 0.3);                            // a quarter of the way
  EXPECT_NEAR(s.sigma, 4, 1e-14);
  EXPECT_NEAR(s.emission.x, 4 * 0.75, 1e-14);
  EXPECT_NEAR(s.emission.y, 4 * 0.25, 1e-14);

  tf.kind = TfKind::table;
  tf.range = {0.5, 1.0};
  tf.entries = {{1, 0, 0, 1}, {0, 0, 1, 3}, {0, 1, 0, 7}};  // at 0.5, 0.75, 1.0
  EXPECT_NEAR(reference::transfer(tf, 0.2).sigma, 1, 1e-14);
  s = reference::transfer(tf, 0.875);
  EXPECT_NEAR(s.sigma, 5, 1e-14);
  EXPECT_NEAR(s.emission.z, 5 * 0.5, 1e-14);
  EXPECT_NEAR(reference::transfer(tf, 2.0).sigma, 7, 1e-14);

  tf.kind = TfKind::gaussian;
  tf.gaussians = {{0.3, 0.1, {1, 0, 0}, 5}, {0.5, 0.2, {0, 0, 1}, 2}};
  s = reference::transfer(tf, 0.4);
  const double g1 = 5 * std::exp(-0.5), g2 = 2 * std::exp(-0.125);
  EXPECT_NEAR(s.sigma, g1 + g2, 1e-14);
  EXPECT_NEAR(s.emission.x, g1, 1e-14);
  EXPECT_NEAR(s.emission.z, g2, 1e-14);
}

TEST(Reference, ConstantBoxBeerLambert) {
  Scene s = test::constant_scene(0.5f, 4, 6);  // unit box, ortho down -z: L = 1 for every pixel
  s.tf.extinction_scale = 3;                   // sigma = 1.5
  s.background = glm::dvec3(0.7);
  for (double step : {0.3, 1e-3}) {  // a constant integrand is integrated exactly at any step
    const auto img = reference::render(s, step);
    ASSERT_EQ(img.size(), 36u);
    for (double v : img) EXPECT_NEAR(v, 0.7 * std::exp(-1.5), 1e-14);
  }
  // A perspective ray from a corner direction: the chord along the space diagonal is sqrt(3).
  s.cameras[0] = Camera{};
  s.cameras[0].eye = {2, 2, 2};
  s.cameras[0].width = s.cameras[0].height = 1;
  const auto img = reference::render(s, 0.01);
  EXPECT_NEAR(img[0], 0.7 * std::exp(-1.5 * std::sqrt(3.0)), 1e-13);
}

TEST(Reference, ConstantEmission) {
  Scene s = test::constant_scene(0.5f, 3, 4);  // densities exact in float and double
  s.model = Model::emission_absorption;
  s.tf.extinction_scale = 4;  // sigma = 2
  s.tf.color_scale = 1.2;     // colour = 0.6
  const glm::dvec3 bg(0.2, 0.3, 0.4);
  s.background = bg;
  const double T = std::exp(-2.0);
  // The midpoint rule here is not exact (its relative error is (sigma*dt)^2/24), so check the
  // error at two steps and its second-order decay.
  double err[2];
  for (int k = 0; k < 2; ++k) {
    const double step = k == 0 ? 1.0 / 60 : 1.0 / 120;  // divides the centre-plane pieces
    const auto img = reference::render(s, step);
    err[k] = 0;
    for (int p = 0; p < 16; ++p) {
      for (int c = 0; c < 3; ++c)
        err[k] = std::max(err[k], std::abs(img[p * 4 + c] - (0.6 * (1 - T) + T * bg[c])));
      EXPECT_NEAR(img[p * 4 + 3], 1 - T, 1e-14);
    }
  }
  EXPECT_LT(err[1], 0.6 * std::pow(2.0 / 120, 2) / 24 * 1.01);
  EXPECT_NEAR(err[0] / err[1], 4.0, 0.01);
}

// Voxels d_i = 0.125 + 0.25 i (exact in float) along x (constant along y, z), identity TF: optical
// depths follow from the clamped linear profile in closed form.
TEST(Reference, LinearRampOpticalDepth) {
  const int n = 6;
  Scene s = test::constant_scene(0.f, n, 12);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) s.volume.data[(k * n + j) * n + i] = float(0.125 + 0.25 * i);
  s.tf.extinction_scale = 2;
  const double h = 1.0 / n, x0 = -0.5;
  auto d_of_x = [&](double x) {  // the continuous profile, clamped in the border half-voxels
    const double u = std::min(std::max((x - x0) / h - 0.5, 0.0), double(n - 1));
    return 0.125 + 0.25 * u;
  };
  // Ortho rays along -z: tau = 2 * d(x) * 1, pixel centres at x = -0.5 + (p + 0.5)/12.
  auto img = reference::render(s, 0.05);
  for (int y = 0; y < 12; ++y)
    for (int x = 0; x < 12; ++x)
      EXPECT_NEAR(img[y * 12 + x], std::exp(-2 * d_of_x(-0.5 + (x + 0.5) / 12)), 1e-14);
  // A ray along +x from inside the first border half-voxel: constant part, ramp, constant part.
  Camera c;
  const double start = x0 + 0.2 * h;
  c.eye = {start, 0.01, -0.02};
  c.target = {1, 0.01, -0.02};
  c.width = c.height = 1;
  s.cameras = {c};
  const double d0 = 0.125, d1 = 0.125 + 0.25 * (n - 1);
  const double tau = 2 * ((0.5 - 0.2) * h * d0 + (n - 1) * h * 0.5 * (d0 + d1) + 0.5 * h * d1);
  img = reference::render(s, 0.05);
  EXPECT_NEAR(img[0], std::exp(-tau), 1e-13);
}

TEST(Reference, MissingRaysSeeTheBackground) {
  Scene s = test::constant_scene(1.f, 2, 2);
  s.model = Model::emission_absorption;
  s.background = glm::dvec3(0.1, 0.2, 0.3);
  s.cameras[0].eye = {5, 0, 2};  // looks down -z beside the box
  s.cameras[0].target = {5, 0, 0};
  const auto img = reference::render(s, 0.1);
  for (int p = 0; p < 4; ++p) {
    EXPECT_EQ(img[p * 4 + 0], 0.1);
    EXPECT_EQ(img[p * 4 + 2], 0.3);
    EXPECT_EQ(img[p * 4 + 3], 0.0);
  }
}

// render_midpoint is the midpoint integrator's own discretisation: a float32 render equals it up to
// rounding (with and without early termination), and it converges to the continuous integral at
// the midpoint rule's second order.
TEST(Reference, MidpointReferenceIsTheKernelsDiscretisation) {
  Scene scene = calibration_scene(24, 32);
  for (double extinction_scale : {1.0, 20.0}) {  // ×20: most rays stop early
    Scene s = scene;
    for (TfPoint& p : s.tf.points) p.extinction *= extinction_scale;
    for (double step : {0.5, 0.37}) {
      const double h = reference::min_voxel_edge(s);
      const std::vector<double> want = reference::render_midpoint(s, step * h, true);
      const Image got = test::render_at(s, Precision::f32, step);
      double worst = 0, scale = 0;
      for (std::size_t i = 0; i < want.size(); ++i) {
        worst = std::max(worst, std::abs(got.pixels[i] - want[i]));
        scale = std::max(scale, std::abs(want[i]));
      }
      EXPECT_LE(worst, 2e-5 + 1e-4 * scale) << "σ ×" << extinction_scale << " step " << step;
    }
  }
  const std::vector<double> truth = reference::render_continuous(scene);
  auto error = [&](double step) {
    const std::vector<double> r =
        reference::render_midpoint(scene, step * reference::min_voxel_edge(scene));
    double sum = 0;
    for (std::size_t i = 0; i < r.size(); ++i) sum += (r[i] - truth[i]) * (r[i] - truth[i]);
    return std::sqrt(sum);
  };
  const double coarse = error(1.0), fine = error(0.5);
  EXPECT_GT(coarse / fine, 3.0) << coarse << " " << fine;  // ~4: second order
  EXPECT_LT(coarse / fine, 5.5) << coarse << " " << fine;
}

}  // namespace
}  // namespace ivr
