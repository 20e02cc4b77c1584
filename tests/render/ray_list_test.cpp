// ray_list_test.cpp — ray lists (docs/design.md, "Ray lists"): a camera's rays as a list give the
// camera's image bit for bit (every scheme, both models, skipping), finite rays against closed
// forms and the float64 reference, the scene file's "rays", sessions switching geometry, and the
// errors of bad rays.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "ivr/session.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using test::device;
using test::has;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// A scene with the camera's pixels as a ray list instead of the camera.
Scene as_ray_list(const Scene& scene, bool f64) {
  Scene r = scene;
  r.rays = ray_list_of_camera(scene.cameras.front(), f64);
  r.cameras.clear();
  return r;
}

Scene sphere_scene(Model model, Scheme scheme, const Camera& camera) {
  Scene s;
  s.volume = synthetic_volume("sphere", 12, 10, 9);
  set_default_box(s);
  s.model = model;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.1, 0.2, 0.9}, 0.0}, {0.5, {0.9, 0.4, 0.1}, 6.0}, {1.0, {1, 1, 1}, 12.0}};
  s.cameras = {camera};
  s.integrator.scheme = scheme;
  s.integrator.step = 0.7;
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  if (model == Model::absorption) s.background = glm::dvec3(1.0);
  return s;
}

Camera perspective_camera() {
  Camera c;
  c.eye = {1.1, 0.6, 1.7};
  c.up = {0, 1, 0};
  c.fov_y = 38;
  c.width = 21;
  c.height = 17;
  return c;
}

TEST(RayList, CameraRaysRenderTheCameraImageBitForBit) {
  const Camera cameras[2] = {perspective_camera(),
                             test::ortho({-0.4, 1.3, 1.2}, {0, 0, 1}, 19, 13, 1.5)};
  for (const Camera& cam : cameras)
    for (Model model : {Model::absorption, Model::emission_absorption})
      for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated,
                            Scheme::exact}) {
        if (scheme == Scheme::exact && model != Model::absorption) continue;
        const Scene s = sphere_scene(model, scheme, cam);
        const Image a = test::render_at(s, Precision::f32, 0);
        const Image b = test::render_at(as_ray_list(s, false), Precision::f32, 0);
        const std::string what = std::string(scheme_name(scheme)) + " " +
                                 (model == Model::absorption ? "absorption" : "emission") + " " +
                                 (cam.projection == Projection::orthographic ? "ortho" : "persp");
        ASSERT_EQ(b.views, 1) << what;
        ASSERT_EQ(b.height, 1) << what;
        ASSERT_EQ(b.width, cam.width * cam.height) << what;
        ASSERT_EQ(a.pixels.size(), b.pixels.size()) << what;
        EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * 4)) << what;
      }
}

TEST(RayList, CameraRaysMatchWithOneRayPerWorkItemAndWithSkipping) {
  // The one-ray kernel (GPUs' layout) and empty-space skipping (a TF zero below 0.3).
  const test::ScopedEnv one_ray("IVR_PACKET", "0");
  Scene s = sphere_scene(Model::emission_absorption, Scheme::midpoint, perspective_camera());
  s.tf.points = {{0.0, {0, 0, 0}, 0.0}, {0.3, {0, 0, 0}, 0.0}, {1.0, {1, 0.5, 0.2}, 9.0}};
  RenderOptions o;
  o.empty_space = EmptySpace::on;
  RenderStats sa, sb;
  const Image a = render(device(), s, o, &sa);
  const Image b = render(device(), as_ray_list(s, false), o, &sb);
  EXPECT_TRUE(sa.skipped_empty);
  EXPECT_TRUE(sb.skipped_empty);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * 4));
}

