// brick_support.hpp — the out-of-core tests' scene and comparisons (bricked_render_test,
// bricked_gradient_test, domain_test).
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "ivr/render.hpp"
#include "test_support.hpp"

namespace ivr::test {

// A noisy volume of odd, unequal dims (bricks end short of the edge) with a TF that has colour,
// zero-extinction stretches and enough extinction that some rays stop early.
inline Scene bricked_scene(Model model, Scheme scheme) {
  Scene s;
  s.volume.nx = 11, s.volume.ny = 9, s.volume.nz = 13;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  s.volume.data.resize(s.volume.voxel_count());
  for (float& v : s.volume.data) v = u(rng);
  set_default_box(s);
  s.model = model;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0, 0, 0}, 0.0},
                 {0.3, {0.2, 0.9, 0.4}, 0.0},
                 {0.6, {1.0, 0.5, 0.1}, 60.0},
                 {1.0, {0.3, 0.3, 1.0}, 30.0}};
  s.integrator.scheme = scheme;
  s.integrator.step = 0.37;
  s.background = {0.1, 0.2, 0.3};
  auto persp = [](glm::dvec3 eye, glm::dvec3 target) {
    Camera c;
    c.eye = eye, c.target = target, c.fov_y = 50, c.width = 11, c.height = 9;
    return c;
  };
  s.cameras = {persp({0.3, 0.4, 2.0}, {0, 0, 0}), persp({-1.6, -0.7, -0.9}, {0.05, 0, 0}),
               persp({0.05, -0.1, 0.1}, {1, 0.3, 0.2}),  // inside the volume
               persp({0.3, 0.4, 2.0}, {0.01, 0, 0})};
  // Orthographic down −z and along +x: rays whose x (and y) lie on the voxel-centre planes that
  // the bricks' faces are made of (11 voxels, 11 pixels across the box).
  s.cameras.push_back(ortho({0, 0, 2}, {0, 1, 0}, 11, 9, s.box_max.y - s.box_min.y));
  Camera side = ortho({-2, 0, 0}, {0, 1, 0}, 11, 9, s.box_max.y - s.box_min.y);
  s.cameras.push_back(side);
  return s;
}

// `count` ray-list rows (origin, direction, t_start, t_end) from `seed`: rays from inside and
// outside the volume, ends inside the box and infinite ones.
inline std::vector<double> random_ray_rows(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> rows;
  for (int r = 0; r < count; ++r) {
    const double o[3] = {u(rng) * (r % 2 ? 0.3 : 1.5), u(rng) * 0.3, u(rng) * (r % 2 ? 0.3 : 1.5)};
    double d[3] = {-o[0] + 0.2 * u(rng), -o[1] + 0.2 * u(rng), -o[2] + 0.2 * u(rng)};
    if (r % 2) d[0] = u(rng), d[1] = u(rng), d[2] = u(rng);
    const double t0 = r % 3 == 0 ? -INFINITY : 0.1 * std::abs(u(rng));
    const double t1 = r % 4 == 0 ? INFINITY : 0.5 + std::abs(u(rng));
    rows.insert(rows.end(), {o[0], o[1], o[2], d[0], d[1], d[2], t0, t1});
  }
  return rows;
}

inline double largest(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

// Every value of `got` within tol × the largest |value| of `want`; none NaN/Inf.
inline void expect_close_values(const std::vector<double>& want, const std::vector<double>& got,
                                double tol, const std::string& what) {
  ASSERT_EQ(want.size(), got.size()) << what;
  const double scale = std::max(largest(want), 1e-30);
  int bad = 0;
  for (std::size_t i = 0; i < want.size() && bad < 5; ++i)
    if (!std::isfinite(got[i]) || std::abs(want[i] - got[i]) > tol * scale) {
      ADD_FAILURE() << what << ": element " << i << " want " << want[i] << ", got " << got[i];
      ++bad;
    }
}

// A gradient test's target: `image` dimmed (0.8 v + 0.05), its float32 pixels alone.
inline Image dimmed(const Image& image) {
  Image target = image;
  for (float& v : target.pixels) v = 0.8f * v + 0.05f;
  target.pixels_f64.clear();
  return target;
}

// Every pixel within tol × the largest |value| of the in-core image; none NaN/Inf.
inline void expect_same(const Image& in_core, const Image& bricked, double tol,
                        const std::string& what) {
  const std::vector<double> a =
      in_core.pixels_f64.empty() ? std::vector<double>(in_core.pixels.begin(), in_core.pixels.end())
                                 : in_core.pixels_f64;
  const std::vector<double> b =
      bricked.pixels_f64.empty() ? std::vector<double>(bricked.pixels.begin(), bricked.pixels.end())
                                 : bricked.pixels_f64;
  expect_close_values(a, b, tol, what);
}

}  // namespace ivr::test
