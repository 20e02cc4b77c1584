// device_shares_test.cpp — several devices' shares of the views sized by weight (view_shares with
// weights, share_weights, the options' `shares`): the split's closed forms and errors, the speeds
// the default weights come from, and unequal shares giving the one-device render, gradients and
// tomography (here: separate contexts on the test device), the command line's --shares too.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include "adjoint/adjoint.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/planner.hpp"
#include "ivr/render.hpp"
#include "ivr/tomo.hpp"
#include "ivr/volume_io.hpp"
#include "brick/brick_support.hpp"
#include "test_support.hpp"
#include "views_scene.hpp"

namespace ivr::test {
namespace {

using Shares = std::vector<std::pair<std::size_t, std::size_t>>;

std::vector<std::size_t> counts(const Shares& shares) {
  std::vector<std::size_t> out;
  std::size_t next = 0;
  for (const auto& [first, count] : shares) {
    EXPECT_EQ(first, next) << "shares are contiguous and in order";
    next = first + count;
    out.push_back(count);
  }
  return out;
}

void expect_refused(const std::vector<double>& weights, const std::string& part) {
  try {
    view_shares(10, weights);
    ADD_FAILURE() << "no error; expected one naming '" << part << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument);
    EXPECT_TRUE(has(e.what(), part)) << e.what();
  }
}

// Closed forms of the largest-remainder split, equal weights giving the equal split's counts, and
// every share within one view of its quota n·wᵢ/Σw.
TEST(DeviceShares, WeightedSharesFollowTheWeights) {
  using V = std::vector<std::size_t>;
  EXPECT_EQ(counts(view_shares(8, {3.0, 1.0})), (V{6, 2}));
  EXPECT_EQ(counts(view_shares(7, {1.0, 2.0, 4.0})), (V{1, 2, 4}));
  EXPECT_EQ(counts(view_shares(3, {2.0, 1.0})), (V{2, 1}));
  // 2.5 + 2.5 + 5: one view left over, the two halves tie, the lower index takes it.
  EXPECT_EQ(counts(view_shares(10, {2.5, 2.5, 5.0})), (V{3, 2, 5}));
  // A device much slower than the other: its share is empty, and kept in its place.
  EXPECT_EQ(counts(view_shares(5, {1.0, 1000.0})), (V{0, 5}));
  EXPECT_EQ(counts(view_shares(5, {1000.0, 1.0, 1000.0})), (V{3, 0, 2}));
  EXPECT_EQ(counts(view_shares(0, {1.0, 2.0})), (V{0, 0}));
  for (std::size_t n : {0, 1, 3, 10, 11, 97})
    for (std::size_t parts : {1, 2, 3, 4, 7}) {
      std::vector<std::size_t> equal(parts, 0);
      const Shares plain = view_shares(n, parts);  // (empty shares dropped)
      for (std::size_t d = 0; d < plain.size(); ++d) equal[d] = plain[d].second;
      EXPECT_EQ(counts(view_shares(n, std::vector<double>(parts, 0.37))), equal)
          << n << " views, " << parts << " equal weights";
    }
  std::mt19937 rng(24);
  std::uniform_real_distribution<double> u(0.01, 50.0);
  for (int trial = 0; trial < 200; ++trial) {
    const std::size_t n = rng() % 200;
    std::vector<double> w(1 + rng() % 6);
    double total = 0;
    for (double& x : w) total += (x = u(rng));
    const std::vector<std::size_t> c = counts(view_shares(n, w));
    std::size_t sum = 0;
    for (std::size_t d = 0; d < w.size(); ++d) {
      const double quota = double(n) * w[d] / total;
      EXPECT_LT(std::abs(double(c[d]) - quota), 1.0) << "trial " << trial << ", share " << d;
      sum += c[d];
    }
    EXPECT_EQ(sum, n) << "trial " << trial;
  }
  expect_refused({}, "no weights");
  expect_refused({1.0, 0.0}, "shares[1]");
  expect_refused({-2.0, 1.0}, "shares[0]");
  expect_refused({1.0, std::numeric_limits<double>::quiet_NaN()}, "shares[1]");
  expect_refused({1.0, std::numeric_limits<double>::infinity()}, "shares[1]");
  expect_refused({1e308, 1e308}, "overflows");
}

// Shares that must each hold a view (MPI ranks): the weighted split where no share is empty; else
// one view each and the rest by the weights; fewer views than shares: one each to the first.
TEST(DeviceShares, SharesEachHoldAViewWhereThereAreEnough) {
  using V = std::vector<std::size_t>;
  EXPECT_EQ(counts(view_shares_each(8, {3.0, 1.0})), (V{6, 2}));  // (none empty: as weighted)
  EXPECT_EQ(counts(view_shares_each(4, {1.0, 9.0})), (V{1, 3}));  // (weighted: 0, 4)
  EXPECT_EQ(counts(view_shares_each(8, {1.0, 24.0})), (V{1, 7}));
  EXPECT_EQ(counts(view_shares_each(5, {1000.0, 1.0, 1000.0})), (V{2, 1, 2}));
  EXPECT_EQ(counts(view_shares_each(3, {1.0, 1e6, 1.0})), (V{1, 1, 1}));
  EXPECT_EQ(counts(view_shares_each(2, {1.0, 5.0, 9.0})), (V{1, 1, 0}));  // (n < parts)
  EXPECT_EQ(counts(view_shares_each(0, {1.0, 2.0})), (V{0, 0}));
  std::mt19937 rng(25);
  std::uniform_real_distribution<double> u(0.001, 50.0);
  for (int trial = 0; trial < 200; ++trial) {
    const std::size_t n = rng() % 40;
    std::vector<double> w(1 + rng() % 6);
    for (double& x : w) x = u(rng);
    const std::vector<std::size_t> c = counts(view_shares_each(n, w));
    const std::vector<std::size_t> weighted = counts(view_shares(n, w));
    std::size_t sum = 0;
    for (std::size_t d = 0; d < w.size(); ++d) {
      sum += c[d];
      if (n >= w.size()) EXPECT_GE(c[d], 1u) << "trial " << trial << ", share " << d;
    }
    EXPECT_EQ(sum, n) << "trial " << trial;
    if (std::find(weighted.begin(), weighted.end(), 0u) == weighted.end())
      EXPECT_EQ(c, weighted) << "trial " << trial;
  }
  EXPECT_THROW(view_shares_each(4, {1.0, 0.0}), Error);
}

// The default weights: each device's samples per second from its cost model — a calibration
// file where there is one, else the estimate from its size (a GPU by its lanes and clock, a CPU
// by its threads).
TEST(DeviceShares, WeightsAreTheDevicesSpeeds) {
  const auto two = device_contexts(2);
  const std::vector<double> w = share_weights(pointers_to(two));
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0], w[1]);
  EXPECT_DOUBLE_EQ(w[0], 1.0 / load_cost_model(device().info()).seconds_per_sample);
  EXPECT_EQ(share_weights(pointers_to(two), {3.0, 1.0}), (std::vector<double>{3.0, 1.0}));
  EXPECT_THROW(share_weights(pointers_to(two), {1.0}), Error);
  EXPECT_THROW(share_weights(pointers_to(two), {1.0, -1.0}), Error);
  EXPECT_THROW(share_weights({}), Error);

  DeviceInfo h200;  // (as the H200's driver describes it; measured: 2.85e-11 s per sample)
  h200.type = "gpu", h200.vendor = "NVIDIA Corporation";
  h200.compute_units = 132, h200.max_clock_mhz = 1980, h200.nv_compute_capability = 90;
  EXPECT_NEAR(default_cost_model(h200).seconds_per_sample, 2.85e-11, 0.05 * 2.85e-11);
  DeviceInfo a100 = h200;  // sm_80: 64 lanes an SM
  a100.compute_units = 108, a100.max_clock_mhz = 1410, a100.nv_compute_capability = 80;
  EXPECT_NEAR(default_cost_model(a100).seconds_per_sample, 950.0 / (108.0 * 64 * 1410e6), 1e-15);
  DeviceInfo cpu;
  cpu.type = "cpu", cpu.compute_units = 2;
  EXPECT_DOUBLE_EQ(default_cost_model(cpu).seconds_per_sample, 3.2e-9);
  cpu.compute_units = 16;
  EXPECT_DOUBLE_EQ(default_cost_model(cpu).seconds_per_sample, 4.0e-10);
  // The GPU takes 11 of 12 views beside the 16-thread CPU (14 times faster by the estimates).
  EXPECT_EQ(counts(view_shares(12, {1 / default_cost_model(h200).seconds_per_sample,
                                    1 / default_cost_model(cpu).seconds_per_sample})),
            (std::vector<std::size_t>{11, 1}));
  DeviceInfo unknown;  // a driver that gives no clock: CostModel's default
  unknown.type = "gpu", unknown.compute_units = 8;
  EXPECT_EQ(default_cost_model(unknown).seconds_per_sample, CostModel{}.seconds_per_sample);

  // A calibration file is what the weight follows.
  const std::string dir = temp_dir("device_shares");
  const std::string file = write_file(dir + "/cost.json", R"({"forward_base": 1.5,
      "forward_per_lane": 0.16, "adjoint": 3, "seconds_per_sample": 2.5e-9})");
  const ScopedEnv env("IVR_COST_MODEL", file);
  EXPECT_DOUBLE_EQ(samples_per_second(device().info()), 4e8);
  EXPECT_EQ(share_weights(pointers_to(two)), (std::vector<double>{4e8, 4e8}));
}

