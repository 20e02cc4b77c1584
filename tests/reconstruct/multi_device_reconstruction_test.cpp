// multi_device_reconstruction_test.cpp — a reconstruction over several devices of one process
// (MultiDeviceReconstruction; here separate contexts on the test device), over their slabs or
// their shares of the views: it follows one process (the losses, priors and the whole volume),
// coarse to fine included; its per-device checkpoints resume bit for bit; bad options are refused
// before any work.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "reconstruct/reconstruct_support.hpp"

namespace ivr {
namespace {

using test::device;
using test::Small;

ReconstructOptions options(Precision precision) {
  ReconstructOptions o;
  o.iterations = 4;
  o.batch = 4;
  o.levels = 2;  // (8³ then 16³: the coarse grid gathered between)
  o.init = Init::constant;
  o.precision = precision;
  o.deterministic = false;  // (float sums in both: fixed point out of core is not in core's bits)
  o.slabs = true;
  o.tv = 0.05;
  // SGD keeps the gradients' agreement in the iterates (ReconstructDomain's slab_options).
  o.automatic_optimizer = false;
  o.optimizer.kind = OptimizerKind::sgd;
  o.optimizer.lr = 1;
  return o;
}

// 2 and 3 devices against one process, float64: every iteration's loss and prior within 1e-12,
// the whole volume within 1e-12 of the largest density.
TEST(MultiDeviceReconstruction, FollowsOneProcess) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  const Small p;
  const ReconstructOptions o = options(Precision::f64);
  Reconstruction one(device(), p.scene, p.targets, o);
  while (!one.done()) one.step();
  const Scene want = one.result();
  // (and 2 devices weighted 1:3: each level's slabs in proportion, domain_slab)
  for (const auto& [count, shares] : std::vector<std::pair<int, std::vector<double>>>{
           {2, {}}, {3, {}}, {2, {1, 3}}}) {
    const std::string what =
        std::to_string(count) + " devices" + (shares.empty() ? "" : ", weighted 1:3");
    const auto devices = test::device_contexts(count);
    ReconstructOptions weighted = o;
    weighted.shares = shares;
    MultiDeviceReconstruction many(test::pointers_to(devices), p.scene, p.targets, weighted);
    EXPECT_EQ(many.devices(), count);
    while (!many.done()) many.step();
    ASSERT_EQ(many.history().size(), one.history().size()) << what;
    for (std::size_t k = 0; k < one.history().size(); ++k) {
      const IterationRecord& a = one.history()[k];
      const IterationRecord& b = many.history()[k];
      EXPECT_NEAR(b.loss, a.loss, 1e-12 * a.loss) << what << ", iteration " << k + 1;
      EXPECT_NEAR(b.prior, a.prior, 1e-12 * a.prior + 1e-300) << what << ", iteration " << k + 1;
      EXPECT_EQ(b.level, a.level) << what;
    }
    const Scene got = many.result();
    ASSERT_EQ(got.volume.nz, want.volume.nz) << what;
    ASSERT_EQ(got.volume.data.size(), want.volume.data.size()) << what;
    double worst = 0, scale = 0;
    for (std::size_t i = 0; i < want.volume.data.size(); ++i) {
      worst = std::max(worst, std::abs(double(got.volume.data[i]) - want.volume.data[i]));
      scale = std::max(scale, std::abs(double(want.volume.data[i])));
    }
    EXPECT_LE(worst, 1e-6 * scale) << what;  // (the volumes are float32: their rounding)
  }
}

// Stopped after 2 iterations, each device's checkpoint saved, resumed by a new object: the end is
// the uninterrupted run's bit for bit (fixed point where the device has 64-bit integer atomics).
TEST(MultiDeviceReconstruction, ResumesFromItsDevicesCheckpoints) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "fixed point needs 64-bit atomics";
  const Small p;
  ReconstructOptions o = options(Precision::f32);
  o.levels = 1;
  o.deterministic = true;
  const auto devices = test::device_contexts(2);
  MultiDeviceReconstruction whole(test::pointers_to(devices), p.scene, p.targets, o);
  while (!whole.done()) EXPECT_TRUE(whole.step().deterministic);
  const std::string prefix = test::temp_dir("multi_device_reconstruction") + "/run";
  {
    MultiDeviceReconstruction first(test::pointers_to(devices), p.scene, p.targets, o);
    first.step();
    first.step();
    first.save_checkpoint(prefix);
  }
  MultiDeviceReconstruction resumed(test::pointers_to(devices), p.scene, p.targets, o);
  resumed.resume(prefix);
  EXPECT_EQ(resumed.iteration(), 2);
  while (!resumed.done()) resumed.step();
  EXPECT_EQ(resumed.result().volume.data, whole.result().volume.data);
  // A missing device checkpoint: refused, and the object then refuses to go on.
  MultiDeviceReconstruction missing(test::pointers_to(devices), p.scene, p.targets, o);
  EXPECT_THROW(missing.resume(prefix + "_none"), Error);
  try {
    missing.step();
    ADD_FAILURE() << "a step after a device failed";
  } catch (const Error& e) {
    EXPECT_TRUE(test::has(e.what(), "a device failed before")) << e.what();
  }
}

