// gradient_share_test.cpp — the one-shot gradient data-parallel over views (GradientOptions::
// workers: what mpirun and several devices run): workers on threads, each with a context of its
// own, every worker ending with the whole gradient; with `deterministic` the density gradient is
// the one process's bit for bit (fixed point: the batch's scale, the passes agreed, the integer
// sums added exactly), without it equal to rounding; a tolerance's step chosen once; bad workers.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <thread>

#include "adjoint/adjoint.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/render.hpp"
#include "multi_device/worker_sum.hpp"
#include "runtime/runtime.hpp"
#include "test_support.hpp"
#include "views_scene.hpp"

namespace ivr::test {
namespace {

Image target_for(const Scene& s, Precision p) {
  RenderOptions ro;
  ro.precision = p;
  Image t = render(device(), s, ro);
  for (std::size_t i = 0; i < t.pixels.size(); ++i) t.pixels[i] = 0.7f * t.pixels[i] + 0.03f * float(i % 5);
  t.pixels_f64.clear();
  return t;
}

// `workers` workers on threads, each with its own context, summing through a WorkerSum; each
// worker's gradient (a worker that threw: its message in `errors`).
struct Runs {
  std::vector<Gradient> gradients;
  std::vector<std::string> errors;
};
Runs on_threads(int workers, const Scene& s, const Image& target,
                const std::vector<std::string>& groups, const GradientOptions& o,
                int failing_worker = -1) {
  const std::vector<std::unique_ptr<Device>> devices = device_contexts(workers);
  WorkerSum sum(workers);
  Runs out;
  out.gradients.resize(std::size_t(workers));
  out.errors.resize(std::size_t(workers));
  std::vector<std::thread> threads;
  for (int w = 0; w < workers; ++w)
    threads.emplace_back([&, w] {
      try {
        GradientOptions ow = o;
        ow.worker = w, ow.workers = workers, ow.sum = sum.of(w);
        const std::vector<std::string> mine =
            w == failing_worker ? std::vector<std::string>{"no_such_group"} : groups;
        out.gradients[std::size_t(w)] = gradient(*devices[std::size_t(w)], s, target, mine, ow);
      } catch (const std::exception& e) {
        out.errors[std::size_t(w)] = e.what();
        sum.abort();
      }
    });
  for (std::thread& t : threads) t.join();
  return out;
}

double largest(const std::vector<double>& v) {
  double m = 1e-30;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

void expect_near_groups(const Gradient& a, const Gradient& b, double tol, const std::string& what) {
  ASSERT_EQ(a.groups.size(), b.groups.size()) << what;
  EXPECT_NEAR(a.loss, b.loss, tol * std::abs(b.loss)) << what;
  for (std::size_t k = 0; k < a.groups.size(); ++k) {
    EXPECT_EQ(a.groups[k].shape, b.groups[k].shape) << what << " " << b.groups[k].name;
    ASSERT_EQ(a.groups[k].values.size(), b.groups[k].values.size()) << what;
    // (listed voxels: relative to the density's largest, as the density's own entries are)
    double scale = largest(b.groups[k].values);
    if (b.groups[k].name == "voxels")
      for (const GroupGradient& d : b.groups)
        if (d.name == "density") scale = largest(d.values);
    for (std::size_t i = 0; i < a.groups[k].values.size(); ++i)
      ASSERT_NEAR(a.groups[k].values[i], b.groups[k].values[i], tol * scale)
          << what << " " << b.groups[k].name << "[" << i << "]";
  }
}

// Fixed point over 2, 3 and 5 workers (5 views: 3 + 2, 2 + 2 + 1, one each) and over several
// devices: the density gradient is the one process's bit for bit in both precisions, the loss
// and the TF, background and camera gradients equal to rounding, every worker's alike.
TEST(GradientShare, DeterministicWorkersEqualOneProcessBitForBit) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "no 64-bit integer atomics";
  const Scene s = views_scene(5);
  const std::vector<std::string> groups = {"density", "tf", "background", "camera"};
  std::vector<Precision> precisions{Precision::f32};
  if (device().info().fp64) precisions.push_back(Precision::f64);
  for (const Precision p : precisions) {
    const Image target = target_for(s, p);
    GradientOptions o;
    o.precision = p;
    o.mode = Mode::adjoint;
    o.deterministic = true;
    const Gradient one = gradient(device(), s, target, groups, o);
    ASSERT_TRUE(one.deterministic);
    const double tol = p == Precision::f64 ? 1e-12 : 2e-5;
    for (int workers : {2, 3, 5}) {
      const Runs r = on_threads(workers, s, target, groups, o);
      for (int w = 0; w < workers; ++w) {
        const std::string what = std::to_string(workers) + " workers, worker " + std::to_string(w);
        ASSERT_EQ(r.errors[std::size_t(w)], "") << what;
        const Gradient& g = r.gradients[std::size_t(w)];
        EXPECT_TRUE(g.deterministic) << what;
        EXPECT_EQ(g.groups[0].values, one.groups[0].values) << what << ": density not bit for bit";
        expect_near_groups(g, one, tol, what);
      }
    }
    // Several devices in one process: the same path, the same bits.
    const std::vector<std::unique_ptr<Device>> devices = device_contexts(3);
    const Gradient many = gradient(pointers_to(devices), s, target, groups, o);
    EXPECT_EQ(many.devices, 3);
    EXPECT_TRUE(many.deterministic);
    EXPECT_EQ(many.groups[0].values, one.groups[0].values) << "3 devices";
    expect_near_groups(many, one, tol, "3 devices");
  }
}

// Out of core (bricks of 3 cells forced for every worker and the one process): with the adjoint's
// groups alone each share sums its rays' segments at the batch's scale into the batch's integers,
// so the density gradient is the one process's out-of-core one bit for bit; asking for a forward
// lane (camera) as well turns fixed point off (the lanes' means are the share's own), to rounding.
TEST(GradientShare, OutOfCoreDeterministicWorkersEqualOneProcessBitForBit) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "no 64-bit integer atomics";
  ScopedEnv bricks("IVR_VOLUME_BRICK", "3");
  const Scene s = views_scene(5);
  std::vector<Precision> precisions{Precision::f32};
  if (device().info().fp64) precisions.push_back(Precision::f64);
  for (const Precision p : precisions) {
    const Image target = target_for(s, p);
    GradientOptions o;
    o.precision = p;
    o.deterministic = true;
    const double tol = p == Precision::f64 ? 1e-12 : 2e-5;
    const std::vector<std::string> adjoint = {"density", "tf", "background"};
    const Gradient one = gradient(device(), s, target, adjoint, o);
    ASSERT_TRUE(one.deterministic);
    ASSERT_GT(one.bricks, 1);
    for (int workers : {2, 3}) {
      const Runs r = on_threads(workers, s, target, adjoint, o);
      for (int w = 0; w < workers; ++w) {
        const std::string what = std::string(name(p)) + ", " + std::to_string(workers) +
                                 " workers, worker " + std::to_string(w);
        ASSERT_EQ(r.errors[std::size_t(w)], "") << what;
        const Gradient& g = r.gradients[std::size_t(w)];
        EXPECT_TRUE(g.deterministic) << what;
        EXPECT_GT(g.bricks, 1) << what;
        EXPECT_EQ(g.groups[0].values, one.groups[0].values) << what << ": density not bit for bit";
        expect_near_groups(g, one, tol, what);
      }
    }
    const std::vector<std::string> with_camera = {"density", "camera"};
    const Gradient one_camera = gradient(device(), s, target, with_camera, o);
    const Runs r = on_threads(2, s, target, with_camera, o);
    for (int w = 0; w < 2; ++w) {
      const std::string what = std::string(name(p)) + ", with camera, worker " + std::to_string(w);
      ASSERT_EQ(r.errors[std::size_t(w)], "") << what;
      EXPECT_FALSE(r.gradients[std::size_t(w)].deterministic) << what;
      // (fixed point against float sums: the fixed-point rounding of the largest entry)
      expect_near_groups(r.gradients[std::size_t(w)], one_camera, std::max(tol, 1e-7), what);
    }
  }
}

// Without fixed point (and with more workers than views, where fixed point is off: a worker
// without a view votes against it), the workers' gradient equals one process's to rounding —
// the mean losses weighted by the shares' sizes, dot summed, camera rows in view order.
TEST(GradientShare, FloatWorkersEqualOneProcessToRounding) {
  const Scene s = views_scene(3);
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const Image target = target_for(s, p);
  const std::vector<std::string> groups = {"density", "tf", "camera", "voxels:3,40-44"};
  for (const Loss loss : {Loss::mse, Loss::dot}) {
    GradientOptions o;
    o.precision = p;
    o.loss = loss;
    const Gradient one = gradient(device(), s, target, groups, o);  // (float sums)
    for (int workers : {2, 4}) {
      GradientOptions ow = o;
      ow.deterministic = workers == 4;  // (asked for, but off for 4 workers on 3 views)
      const Runs r = on_threads(workers, s, target, groups, ow);
      for (int w = 0; w < workers; ++w) {
        const std::string what = std::to_string(workers) + " workers, worker " +
                                 std::to_string(w) + (loss == Loss::dot ? ", dot" : ", mse");
        ASSERT_EQ(r.errors[std::size_t(w)], "") << what;
        EXPECT_FALSE(r.gradients[std::size_t(w)].deterministic) << what;
        expect_near_groups(r.gradients[std::size_t(w)], one, p == Precision::f64 ? 1e-12 : 2e-5,
                           what);
      }
    }
  }
}

// A scene asking for a tolerance: worker 0 chooses the step for the whole scene and every worker
// marches it (a share's own pilots could choose another).
TEST(GradientShare, ToleranceStepChosenOnceForTheWholeScene) {
  Scene s = views_scene(3);
  s.integrator.tolerance = 2e-3;
  const Image target = target_for(views_scene(3), Precision::f32);
  GradientOptions o;
  const Gradient one = gradient(device(), s, target, {"density"}, o);
  const Runs r = on_threads(2, s, target, {"density"}, o);
  for (int w = 0; w < 2; ++w) {
    ASSERT_EQ(r.errors[std::size_t(w)], "");
    EXPECT_EQ(r.gradients[std::size_t(w)].step, one.step) << "worker " << w;
    expect_near_groups(r.gradients[std::size_t(w)], one, 2e-5, "tolerance");
  }
}

// Bad workers are refused by name; a worker that fails stops the others' sums instead of leaving
// them waiting.
TEST(GradientShare, BadWorkersAndAFailingWorker) {
  const Scene s = views_scene(2);
  const Image target = target_for(s, Precision::f32);
  GradientOptions o;
  o.workers = 2, o.worker = 2;
  o.sum = [](std::vector<double>&) {};
  try {
    gradient(device(), s, target, {"density"}, o);
    ADD_FAILURE() << "worker 2 of 2 accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument);
    EXPECT_TRUE(has(e.what(), "worker 2 of 2")) << e.what();
  }
  o.worker = 0, o.sum = {};
  try {
    gradient(device(), s, target, {"density"}, o);
    ADD_FAILURE() << "no sum accepted";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "no sum")) << e.what();
  }
  const Runs r = on_threads(2, s, target, {"density"}, GradientOptions{}, 1);
  EXPECT_TRUE(has(r.errors[1], "no_such_group")) << r.errors[1];
  EXPECT_TRUE(has(r.errors[0], "another worker failed")) << r.errors[0];
}

}  // namespace
}  // namespace ivr::test
