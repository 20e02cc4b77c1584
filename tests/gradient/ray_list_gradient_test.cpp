// ray_list_gradient_test.cpp — gradients over ray lists: a camera's rays as a list give the
// camera's gradients (the deterministic density gradient bit for bit); the density, TF and
// background gradients of finite rays agree with central differences of the float64 loss in
// both modes; and so do the gradients with respect to the rays themselves (origin, direction,
// t_start, t_end) for every integrator and both models.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <cstring>
#include <glm/geometric.hpp>
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

// The float64 render of `s` with voxel i's density scaled by factor(i): a target the scene misses.
template <class Factor>
Image f64_target(Scene s, Factor factor) {
  for (std::size_t i = 0; i < s.volume.data.size(); ++i) s.volume.data[i] *= float(factor(i));
  RenderOptions ro;
  ro.precision = Precision::f64;
  return render(device(), s, ro);
}

TEST(RayListGradient, FiniteRaysAgainstCentralDifferences) {
  Scene s = emission_scene();
  s.rays = finite_rays(400, 17);
  const Image target = f64_target(s, [](std::size_t i) { return 0.8 + 0.4 * double(i % 7) / 6; });
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

// Rays of every kind for the ray-parameter gradients: both ends inside the box, a finite start
// outside it (a box face bounds the march), ±∞ ends (the box's entry and exit), an end past the
// box. Directions random; lengths kept away from 0.
RayList mixed_rays(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.45, 0.45), dir(-1, 1);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> rows;
  for (std::size_t i = 0; i < count; ++i) {
    glm::dvec3 d(dir(rng), dir(rng), dir(rng));
    d /= glm::length(d);
    const glm::dvec3 o(u(rng), u(rng), u(rng));
    double t0 = 0, t1 = 0.3 + 0.2 * std::abs(dir(rng));
    switch (i % 4) {
      case 0: break;                                    // inside to inside
      case 1: t0 = -1.5; break;                         // from outside the box
      case 2: t0 = -inf, t1 = inf; break;               // through the box
      default: t0 = 0.05, t1 = 3.0; break;              // to past the box
    }
    rows.insert(rows.end(), {o.x, o.y, o.z, d.x, d.y, d.z, t0, t1});
  }
  return make_ray_list(rows.data(), count, 8);
}

// The list with column `column` of every ray moved by eps · v[ray]: origins and ends directly,
// directions as normalize(d + eps · v) (ivr normalises the directions it is given).
RayList moved_rays(const RayList& rays, int column, const std::vector<double>& v, double eps) {
  std::vector<double> rows = rays.values;
  for (std::size_t r = 0; r < rays.count(); ++r) {
    double* row = rows.data() + r * 8;
    if (column >= 3 && column <= 5) {
      glm::dvec3 d(row[3], row[4], row[5]);
      d[column - 3] += eps * v[r];
      d /= glm::length(d);
      row[3] = d.x, row[4] = d.y, row[5] = d.z;
    } else if (std::isfinite(row[column])) {
      row[column] += eps * v[r];
    }
  }
  return make_ray_list(rows.data(), rays.count(), 8);
}

double session_loss(Session& s, const RayList& rays) {
  s.set_rays(rays);
  GradientRequest q;
  q.wrt = {"background"};
  q.mode = Mode::forward;
  return s.gradient(q).loss.to_doubles()[0];
}

struct RayCase {
  Scheme scheme;
  Model model;
};

class RayParameterGradient : public ::testing::TestWithParam<RayCase> {};

// d loss / d every ray's column k against central differences of the float64 loss, column by
// column (a random direction over every ray's column), and the float32 gradient against the
// float64 one.
TEST_P(RayParameterGradient, EveryColumnAgainstCentralDifferences) {
  Scene s = emission_scene();
  s.integrator.scheme = GetParam().scheme;
  s.model = GetParam().model;
  if (s.model == Model::absorption) s.background = glm::dvec3(1.0);
  const std::size_t count = 48;
  s.rays = mixed_rays(count, 29);
  const Image target = f64_target(s, [](std::size_t i) { return 0.7 + 0.6 * double(i % 5) / 4; });

  SessionOptions so;
  so.precision = Precision::f64;
  Session f64(device(), s, so);
  f64.set_target(target);
  GradientRequest q;
  q.wrt = {"rays"};
  q.mode = Mode::automatic;  // forward: the only mode with ray parameters
  const SessionGradient g = f64.gradient(q);
  EXPECT_EQ(g.plan.mode, Mode::forward);
  const DeviceArray& ga = g["rays"];
  ASSERT_EQ(ga.shape(), (std::vector<std::int64_t>{std::int64_t(count), 8}));
  const std::vector<double> grad = ga.to_doubles();

  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const double eps = 1e-6;
  double largest = 0;
  for (double x : grad) largest = std::max(largest, std::abs(x));
  ASSERT_GT(largest, 0);
  Session probe(device(), s, so);
  probe.set_target(target);
  for (int column = 0; column < 8; ++column) {
    std::vector<double> v(count);
    for (double& x : v) x = u(rng);
    double analytic = 0;
    for (std::size_t r = 0; r < count; ++r) {
      const double* row = s.rays.values.data() + r * 8;
      if (column >= 6 && !std::isfinite(row[column])) {
        EXPECT_EQ(grad[r * 8 + column], 0.0) << "ray " << r << ": an infinite end";
        continue;
      }
      analytic += grad[r * 8 + column] * v[r];
    }
    const double fd = (session_loss(probe, moved_rays(s.rays, column, v, eps)) -
                       session_loss(probe, moved_rays(s.rays, column, v, -eps))) /
                      (2 * eps);
    EXPECT_NEAR(analytic, fd, 1e-5 * std::abs(fd) + 1e-9 * largest) << "column " << column;
  }
  // The directions' gradients are tangent to the unit sphere.
  for (std::size_t r = 0; r < count; ++r) {
    const double* row = s.rays.values.data() + r * 8;
    const double along =
        row[3] * grad[r * 8 + 3] + row[4] * grad[r * 8 + 4] + row[5] * grad[r * 8 + 5];
    EXPECT_NEAR(along, 0, 1e-12 * largest) << "ray " << r;
  }

  Session f32(device(), s);
  f32.set_target(target);
  const std::vector<double> g32 = f32.gradient(q)["rays"].to_doubles();
  for (std::size_t i = 0; i < grad.size(); ++i)
    EXPECT_NEAR(g32[i], grad[i], 2e-3 * largest + 1e-3 * std::abs(grad[i])) << "entry " << i;
}