// Unequal shares over 2 and 3 contexts: the render is the one device's exactly; the gradients
// (density, TF, background, camera) within rounding, the density in fixed point bit for bit; a
// device whose share is empty does not run; tomography's iterate within rounding.
TEST(DeviceShares, UnequalSharesEqualOneDevice) {
  const Scene s = views_scene(6);
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
  RenderOptions ro;
  ro.precision = p;
  const Image one = render(device(), s, ro);
  const Image target = dimmed(one);
  GradientOptions go;
  go.precision = p;
  go.mode = Mode::adjoint;
  const std::vector<std::string> groups = {"density", "tf", "background", "camera"};
  const Gradient g1 = gradient(device(), s, target, groups, go);
  GradientOptions fixed = go;
  fixed.deterministic = true;
  const bool int64 = has_int64_atomics(device().impl());
  const Gradient f1 = gradient(device(), s, target, {"density"}, fixed);
  struct Case {
    std::vector<double> shares;
    int running;  // devices with views
  };
  for (const Case& c : {Case{{3.0, 1.0}, 2}, Case{{1.0, 4.0}, 2}, Case{{1.0, 5.0, 2.0}, 3},
                        Case{{1.0, 1000.0}, 1}, Case{{1000.0, 1.0, 1000.0}, 2},
                        // 1, 0, 5 views: by the running devices' weights alone (0.05 : 0.7) the
                        // first would get none; they take their counts.
                        Case{{0.05, 0.05, 0.7}, 2}}) {
    std::string what = "shares";
    for (double w : c.shares) what += " " + std::to_string(w);
    const auto devices = device_contexts(int(c.shares.size()));
    RenderOptions r = ro;
    r.shares = c.shares;
    RenderStats st;
    const Image many = render(pointers_to(devices), s, r, &st);
    EXPECT_EQ(st.devices, c.running) << what;
    EXPECT_EQ(many.pixels, one.pixels) << what;
    EXPECT_EQ(many.pixels_f64, one.pixels_f64) << what;
    GradientOptions o = go;
    o.shares = c.shares;
    const Gradient gm = gradient(pointers_to(devices), s, target, groups, o);
    EXPECT_EQ(gm.devices, c.running) << what;
    EXPECT_NEAR(gm.loss, g1.loss, tol * std::abs(g1.loss)) << what;
    ASSERT_EQ(gm.groups.size(), g1.groups.size()) << what;
    for (std::size_t k = 0; k < groups.size(); ++k) {
      const std::vector<double>& a = g1.groups[k].values;
      const std::vector<double>& b = gm.groups[k].values;
      ASSERT_EQ(a.size(), b.size()) << groups[k] << ", " << what;
      const double scale = largest(a);
      for (std::size_t i = 0; i < a.size(); ++i)
        ASSERT_NEAR(b[i], a[i], tol * scale) << groups[k] << "[" << i << "], " << what;
    }
    if (int64) {
      GradientOptions fo = fixed;
      fo.shares = c.shares;
      const Gradient fm = gradient(pointers_to(devices), s, target, {"density"}, fo);
      EXPECT_TRUE(fm.deterministic) << what;
      EXPECT_EQ(fm.groups[0].values, f1.groups[0].values) << what;
    }
  }
  const auto two = device_contexts(2);
  RenderOptions bad = ro;
  bad.shares = {1.0, 2.0, 3.0};
  try {
    render(pointers_to(two), s, bad);
    ADD_FAILURE() << "3 weights for 2 devices";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "3 weights for 2 devices")) << e.what();
  }

  Scene t = s;
  t.model = Model::absorption;
  t.tf = TransferFunction{};  // (identity)
  TomoOptions to;
  to.precision = p;
  to.iterations = 4;
  const Projector N(device(), t, p);
  std::vector<double> x(N.voxel_count());
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 0.5 + 0.4 * std::sin(0.7 * double(i));
  const std::vector<double> lines = N.project(x);
  const TomoResult a = tomo(device(), t, lines, to);
  to.shares = {1.0, 5.0};
  const TomoResult b = tomo(pointers_to(two), t, lines, to);
  const std::vector<double> va = a.volume_f64.empty()
                                     ? std::vector<double>(a.volume.begin(), a.volume.end())
                                     : a.volume_f64;
  const std::vector<double> vb = b.volume_f64.empty()
                                     ? std::vector<double>(b.volume.begin(), b.volume.end())
                                     : b.volume_f64;
  ASSERT_EQ(va.size(), vb.size());
  const double tomo_tol = (p == Precision::f64 ? 1e-10 : 1e-4) * largest(va);
  for (std::size_t i = 0; i < va.size(); ++i) ASSERT_NEAR(vb[i], va[i], tomo_tol) << "voxel " << i;
}