// A constant density c in the unit box with the identity TF: T = exp(−c·L) over the part of the
// ray's interval inside the box (trilinear of a constant is the constant: every scheme is exact).
TEST(RayList, FiniteRaysAgainstTheClosedFormOfAConstantDensity) {
  const double c = double(1.7f);
  Scene s = test::constant_scene(1.7f, 6);
  s.cameras.clear();
  const double inf = INFINITY;
  // ox oy oz dx dy dz t0 t1 and the length inside the box.
  const std::vector<std::pair<std::vector<double>, double>> rays = {
      {{0, 0, 0, 1, 0, 0, 0, 0.3}, 0.3},              // starts and ends inside (mid-voxel)
      {{-2, 0.1, 0, 1, 0, 0, 0, 1.8}, 0.3},           // starts outside, ends inside
      {{0.2, -0.3, 0.1, 0, 0, 1, 0, inf}, 0.4},       // starts inside, to the box exit
      {{0.2, -0.3, 0.1, 0, 0, 1, -inf, inf}, 1.0},    // the whole chord
      {{0.2, -0.3, 0.1, 0, 0, 1, -inf, 0.0}, 0.6},    // from the box entry to the origin
      {{0.1, 0.1, 0.1, 0, 1, 0, 0.25, 0.25}, 0.0},    // length 0
      {{0.1, 0.1, 0.1, 0, 1, 0, 0.5, 0.9}, 0.0},      // the interval lies past the box
      {{-0.3, -0.3, -0.3, 3, 3, 3, 0.1, 0.5}, 0.4},   // direction normalised: t in world units
      {{2, 2, 2, 1, 0, 0, 0, inf}, 0.0},              // misses
  };
  std::vector<double> flat;
  for (const auto& r : rays) flat.insert(flat.end(), r.first.begin(), r.first.end());
  s.rays = make_ray_list(flat.data(), rays.size(), 8);
  for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::exact})
    for (Precision p : {Precision::f32, Precision::f64}) {
      s.integrator.scheme = scheme;
      const Image img = test::render_at(s, p, 0.5);
      ASSERT_EQ(img.width, int(rays.size()));
      for (std::size_t i = 0; i < rays.size(); ++i) {
        const double want = std::exp(-c * rays[i].second);
        const double got = p == Precision::f64 ? img.pixels_f64[i] : img.pixels[i];
        EXPECT_NEAR(got, want, (p == Precision::f64 ? 1e-13 : 2e-6) * (1 + want))
            << "ray " << i << " " << scheme_name(scheme) << " " << test::name(p);
      }
    }
}

// Densities linear in x at the voxel centres: the trilinear interpolant is that line between the
// outer centres, so the projector's line integral along x is the line's integral.
TEST(RayList, ProjectionOfALinearDensityAgainstItsIntegral) {
  const int n = 8;
  Scene s = test::constant_scene(0, n);
  s.cameras.clear();
  const double h = 1.0 / n;
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x)
        s.volume.data[(std::size_t(z) * n + y) * n + x] = float(0.5 + 0.25 * x);
  // d(x_world) = 0.5 + 0.25·(x_world + 0.5 − h/2)/h inside [−0.5 + h/2, 0.5 − h/2].
  const auto d = [&](double xw) { return 0.5 + 0.25 * ((xw + 0.5) / h - 0.5); };
  const auto integral = [&](double a, double b) {  // ∫_a^b d
    return (b - a) * 0.5 * (d(a) + d(b));
  };
  const double a0 = -0.5 + h / 2;
  const std::vector<double> flat = {a0, 0.03, -0.11, 1, 0, 0, 0.0, 0.37,   // ends inside a cell
                                    0.1, 0.2, 0.05, -1, 0, 0, 0.05, 0.4,   // backwards
                                    -0.2, 0.0, 0.0, 1, 0, 0, 0.13, 0.13};  // length 0
  s.rays = make_ray_list(flat.data(), 3, 8);
  Projector N(device(), s, Precision::f64);
  const std::vector<double> lines =
      N.project(std::vector<double>(s.volume.data.begin(), s.volume.data.end()));
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_NEAR(lines[0], integral(a0, a0 + 0.37), 1e-13);
  EXPECT_NEAR(lines[1], integral(0.1 - 0.4, 0.1 - 0.05), 1e-13);
  EXPECT_EQ(lines[2], 0.0);
}

