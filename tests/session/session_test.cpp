// session_test.cpp — the C++ core's sessions (ivr/session.hpp): results equal the one-shot
// functions' (themselves held to the float64 reference elsewhere), derived state rebuilt only when
// stale, the device-side volume check, arrays that stay valid, bad input that changes nothing,
// and sessions used from several threads.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "empty_space/empty_space_support.hpp"
#include "ivr/core.hpp"
#include "session/session.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A small emission–absorption scene with empty space around a ball (piecewise-linear TF that is
// 0 below 0.2), two views.
Scene small_scene() {
  Scene s = ball_scene(Model::emission_absorption, TfKind::piecewise_linear, 24);
  s.cameras = {hard_cameras()[0], hard_cameras()[1]};
  for (Camera& c : s.cameras) c.width = c.height = 20;
  return s;
}

double max_difference(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return INFINITY;
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, double(std::abs(a[i] - b[i])));
  return worst;
}

std::vector<float> one_shot(const Scene& s, Precision p = Precision::f32) {
  RenderOptions o;
  o.precision = p;
  return render(device(), s, o).pixels;
}

// The message of the ivr::Error `f` throws ("" if none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Session, RenderEqualsTheOneShotRenderAfterEverySetter) {
  Scene s = small_scene();
  Session session(device(), s);
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(s)), 0.0);

  s.tf.points[2].extinction = 12;  // set_tf
  session.set_tf(s.tf);
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(s)), 0.0);

  s.cameras = {hard_cameras()[2]};  // set_cameras: fewer views, another size
  s.cameras[0].width = 12;
  s.cameras[0].height = 9;
  session.set_cameras(s.cameras);
  EXPECT_EQ(session.image_shape(), (std::vector<std::int64_t>{1, 9, 12, 4}));
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(s)), 0.0);

  s.integrator.scheme = Scheme::trapezoid;  // set_integrator
  s.integrator.step = 0.7;
  session.set_integrator(s.integrator);
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(s)), 0.0);

  s.background = glm::dvec3(0.2, 0.3, 0.4);  // set_background
  session.set_background(*s.background);
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(s)), 0.0);

  Scene other = ball_scene(Model::emission_absorption, TfKind::piecewise_linear, 17);
  s.volume = other.volume;  // set_volume: another shape in the same (kept) box
  s.volume.nz = 11;
  s.volume.data.resize(s.volume.voxel_count());
  session.set_volume(s.volume);
  EXPECT_EQ(session.volume_shape(), (std::vector<std::int64_t>{11, 17, 17}));
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(s)), 0.0);

  DeviceArray doubles(device(), {11, 17, 17}, DType::f64);  // set_volume from a device array
  std::vector<double> twice(s.volume.data.begin(), s.volume.data.end());
  for (double& v : twice) v *= 0.5;
  doubles.upload(twice.data(), twice.size());
  session.set_volume(doubles);
  for (float& v : s.volume.data) v *= 0.5f;
  EXPECT_LE(max_difference(session.render().to_floats(), one_shot(s)), 1e-7);
}

TEST(Session, GridIsRebuiltOnlyWhenTheVolumeOrTheTfChanged) {
  Scene s = small_scene();
  SessionOptions o;
  o.empty_space = EmptySpace::on;
  Session session(device(), s, o);
  session.render();
  OperationStats first = session.last_stats();
  EXPECT_TRUE(first.skipped_empty);
  EXPECT_GT(first.empty_fraction, 0.2);
  EXPECT_GT(first.grid_seconds, 0.0) << "the first render builds the grid";
  session.render();
  EXPECT_EQ(session.last_stats().grid_seconds, 0.0) << "a fresh grid is not rebuilt";
  s.cameras[0].eye = {1.2, 0.5, 1.7};
  session.set_cameras(s.cameras);
  session.render();
  EXPECT_EQ(session.last_stats().grid_seconds, 0.0) << "cameras do not touch the grid";

  s.tf.points[1].density = 0.4;  // a wider zero range: more empty bricks
  session.set_tf(s.tf);
  const std::vector<float> image = session.render().to_floats();
  const OperationStats after_tf = session.last_stats();
  EXPECT_GT(after_tf.grid_seconds, 0.0);
  EXPECT_GT(after_tf.empty_fraction, first.empty_fraction);
  RenderOptions ro;
  ro.empty_space = EmptySpace::off;  // the skip leaves the image as it is, up to rounding
  EXPECT_LE(max_difference(image, render(device(), s, ro).pixels), 2e-6);

  for (float& v : s.volume.data) v = std::min(1.0f, v * 1.5f);  // a bigger ball: fewer empty
  session.set_volume(s.volume);
  session.render();
  const OperationStats after_volume = session.last_stats();
  EXPECT_GT(after_volume.grid_seconds, 0.0);
  EXPECT_LT(after_volume.empty_fraction, after_tf.empty_fraction);
}