// A data-parallel worker differentiates the share its weights give it: worker 0 of 2 with weights
// 1 : 5 over 6 views, its sum over the workers left as its own part (the other's zeros), holds
// 1/6 of the loss of view 0 alone — with equal shares it would be half of views 0–2's.
TEST(DeviceShares, AWorkerTakesItsWeightedShare) {
  const Scene s = views_scene(6);
  RenderOptions ro;
  const Image one = render(device(), s, ro);
  Image target = one;
  for (float& v : target.pixels) v = 0.7f * v + 0.1f;
  GradientOptions o;
  o.mode = Mode::adjoint;
  const Gradient first = gradient(device(), scene_share(s, 0, 1),
                                  target_share(s, target, 0, 1), {"tf"}, o);
  ASSERT_GT(first.loss, 0.0);
  GradientOptions worker = o;
  worker.worker = 0, worker.workers = 2;
  worker.sum = [](std::vector<double>&) {};  // (the other worker's parts: zeros)
  worker.shares = {1.0, 5.0};
  const Gradient mine = gradient(device(), s, target, {"tf"}, worker);
  EXPECT_NEAR(mine.loss, first.loss / 6, 1e-6 * first.loss);
  worker.shares = {1.0, 5.0, 1.0};
  try {
    gradient(device(), s, target, {"tf"}, worker);
    ADD_FAILURE() << "3 weights for 2 workers";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "3 weights for 2 workers")) << e.what();
  }
}