// Random finite rays (inside, outside, through, ending inside voxels) against the float64
// reference of the same discretisation, both models, both precisions.
TEST(RayList, RandomFiniteRaysAgainstTheFloat64Reference) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::size_t count = 300;
  std::vector<double> flat;
  for (std::size_t i = 0; i < count; ++i) {
    const double o[3] = {0.8 * u(rng), 0.8 * u(rng), 0.8 * u(rng)};
    const double d[3] = {u(rng), u(rng), u(rng)};
    const double t0 = i % 5 == 0 ? -INFINITY : 0.3 * u(rng);
    const double t1 = i % 7 == 0 ? INFINITY : t0 + 0.9 * (u(rng) + 1) / 2 * (i % 5 == 0 ? 0 : 1);
    flat.insert(flat.end(), {o[0], o[1], o[2], d[0], d[1], d[2], t0,
                             i % 5 == 0 ? INFINITY : t1});
  }
  for (Model model : {Model::absorption, Model::emission_absorption}) {
    Scene s = sphere_scene(model, Scheme::midpoint, perspective_camera());
    s.cameras.clear();
    s.rays = make_ray_list(flat.data(), count, 8);
    s.integrator.min_transmittance = 0;
    const double step = 0.5 * reference::min_voxel_edge(s);
    const std::vector<double> ref = reference::render_midpoint(s, step, false);
    for (Precision p : {Precision::f32, Precision::f64}) {
      const Image img = test::render_at(s, p, 0.5);
      ASSERT_EQ(img.pixels.size(), ref.size());
      const double tol = p == Precision::f64 ? 1e-11 : 2e-5;
      for (std::size_t i = 0; i < ref.size(); ++i) {
        const double got = p == Precision::f64 ? img.pixels_f64[i] : img.pixels[i];
        ASSERT_NEAR(got, ref[i], tol * (1 + std::abs(ref[i])))
            << "ray " << i / s.channels() << " channel " << i % s.channels() << " "
            << test::name(p);
      }
    }
  }
}

TEST(RayList, SixColumnsAreStartAndEndPoints) {
  const std::vector<double> points = {-0.2, 0.1, 0.0, 0.3, 0.1, 0.0,  // length 0.5 along +x
                                      0.1, 0.1, 0.1, 0.1, 0.1, 0.1};  // length 0
  const RayList r = make_ray_list(points.data(), 2, 6);
  ASSERT_EQ(r.count(), 2u);
  const std::vector<double> want0 = {-0.2, 0.1, 0.0, 1, 0, 0, 0, 0.5};
  for (int k = 0; k < 8; ++k) EXPECT_DOUBLE_EQ(r.values[k], want0[k]) << k;
  EXPECT_EQ(r.values[8 + 6], 0.0);
  EXPECT_EQ(r.values[8 + 7], 0.0);
  Scene s = test::constant_scene(2.0f, 4);
  s.cameras.clear();
  s.rays = r;
  const Image img = test::render_at(s, Precision::f64, 0.5);
  EXPECT_NEAR(img.pixels_f64[0], std::exp(-2.0 * 0.5), 1e-13);
  EXPECT_EQ(img.pixels_f64[1], 1.0);
}

TEST(RayList, BadRaysNameTheRayAndTheField) {
  const double inf = INFINITY, nan = NAN;
  const auto err = [](std::vector<double> v, int columns = 8) {
    return error_of([&] { make_ray_list(v.data(), v.size() / columns, columns); });
  };
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 1}),
                  "rays[1].direction: is zero"));
  EXPECT_TRUE(has(err({0, 0, nan, 1, 0, 0, 0, 1}), "rays[0].origin.z: is NaN"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, inf, 0, 0, 1}), "rays[0].direction.y: is inf"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, 0, 0.5, 0.2}), "rays[0].t_end: 0.2 is before t_start 0.5"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, 0, inf, inf}), "rays[0].t_start: is inf"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, 0, 0, -inf}), "rays[0].t_end: is -inf"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, 0, 0, nan}), "rays[0].t_end: is NaN"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, inf}, 6), "rays[0].end.z: is inf"));
  EXPECT_TRUE(has(err({0, 0, 0, 1, 0, 0, 0}, 7), "8 columns"));
  EXPECT_TRUE(has(err({}, 8), "no rays"));
  // A scene with both, or with a list not from make_ray_list.
  Scene s = test::constant_scene(1.0f);
  s.rays = ray_list_of_camera(s.cameras[0]);
  EXPECT_TRUE(has(error_of([&] { validate(s); }), "cameras or a ray list, not both"));
  s.cameras.clear();
  s.rays.values[3] = 2;  // direction (2, …): not unit
  EXPECT_TRUE(has(error_of([&] { validate(s); }), "rays[0]: its direction is not unit length"));
}