// Both layouts of the check's pass (contiguous chunks per work-item on CPU devices, grid-stride
// on GPUs) on a volume whose size is no multiple of the vectors' 16.
TEST(Session, VolumeCheckFindsTheFirstBadVoxelInBothLayouts) {
  Scene s = small_scene();
  s.volume.nx = 23;
  s.volume.data.assign(s.volume.voxel_count(), 0.25f);
  for (const char* layout : {"chunks", "strided"}) {
    const ScopedEnv env("IVR_CHECK_LAYOUT", layout);
    Session session(device(), s);
    for (const std::size_t voxel : {std::size_t(0), std::size_t(5000), s.volume.data.size() - 1}) {
      Volume v = s.volume;
      v.data[voxel] = -INFINITY;
      if (voxel + 7 < v.data.size()) v.data[voxel + 7] = NAN;  // a later one is not named
      const std::size_t x = voxel % 23, y = voxel / 23 % 24, z = voxel / (23 * 24);
      const std::string want = "(x, y, z) = (" + std::to_string(x) + ", " + std::to_string(y) +
                               ", " + std::to_string(z) + ")";
      const std::string message = error_of([&] { session.set_volume(v); });
      EXPECT_TRUE(has(message, want)) << layout << ": " << message;
    }
    Volume fine = s.volume;
    fine.data[77] = 3.5f;  // the range the check reports decides the skipping shortcut
    session.set_volume(fine);
    EXPECT_EQ(session.impl().volume_max, 3.5) << layout;
    EXPECT_EQ(session.impl().volume_min, 0.25) << layout;
  }
  const ScopedEnv bad("IVR_CHECK_LAYOUT", "diagonal");
  EXPECT_TRUE(has(error_of([&] { Session(device(), s); }), "IVR_CHECK_LAYOUT must be"));
}

TEST(Session, VolumeIsCheckedOnTheDeviceAndABadOneChangesNothing) {
  Scene s = small_scene();
  Session session(device(), s);
  const std::vector<float> before = session.render().to_floats();
  const std::size_t voxel = (std::size_t(5) * 24 + 7) * 24 + 3;  // (x, y, z) = (3, 7, 5)
  for (const float bad : {NAN, INFINITY, -0.25f}) {
    Volume v = s.volume;
    v.data[voxel] = bad;
    v.data[voxel + 100] = bad;  // a later one is not the one named
    const std::string message = error_of([&] { session.set_volume(v); });
    EXPECT_TRUE(has(message, "(x, y, z) = (3, 7, 5)")) << message;
    EXPECT_TRUE(has(message, "densities must be finite and >= 0")) << message;
    std::vector<double> as_doubles(v.data.begin(), v.data.end());
    EXPECT_TRUE(has(error_of([&] { session.set_volume(as_doubles.data(), 24, 24, 24); }),
                    "(x, y, z) = (3, 7, 5)"));
    DeviceArray a(device(), {24, 24, 24}, DType::f32);
    a.upload(v.data.data(), v.data.size());
    EXPECT_TRUE(has(error_of([&] { session.set_volume(a); }), "(x, y, z) = (3, 7, 5)"));
  }
  EXPECT_TRUE(has(error_of([&] { session.set_volume(s.volume.data.data(), 24, 24, 0); }),
                  "each dimension 1 .. 2^20"));
  Volume short_volume = s.volume;
  short_volume.data.pop_back();
  EXPECT_TRUE(has(error_of([&] { session.set_volume(short_volume); }), "values for a volume"));
  DeviceArray flat(device(), {24, 576}, DType::f32);
  EXPECT_TRUE(has(error_of([&] { session.set_volume(flat); }), "densities are (nz, ny, nx)"));
  EXPECT_EQ(session.volume_shape(), (std::vector<std::int64_t>{24, 24, 24}));
  EXPECT_EQ(max_difference(session.render().to_floats(), before), 0.0);
}

