// ray_list_gradient_test.cpp — gradients over ray lists: a camera's rays as a list give the
// camera's gradients (the deterministic density gradient bit for bit), and the density, TF and
// background gradients of finite rays agree with central differences of the float64 loss in
// both modes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "ivr/session.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using test::device;

Scene emission_scene() {
  Scene s;
  s.volume = synthetic_volume("sphere", 8, 7, 6);
  for (float& d : s.volume.data) d += 0.1f;  // > 0: central differences stay in range
  set_default_box(s);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.2, 0.3, 0.8}, 1.0}, {0.6, {0.9, 0.5, 0.1}, 5.0}, {1.2, {1, 1, 1}, 9.0}};
  s.background = glm::dvec3(0.2, 0.1, 0.3);
  s.integrator.min_transmittance = 0;  // no threshold for a difference quotient to jump over
  return s;
}

// Rays that start and end inside the box, from outside into it, and through it.
RayList finite_rays(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  std::vector<double> points;
  for (std::size_t i = 0; i < count; ++i)
    points.insert(points.end(), {u(rng), u(rng), u(rng), u(rng), u(rng), u(rng)});
  return make_ray_list(points.data(), count, 6);
}

TEST(RayListGradient, CameraRaysGiveTheCameraGradients) {
  Scene s = emission_scene();
  Camera c;
  c.eye = {0.9, -1.2, 1.4};
  c.width = 15;
  c.height = 12;
  s.cameras = {c};
  Scene r = s;
  r.rays = ray_list_of_camera(c);
  r.cameras.clear();
  Session a(device(), s), b(device(), r);
  Scene perturbed = s;
  for (float& d : perturbed.volume.data) d *= 1.1f;
  Session t(device(), perturbed);
  const std::vector<float> target = t.render().to_floats();
  a.set_target(Image(1, c.height, c.width, 4, target));
  b.set_target(Image(1, 1, c.width * c.height, 4, target));
  GradientRequest q;
  q.wrt = {"density"};
  q.mode = Mode::adjoint;
  q.deterministic = true;
  const std::vector<float> ga = a.gradient(q)["density"].to_floats();
  const std::vector<float> gb = b.gradient(q)["density"].to_floats();
  ASSERT_EQ(ga.size(), gb.size());
  EXPECT_EQ(0, std::memcmp(ga.data(), gb.data(), ga.size() * 4));
  // The TF and background in forward mode: per-group partial sums whose grouping follows the
  // launch (rows of a tile against runs of a list), so equal to rounding.
  q.wrt = {"tf", "background"};
  q.mode = Mode::forward;
  const SessionGradient fa = a.gradient(q), fb = b.gradient(q);
  for (const char* g : {"tf", "background"}) {
    const std::vector<double> va = fa[g].to_doubles(), vb = fb[g].to_doubles();
    ASSERT_EQ(va.size(), vb.size());
    for (std::size_t i = 0; i < va.size(); ++i)
      EXPECT_NEAR(va[i], vb[i], 1e-5 * (1e-3 + std::abs(va[i]))) << g << "[" << i << "]";
  }
}

double loss_of(const Scene& s, const Image& target) {
  GradientOptions o;
  o.precision = Precision::f64;
  o.mode = Mode::forward;
  return gradient(device(), s, target, {"background"}, o).loss;
}

TEST(RayListGradient, FiniteRaysAgainstCentralDifferences) {
  Scene s = emission_scene();
  s.rays = finite_rays(400, 17);
  Scene other = s;
  for (std::size_t i = 0; i < other.volume.data.size(); ++i)
    other.volume.data[i] *= float(0.8 + 0.4 * double(i % 7) / 6);
  RenderOptions ro;
  ro.precision = Precision::f64;
  const Image target = render(device(), other, ro);
  ASSERT_EQ(target.width, 400);

  for (Mode mode : {Mode::adjoint, Mode::forward}) {
    GradientOptions o;
    o.precision = Precision::f64;
    o.mode = mode;
    const std::vector<std::string> groups =
        mode == Mode::adjoint ? std::vector<std::string>{"density", "tf", "background"}
                              : std::vector<std::string>{"tf", "background"};
    const Gradient g = gradient(device(), s, target, groups, o);
    for (const GroupGradient& gg : g.groups) {
      std::mt19937_64 rng(5);
      std::uniform_real_distribution<double> u(0, 1);
      std::vector<double> dir(gg.values.size());
      for (double& d : dir) d = u(rng);
      const double eps = 1e-5;
      auto moved = [&](double sign) {
        Scene m = s;
        if (gg.name == "density") {
          for (std::size_t i = 0; i < dir.size(); ++i)
            m.volume.data[i] = float(double(s.volume.data[i]) + sign * eps * 1e2 * dir[i]);
        } else if (gg.name == "background") {
          for (int k = 0; k < 3; ++k) (*m.background)[k] += sign * eps * dir[k];
        } else {  // tf: a row per control point, [r, g, b, extinction]
          for (std::size_t p = 0; p < m.tf.points.size(); ++p) {
            const std::size_t row = p * gg.shape[1];
            for (int k = 0; k < 3; ++k) m.tf.points[p].color[k] += sign * eps * dir[row + k];
            m.tf.points[p].extinction += sign * eps * dir[row + 3];
          }
        }
        return m;
      };
      double analytic = 0;
      for (std::size_t i = 0; i < dir.size(); ++i) analytic += gg.values[i] * dir[i];
      if (gg.name == "density") {
        // float32 densities: the actual step taken, per voxel.
        analytic = 0;
        const Scene up = moved(1), down = moved(-1);
        for (std::size_t i = 0; i < dir.size(); ++i)
          analytic += gg.values[i] * (double(up.volume.data[i]) - double(down.volume.data[i]));
        const double fd = loss_of(up, target) - loss_of(down, target);
        EXPECT_NEAR(analytic, fd, 1e-5 * std::abs(fd) + 1e-14) << "density, " << mode_name(mode);
        continue;
      }
      const double fd = (loss_of(moved(1), target) - loss_of(moved(-1), target)) / (2 * eps);
      EXPECT_NEAR(analytic, fd, 1e-5 * std::abs(fd) + 1e-10) << gg.name << ", " << mode_name(mode);
    }
  }
}

}  // namespace
}  // namespace ivr