TEST(RayList, CameraGradientsOfARayListAreRefused) {
  Scene s = as_ray_list(test::constant_scene(1.0f), false);
  const Image target = test::render_at(s, Precision::f32, 0);
  for (Mode mode : {Mode::adjoint, Mode::forward}) {
    GradientOptions o;
    o.mode = mode;
    const std::string e = error_of([&] { gradient(device(), s, target, {"camera"}, o); });
    EXPECT_TRUE(has(e, "ray list")) << e;
  }
}

TEST(RayList, SceneFileRaysFromNpyAndInline) {
  const std::string dir = test::temp_dir("ray_list_json");
  // rays.npy: (2, 8) float64, written by hand (the header and the raw values).
  const double values[16] = {0, 0, 0, 1, 0, 0, 0, 0.25, 0.1, 0.1, -2, 0, 0, 1, 0, INFINITY};
  {
    std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 8), }";
    while ((10 + header.size() + 1) % 64) header += ' ';
    header += '\n';
    std::ofstream f(dir + "/rays.npy", std::ios::binary);
    f.write("\x93NUMPY\x01\x00", 8);
    const unsigned short len = (unsigned short)header.size();
    f.write(reinterpret_cast<const char*>(&len), 2);
    f << header;
    f.write(reinterpret_cast<const char*>(values), sizeof values);
  }
  const std::string head =
      R"({"volume": {"synthetic": "zeros", "dims": [4, 4, 4]}, "model": "absorption", )";
  Scene a = parse_scene(head + R"("rays": {"file": "rays.npy"}})", dir);
  ASSERT_EQ(a.rays.count(), 2u);
  EXPECT_TRUE(a.cameras.empty());
  for (int k = 0; k < 16; ++k) EXPECT_EQ(a.rays.values[k], values[k]) << k;
  Scene b = parse_scene(
      head + R"("rays": [[0, 0, 0, 1, 0, 0, 0, 0.25], [0.1, 0.1, -2, 0, 0, 1, 0, "inf"]]})", dir);
  EXPECT_EQ(b.rays.values, a.rays.values);
  EXPECT_TRUE(has(error_of([&] {
                    parse_scene(head + R"("rays": [[0, 0, 0, 0, 0, 0, 0, 1]]})", dir, "s.json");
                  }),
                  "s.json: rays[0].direction: is zero"));
  EXPECT_TRUE(has(error_of([&] {
                    parse_scene(head + R"("rays": [[0, 0, 0, 1, 0, 0, 0, 1]], "cameras": []})",
                                dir);
                  }),
                  "cameras or rays, not both"));
  EXPECT_TRUE(has(error_of([&] { parse_scene(head + R"("rays": {"file": "none.npy"}})", dir); }),
                  "none.npy"));
}

TEST(RayList, SessionsSwitchBetweenCamerasAndRays) {
  Scene s = sphere_scene(Model::emission_absorption, Scheme::midpoint, perspective_camera());
  Session session(device(), s);
  const std::vector<float> camera_image = session.render().to_floats();
  const RayList rays = ray_list_of_camera(s.cameras[0]);
  session.set_rays(rays);
  const DeviceArray image = session.render();
  EXPECT_EQ(image.shape(), (std::vector<std::int64_t>{std::int64_t(rays.count()), 4}));
  EXPECT_EQ(image.to_floats(), camera_image);
  // A target of the image's shape, then a gradient; back to cameras drops the target.
  session.set_target(image);
  const SessionGradient g = session.gradient();
  EXPECT_EQ(g.loss.to_doubles()[0], 0.0);
  session.set_cameras(s.cameras);
  EXPECT_EQ(session.render().to_floats(), camera_image);
  EXPECT_TRUE(has(error_of([&] { session.gradient(); }), "target"));
  // A bad list changes nothing.
  RayList bad = rays;
  bad.values[5] = 7;
  EXPECT_TRUE(has(error_of([&] { session.set_rays(bad); }), "not unit length"));
  EXPECT_EQ(session.render().to_floats(), camera_image);
}

}  // namespace
}  // namespace ivr