TEST(Session, BadSettersAndTargetsChangeNothing) {
  Scene s = small_scene();
  Session session(device(), s);
  session.set_target(render(device(), s));
  const SessionGradient reference = session.gradient();
  const double loss = reference.loss.to_doubles()[0];
  const std::vector<float> image = session.render().to_floats();

  TransferFunction tf = s.tf;
  tf.points[0].extinction = -1;
  EXPECT_TRUE(has(error_of([&] { session.set_tf(tf); }), "extinction"));
  std::vector<Camera> cams = s.cameras;
  cams[1].eye = cams[1].target;
  EXPECT_TRUE(has(error_of([&] { session.set_cameras(cams); }), "cameras[1]"));
  EXPECT_TRUE(has(error_of([&] { session.set_cameras({}); }), "at least one camera"));
  cams = s.cameras;
  cams[1].width = 7;
  EXPECT_TRUE(has(error_of([&] { session.set_cameras(cams); }), "share width and height"));
  Integrator it = s.integrator;
  it.step = 0;
  EXPECT_TRUE(has(error_of([&] { session.set_integrator(it); }), "integrator.step"));
  it = s.integrator;
  it.scheme = Scheme::exact;  // exact is for absorption only
  EXPECT_TRUE(has(error_of([&] { session.set_integrator(it); }), "integrator.scheme"));
  EXPECT_TRUE(has(error_of([&] { session.set_background({NAN, 0, 0}); }), "finite"));
  Image target = render(device(), s);
  target.pixels[17] = NAN;
  EXPECT_TRUE(has(error_of([&] { session.set_target(target); }), "target element 17"));
  target.views = 1;
  EXPECT_TRUE(has(error_of([&] { session.set_target(target); }), "target has shape"));
  DeviceArray wrong(device(), {2, 20, 20, 1}, DType::f32);
  EXPECT_TRUE(has(error_of([&] { session.set_target(wrong); }), "(2, 20, 20, 1)"));
  DeviceArray nan_target(device(), {2, 20, 20, 4}, DType::f32);
  std::vector<float> values(nan_target.size(), 0.5f);
  values[99] = INFINITY;
  nan_target.upload(values.data(), values.size());
  EXPECT_TRUE(has(error_of([&] { session.set_target(nan_target); }), "target element 99"));
  GradientRequest request;
  request.wrt = {"densty"};
  EXPECT_TRUE(has(error_of([&] { session.gradient(request); }), "unknown parameter group"));

  // Everything as before.
  EXPECT_EQ(session.image_shape(), (std::vector<std::int64_t>{2, 20, 20, 4}));
  EXPECT_EQ(max_difference(session.render().to_floats(), image), 0.0);
  const SessionGradient again = session.gradient();
  EXPECT_NEAR(again.loss.to_doubles()[0], loss, 1e-12 + 1e-9 * loss);
  EXPECT_LE(max_difference(again["density"].to_floats(), reference["density"].to_floats()),
            1e-6);
}

TEST(Session, ArraysStayValidAcrossCalls) {
  Scene s = small_scene();
  Session session(device(), s);
  const DeviceArray first = session.render();
  const std::vector<float> expected = one_shot(s);
  Scene changed = s;
  changed.tf.points[2].color = {0.1, 0.9, 0.1};
  session.set_tf(changed.tf);
  for (int i = 0; i < 3; ++i) session.render();  // the pool must not hand `first` out again
  EXPECT_EQ(max_difference(first.to_floats(), expected), 0.0);
  EXPECT_EQ(max_difference(session.render().to_floats(), one_shot(changed)), 0.0);
  // A view of the densities shows an optimiser's in-place step.
  DeviceArray view = session.volume();
  session.set_target(render(device(), s));
  const SessionGradient g = session.gradient();
  OptimizerOptions oo;
  oo.lr = 0.05;
  oo.lower = 0;
  Optimizer opt(device(), session.volume().size(), oo);
  const std::vector<float> before = view.to_floats();
  session.step(opt, g["density"]);
  EXPECT_GT(max_difference(view.to_floats(), before), 0.0);
  for (float v : view.to_floats()) ASSERT_GE(v, 0.0f);
}