INSTANTIATE_TEST_SUITE_P(
    Schemes, RayParameterGradient,
    ::testing::Values(RayCase{Scheme::midpoint, Model::emission_absorption},
                      RayCase{Scheme::trapezoid, Model::absorption},
                      RayCase{Scheme::exact, Model::absorption},  // absorption only
                      RayCase{Scheme::preintegrated, Model::emission_absorption}),
    [](const ::testing::TestParamInfo<RayCase>& i) {
      return std::string(scheme_name(i.param.scheme)) + "_" +
             (i.param.model == Model::absorption ? "absorption" : "emission");
    });

// The rays' gradient beside other groups and listed one by one through jacobian(): the same
// values; and the errors.
TEST(RayListGradient, RayParametersWithOtherGroupsAndErrors) {
  Scene s = emission_scene();
  s.rays = mixed_rays(20, 41);
  const Image target = f64_target(s, [](std::size_t) { return 1.2; });
  GradientOptions o;
  o.precision = Precision::f64;
  const Gradient alone = gradient(device(), s, target, {"rays"}, o);
  const Gradient mixed = gradient(device(), s, target, {"background", "rays", "tf"}, o);
  // The plan reports the passes that run: the rays' own pass of 8 lanes, after the others'.
  EXPECT_EQ(alone.plan.mode, Mode::forward);
  EXPECT_EQ(alone.plan.passes, 1u);
  EXPECT_EQ(alone.plan.lanes, 8u);
  EXPECT_EQ(mixed.plan.passes, 2u);
  EXPECT_EQ(mixed.plan.lanes, 16u);  // background 3 + TF 3 × 4 = 15 lanes → 16
  ASSERT_EQ(mixed.groups.size(), 3u);
  EXPECT_EQ(mixed.groups[1].name, "rays");
  EXPECT_EQ(mixed.groups[1].shape, (std::vector<std::size_t>{20, 8}));
  EXPECT_EQ(mixed.groups[1].values, alone.groups[0].values);
  // The same forward pass of background and TF lanes (left to the planner, a GPU takes the adjoint).
  GradientOptions forward = o;
  forward.mode = Mode::forward;
  const Gradient tf_only = gradient(device(), s, target, {"background", "tf"}, forward);
  EXPECT_EQ(mixed.groups[0].values, tf_only.groups[0].values);
  EXPECT_EQ(mixed.groups[2].values, tf_only.groups[1].values);
  EXPECT_DOUBLE_EQ(mixed.loss, tf_only.loss);

  // Parameters listed in any order, mixed with others.
  const std::vector<Parameter> listed = {{ParameterGroup::ray, 7, 6},
                                         {ParameterGroup::background, 1, 0},
                                         {ParameterGroup::ray, 3, 0},
                                         {ParameterGroup::ray, 19, 4}};
  JacobianOptions jo;
  jo.precision = Precision::f64;
  const Jacobian j = jacobian(device(), s, listed, &target, jo);
  ASSERT_EQ(j.gradient.size(), 4u);
  EXPECT_DOUBLE_EQ(j.gradient[0], alone.groups[0].values[7 * 8 + 6]);
  EXPECT_DOUBLE_EQ(j.gradient[1], tf_only.groups[0].values[1]);
  EXPECT_DOUBLE_EQ(j.gradient[2], alone.groups[0].values[3 * 8 + 0]);
  EXPECT_DOUBLE_EQ(j.gradient[3], alone.groups[0].values[19 * 8 + 4]);

  auto message = [&](auto&& call) {
    try {
      call();
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument);
      return std::string(e.what());
    }
    return std::string("no error");
  };
  o.mode = Mode::adjoint;
  EXPECT_NE(message([&] { gradient(device(), s, target, {"rays"}, o); }).find("'rays'"),
            std::string::npos);
  jo.jacobian = true;
  EXPECT_NE(message([&] { jacobian(device(), s, listed, &target, jo); }).find("Jacobian of ray"),
            std::string::npos);
  jo.jacobian = false;
  EXPECT_NE(message([&] { jacobian(device(), s, listed, nullptr, jo); }).find("need a target"),
            std::string::npos);
  EXPECT_NE(message([&] {
              jacobian(device(), s, {{ParameterGroup::ray, 20, 0}}, &target, jo);
            }).find("ray 20 column 0 (rays: 20"),
            std::string::npos);
  Scene cameras = emission_scene();
  cameras.cameras = {Camera{}};
  EXPECT_NE(message([&] { parameters_of(cameras, "rays"); }).find("needs a scene of rays"),
            std::string::npos);
}

}  // namespace
}  // namespace ivr