// Over views (options.slabs false): every device the whole volume and a share of each batch's
// views, the gradients summed in fixed point — the run is one device's bit for bit.
TEST(MultiDeviceReconstruction, ViewsFollowOneDeviceBitForBit) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "fixed point needs 64-bit atomics";
  const Small p;
  ReconstructOptions o = options(Precision::f32);
  o.slabs = false;
  o.deterministic = true;
  Reconstruction one(device(), p.scene, p.targets, o);
  while (!one.done()) one.step();
  const auto contexts = test::device_contexts(3);
  // Equal shares (equal speeds), 3 : 1 and 1 : 3 of each batch of 4, a device whose share would
  // be empty, which takes no part, and 0.05 : 0.5 : 0.05 over 3 devices — 1, 3 and 0 views, which
  // by the two running devices' weights alone would be 0 and 4.
  struct Case {
    std::vector<double> shares;
    int taking;
  };
  for (const Case& c : {Case{{}, 2}, Case{{3.0, 1.0}, 2}, Case{{1.0, 3.0}, 2}, Case{{1.0, 1e6}, 1},
                        Case{{0.05, 0.5, 0.05}, 2}}) {
    std::string what = "shares";
    for (double w : c.shares) what += " " + std::to_string(w);
    ReconstructOptions weighted = o;
    weighted.shares = c.shares;
    std::vector<Device*> devices = test::pointers_to(contexts);
    devices.resize(std::max<std::size_t>(c.shares.size(), 2));
    MultiDeviceReconstruction many(devices, p.scene, p.targets, weighted);
    EXPECT_EQ(many.devices(), c.taking) << what;
    while (!many.done()) EXPECT_TRUE(many.step().deterministic) << what;
    ASSERT_EQ(many.history().size(), one.history().size()) << what;
    for (std::size_t k = 0; k < one.history().size(); ++k)
      EXPECT_NEAR(many.history()[k].loss, one.history()[k].loss, 1e-6 * one.history()[k].loss)
          << what << ", iteration " << k + 1;
    EXPECT_EQ(many.result().volume.data, one.result().volume.data) << what;
  }
  // A worker's weighted share of a batch that would be empty is refused.
  ReconstructOptions worker = o;
  worker.workers = 2;
  worker.sum = [](std::vector<double>&) {};
  worker.shares = {1.0, 1e6};
  try {
    Reconstruction r(device(), p.scene, p.targets, worker);
    ADD_FAILURE() << "an empty share";
  } catch (const Error& e) {
    EXPECT_TRUE(test::has(e.what(), "worker 0's share of a batch of 4 views is empty")) << e.what();
  }
}

TEST(MultiDeviceReconstruction, BadOptionsAreRefusedBeforeAnyWork) {
  const Small p;  // 16 planes: 15 cells
  ReconstructOptions o = options(Precision::f32);
  o.levels = 1;
  auto expect_refused = [&](const std::vector<Device*>& devices, const ReconstructOptions& opt,
                            const std::string& part) {
    try {
      MultiDeviceReconstruction r(devices, p.scene, p.targets, opt);
      ADD_FAILURE() << "no error; expected one naming '" << part << "'";
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument) << e.what();
      EXPECT_TRUE(test::has(e.what(), part)) << e.what();
    }
  };
  expect_refused({}, o, "none given");
  expect_refused(test::pointers_to(test::device_contexts(16)), o, "16 workers for a volume of 16 planes");
  ReconstructOptions worker = o;
  worker.workers = 2;
  expect_refused({&device()}, worker, "leave them unset");
}

}  // namespace
}  // namespace ivr