TEST(Session, GradientsEqualTheOneShotFunctions) {
  Scene s = small_scene();
  Image target = render(device(), s);
  for (float& p : target.pixels) p = 0.8f * p + 0.05f;
  Session session(device(), s);
  session.set_target(target);
  for (const Mode mode : {Mode::adjoint, Mode::forward}) {
    GradientRequest request;
    request.wrt = {"tf", "background", "camera"};
    request.mode = mode;
    const SessionGradient g = session.gradient(request);
    EXPECT_EQ(g.plan.mode, mode);
    GradientOptions o;
    o.mode = mode;
    const Gradient d = gradient(device(), s, target, request.wrt, o);
    EXPECT_NEAR(g.loss.to_doubles()[0], d.loss, 1e-9 * d.loss);
    for (std::size_t k = 0; k < d.groups.size(); ++k) {
      const std::vector<double> got = g[d.groups[k].name].to_doubles();
      ASSERT_EQ(got.size(), d.groups[k].values.size());
      for (std::size_t i = 0; i < got.size(); ++i)
        EXPECT_NEAR(got[i], d.groups[k].values[i], 1e-6 * (1 + std::abs(d.groups[k].values[i])))
            << d.groups[k].name << "[" << i << "] " << mode_name(mode);
    }
  }
  const AdjointGradient one = adjoint(device(), s, target);
  const SessionGradient density = session.gradient();
  EXPECT_LE(max_difference(density["density"].to_floats(), one.density), 1e-7);
  EXPECT_NEAR(session.loss(session.render(), session.target()).to_doubles()[0],
              image_loss(render(device(), s), target, Loss::mse), 1e-12);
}

TEST(Session, DeterministicGradientsRepeatBitForBit) {
  Scene s = small_scene();
  Image target = render(device(), s);
  for (float& p : target.pixels) p *= 0.7f;
  Session session(device(), s);
  session.set_target(target);
  GradientRequest request;
  request.deterministic = true;
  const std::vector<float> first = session.gradient(request)["density"].to_floats();
  EXPECT_TRUE(session.last_stats().deterministic);
  for (int i = 0; i < 2; ++i)
    EXPECT_EQ(session.gradient(request)["density"].to_floats(), first);
  AdjointOptions o;
  o.deterministic = true;
  EXPECT_EQ(adjoint(device(), s, target, o).density, first);
}

TEST(Session, ToleranceStepIsChosenOnTheDeviceAndAgainAfterAChange) {
  Scene s = small_scene();
  s.integrator.tolerance = 2e-3;
  Session session(device(), s);
  const StepChoice one = choose_step(device(), s, 2e-3);
  EXPECT_DOUBLE_EQ(session.integrator().step, one.step);
  for (float& v : s.volume.data) v = std::min(1.0f, 2 * v);  // denser: a finer step
  session.set_volume(s.volume);
  const double again = session.integrator().step;
  EXPECT_DOUBLE_EQ(again, choose_step(device(), s, 2e-3).step);
  EXPECT_LT(again, one.step);
}

TEST(Session, ArraysOfAnotherDeviceAndBadStepsAreRefused) {
  Scene s = small_scene();
  Session session(device(), s);
  Device other(std::to_string(device().info().index));  // the same hardware, another context
  DeviceArray foreign(other, {24, 24, 24}, DType::f32);
  EXPECT_TRUE(has(error_of([&] { session.set_volume(foreign); }), "another device or context"));
  EXPECT_TRUE(has(error_of([&] { session.project(foreign); }), "another device or context"));
  DeviceArray empty;
  EXPECT_TRUE(has(error_of([&] { session.set_target(empty); }), "empty"));
  EXPECT_TRUE(has(error_of([&] { empty.to_floats(); }), "empty"));
  DeviceArray a(device(), {3}, DType::f32);
  const float two[2] = {1, 2};
  EXPECT_TRUE(has(error_of([&] { a.upload(two, 2); }), "2 values for an array of 3"));
  float out[2];
  EXPECT_TRUE(has(error_of([&] { a.download(out, 2); }), "room for 2 values"));

  session.set_target(render(device(), s));
  const DeviceArray g = session.gradient()["density"];
  OptimizerOptions oo;
  oo.lower = 0;
  Optimizer small(device(), 10, oo);
  EXPECT_TRUE(has(error_of([&] { session.step(small, g); }), "10 parameters"));
  oo.lower = -1;
  Optimizer unbounded(device(), g.size(), oo);
  EXPECT_TRUE(has(error_of([&] { session.step(unbounded, g); }), "lower bound must be >= 0"));
  oo.lower = 0;
  Optimizer fine(device(), g.size(), oo);
  DeviceArray flat(device(), {std::int64_t(g.size())}, DType::f32);
  EXPECT_TRUE(has(error_of([&] { session.step(fine, flat); }), "the gradient has shape"));
  Scene no_data = s;
  no_data.volume.data.clear();
  Session geometry(device(), no_data);
  EXPECT_FALSE(geometry.has_volume());
  EXPECT_TRUE(has(error_of([&] { geometry.render(); }), "no densities"));
}

