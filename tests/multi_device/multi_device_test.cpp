// multi_device_test.cpp — several devices in one process (lib/multi_device/): the views or rays
// split over devices (here: separate contexts on the test device) give the one-device render
// exactly, the one-device gradients and tomography iterates to rounding, in every group; the
// command line too.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>
#include <random>

#include "brick/brick_support.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/render.hpp"
#include "ivr/tomo.hpp"
#include "test_support.hpp"
#include "views_scene.hpp"

namespace ivr::test {
namespace {

TEST(MultiDevice, RenderAndGradientsEqualOneDevice) {
  const Scene s = views_scene(5);
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  RenderOptions ro;
  ro.precision = p;
  const Image one = render(device(), s, ro);
  const Image target = dimmed(one);
  GradientOptions go;
  go.precision = p;
  go.mode = Mode::adjoint;
  const std::vector<std::string> groups = {"density", "tf", "background", "camera"};
  const Gradient g1 = gradient(device(), s, target, groups, go);
  for (int count : {2, 3, 7}) {  // 7 devices for 5 views: two get none
    const auto devices = device_contexts(count);
    RenderStats st;
    const Image many = render(pointers_to(devices), s, ro, &st);
    EXPECT_EQ(st.devices, std::min(count, 5));
    ASSERT_EQ(many.views, one.views);
    EXPECT_EQ(many.pixels, one.pixels) << count << " devices";
    EXPECT_EQ(many.pixels_f64, one.pixels_f64) << count << " devices";
    const Gradient gm = gradient(pointers_to(devices), s, target, groups, go);
    EXPECT_EQ(gm.devices, std::min(count, 5));
    const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
    EXPECT_NEAR(gm.loss, g1.loss, tol * std::abs(g1.loss)) << count;
    ASSERT_EQ(gm.groups.size(), g1.groups.size());
    for (std::size_t k = 0; k < groups.size(); ++k) {
      const std::vector<double>& a = g1.groups[k].values;
      const std::vector<double>& b = gm.groups[k].values;
      ASSERT_EQ(a.size(), b.size()) << groups[k];
      EXPECT_EQ(gm.groups[k].shape, g1.groups[k].shape) << groups[k];
      double scale = 1e-30;
      for (double v : a) scale = std::max(scale, std::abs(v));
      for (std::size_t i = 0; i < a.size(); ++i)
        ASSERT_NEAR(a[i], b[i], tol * scale) << groups[k] << "[" << i << "], " << count << " devices";
    }
  }
  EXPECT_THROW(render(std::vector<Device*>{}, s), Error);
  EXPECT_THROW(render(std::vector<Device*>{nullptr, &device()}, s), Error);
}

TEST(MultiDevice, CommandLine) {
  const std::string dir = temp_dir("multi_device_cli");
  const std::string scene = write_file(dir + "/scene.json", R"({
    "volume": {"synthetic": "sphere", "dims": [16, 16, 16]}, "model": "emission_absorption",
    "tf": {"type": "piecewise_linear", "points": [
      {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0},
      {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
    "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 12, "height": 10},
                {"eye": [-1.4, 0.3, -1.0], "width": 12, "height": 10},
                {"eye": [0.2, -1.6, 1.0], "width": 12, "height": 10}],
    "integrator": {"scheme": "midpoint", "step": 0.5}})");
  const std::string d = std::to_string(device().info().index);
  CliResult r = run_cli("render '" + scene + "' -o '" + dir + "/a.npy' --device " + d);
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_cli("render '" + scene + "' -o '" + dir + "/b.npy' --json --device " + d + "," + d);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["devices"], 2) << r.out;
  EXPECT_EQ(file_text(dir + "/a.npy"), file_text(dir + "/b.npy"));
  r = run_cli("gradient '" + scene + "' --target '" + dir + "/a.npy' --wrt density -o '" + dir +
              "/g' --json --device " + d + "," + d + "," + d);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["devices"], 3) << r.out;
  r = run_cli("render '" + scene + "' -o '" + dir + "/c.npy' --device " + d + ",");
  EXPECT_NE(r.status, 0);
  EXPECT_TRUE(has(r.err, "empty selector")) << r.err;
}

// Tomography over the devices' views (each device a worker of tomo_shared): the iterate and the
// residuals are one device's to rounding; a progress stopping after iteration 3 is asked on one
// device and stops them all.
TEST(MultiDevice, TomoOverViewsEqualsOneDevice) {
  Scene s = views_scene(5);
  s.model = Model::absorption;
  s.tf = TransferFunction{};  // (identity)
  TomoOptions o;
  o.precision = device().info().fp64 ? Precision::f64 : Precision::f32;
  o.iterations = 5;
  o.nonneg = true;
  const double tol = o.precision == Precision::f64 ? 1e-10 : 1e-4;
  const Projector N(device(), s, o.precision);
  std::vector<double> truth(N.voxel_count());
  for (std::size_t i = 0; i < truth.size(); ++i) truth[i] = 0.5 + 0.4 * std::sin(0.7 * double(i));
  std::vector<double> lines = N.project(truth);
  for (std::size_t i = 0; i < lines.size(); ++i) lines[i] *= 1.0 + 0.05 * std::cos(double(i));
  const TomoResult one = tomo(device(), s, lines, o);
  const auto values = [](const TomoResult& r) {
    return r.volume_f64.empty() ? std::vector<double>(r.volume.begin(), r.volume.end())
                                : r.volume_f64;
  };
  double scale = 0;
  for (double v : values(one)) scale = std::max(scale, std::abs(v));
  ASSERT_GT(scale, 0.0);
  for (int count : {2, 3}) {
    const auto devices = device_contexts(count);
    const TomoResult many = tomo(pointers_to(devices), s, lines, o);
    const std::vector<double> a = values(one), b = values(many);
    ASSERT_EQ(a.size(), b.size()) << count;
    for (std::size_t i = 0; i < a.size(); ++i)
      ASSERT_NEAR(b[i], a[i], tol * scale) << count << " devices, voxel " << i;
    ASSERT_EQ(many.history.size(), one.history.size()) << count;
    for (std::size_t k = 0; k < one.history.size(); ++k)
      EXPECT_NEAR(many.history[k].residual, one.history[k].residual, tol) << count;
  }
  int calls = 0;
  const auto devices = device_contexts(2);
  const TomoResult stopped = tomo(pointers_to(devices), s, lines, o, [&](const TomoIteration& it) {
    ++calls;
    return it.iteration < 3;
  });
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(stopped.history.size(), 3u);
  EXPECT_EQ(stopped.stop_reason, "interrupted");
}

}  // namespace
}  // namespace ivr::test