// The command line: --shares sizes the devices' shares (--json "shares": each device's views;
// with --split slabs "slabs": each device's planes), the image is the one device's, and a bad
// --shares is one line before any work.
TEST(DeviceShares, CommandLine) {
  const std::string dir = temp_dir("device_shares_cli");
  const std::string scene = write_file(dir + "/scene.json", R"({
    "volume": {"synthetic": "sphere", "dims": [12, 12, 12]}, "model": "emission_absorption",
    "tf": {"type": "piecewise_linear", "points": [
      {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0},
      {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
    "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 10, "height": 8},
                {"eye": [-1.4, 0.3, -1.0], "width": 10, "height": 8},
                {"eye": [0.2, -1.6, 1.0], "width": 10, "height": 8},
                {"eye": [1.6, -0.2, 0.4], "width": 10, "height": 8}],
    "integrator": {"scheme": "midpoint", "step": 0.5}})");
  const std::string d = std::to_string(device().info().index);
  const std::string two = " --device " + d + "," + d;
  CliResult r = run_cli("render '" + scene + "' -o '" + dir + "/a.npy' --device " + d);
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_cli("render '" + scene + "' -o '" + dir + "/b.npy' --json --shares 3,1" + two);
  ASSERT_EQ(r.status, 0) << r.err;
  nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["shares"], (std::vector<int>{3, 1})) << r.out;
  EXPECT_EQ(j["devices"], 2) << r.out;
  EXPECT_EQ(file_text(dir + "/a.npy"), file_text(dir + "/b.npy"));
  r = run_cli("render '" + scene + "' -o '" + dir + "/c.npy' --json" + two);  // (equal speeds)
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["shares"], (std::vector<int>{2, 2})) << r.out;
  r = run_cli("gradient '" + scene + "' --target '" + dir + "/a.npy' --wrt density -o '" + dir +
              "/g' --json --shares 1,3" + two);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["shares"], (std::vector<int>{1, 3})) << r.out;
  // Over slabs: 11 cells weighted 1:3 (quotas 2.75 and 8.25), planes 0..3 and 3..11.
  r = run_cli("render '" + scene + "' -o '" + dir + "/s.npy' --json --split slabs --shares 1,3" +
              two);
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["slabs"], (std::vector<std::vector<int>>{{0, 3}, {3, 11}})) << r.out;
  EXPECT_EQ(j["devices"], 2) << r.out;
  expect_close_values(load_npy(dir + "/a.npy").data, load_npy(dir + "/s.npy").data, 1e-5,
                      "slabs 1:3");
  struct Bad {
    std::string args, says;
  };
  for (const Bad& b : {Bad{"--shares 1,2,3" + two, "3 weights for 2 devices"},
                       Bad{"--shares 1,0" + two, "shares[1]"},
                       Bad{"--shares 1,x" + two, "--shares"},
                       Bad{"--split slabs --shares 1,2,3" + two, "3 weights for 2 devices"}}) {
    r = run_cli("render '" + scene + "' -o '" + dir + "/bad.npy' " + b.args);
    EXPECT_NE(r.status, 0) << b.args;
    EXPECT_TRUE(has(r.err, b.says)) << b.args << ": " << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/bad.npy")) << b.args;
  }
}

}  // namespace
}  // namespace ivr::test