TEST(Session, ProjectorPairIsMatchedOnDeviceArrays) {
  Scene s = constant_scene(0.5f, 13, 11);
  s.volume.ny = 9;  // anisotropic, not cubic
  s.volume.data.assign(s.volume.voxel_count(), 0.5f);
  s.cameras.push_back(s.cameras[0]);
  s.cameras[1].eye = {1.5, 0.4, 1.0};
  s.cameras[1].projection = Projection::perspective;
  for (Precision p : {Precision::f32, Precision::f64}) {
    if (p == Precision::f64 && !device().info().fp64) continue;
    SessionOptions o;
    o.precision = p;
    Session session(device(), s, o);
    const DType d = p == Precision::f64 ? DType::f64 : DType::f32;
    DeviceArray x(device(), session.volume_shape(), d);
    std::vector<std::int64_t> rays = session.image_shape();
    rays[3] = 1;
    DeviceArray y(device(), rays, d);
    std::vector<double> xs(x.size()), ys(y.size());
    for (std::size_t i = 0; i < xs.size(); ++i) xs[i] = std::sin(0.37 * double(i)) + 1.1;
    for (std::size_t i = 0; i < ys.size(); ++i) ys[i] = std::cos(0.21 * double(i));
    x.upload(xs.data(), xs.size());
    y.upload(ys.data(), ys.size());
    const std::vector<double> nx = session.project(x).to_doubles();
    const std::vector<double> nty = session.backproject(y).to_doubles();
    double lhs = 0, rhs = 0;
    for (std::size_t i = 0; i < ys.size(); ++i) lhs += nx[i] * ys[i];
    for (std::size_t i = 0; i < xs.size(); ++i) rhs += xs[i] * nty[i];
    EXPECT_NEAR(lhs, rhs, (p == Precision::f64 ? 1e-12 : 1e-5) * std::abs(lhs)) << name(p);
    const Projector P(device(), s, p);
    const std::vector<double> host = P.project(xs);
    for (std::size_t i = 0; i < host.size(); ++i) ASSERT_EQ(nx[i], host[i]) << name(p) << i;
  }
}

TEST(Session, SessionsOnOneDeviceFromTwoThreadsGiveTheOneThreadResults) {
  Scene a = small_scene(), b = small_scene();
  b.tf.points[2].extinction = 50;
  Image ta = render(device(), a), tb = render(device(), b);
  for (float& p : ta.pixels) p *= 0.9f;
  for (float& p : tb.pixels) p *= 0.8f;
  GradientRequest request;
  request.deterministic = true;  // the same bits whatever the order of the atomic adds
  auto work = [&](Session& s, std::vector<float>& image, std::vector<float>& grad) {
    for (int i = 0; i < 4; ++i) {
      image = s.render().to_floats();
      grad = s.gradient(request)["density"].to_floats();
    }
  };
  Session sa(device(), a), sb(device(), b);
  sa.set_target(ta);
  sb.set_target(tb);
  std::vector<float> ia, ga, ib, gb;
  work(sa, ia, ga);
  work(sb, ib, gb);
  std::vector<float> ia2, ga2, ib2, gb2;
  std::thread t1([&] { work(sa, ia2, ga2); }), t2([&] { work(sb, ib2, gb2); });
  t1.join();
  t2.join();
  EXPECT_EQ(ia2, ia);
  EXPECT_EQ(ga2, ga);
  EXPECT_EQ(ib2, ib);
  EXPECT_EQ(gb2, gb);
  // One session from two threads in turn.
  std::vector<float> i3, g3;
  std::thread t3([&] { work(sa, i3, g3); });
  t3.join();
  std::thread t4([&] { work(sa, i3, g3); });
  t4.join();
  EXPECT_EQ(i3, ia);
  EXPECT_EQ(g3, ga);
}

}  // namespace
}  // namespace ivr::test
