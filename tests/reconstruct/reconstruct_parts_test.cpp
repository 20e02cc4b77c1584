// reconstruct_parts_test.cpp — the pieces of a reconstruction: the density priors against finite
// differences and closed forms, L-BFGS on bounded problems with known minima, volume resampling,
// view batches, joint density + TF, checkpoints (bit-for-bit where the gradient is
// deterministic), and the option errors.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>
#include <filesystem>
#include <random>

#include "ivr/adjoint.hpp"
#include "multi_device/worker_sum.hpp"
#include "reconstruct/lbfgs.hpp"
#include "reconstruct/priors.hpp"
#include "runtime/real_args.hpp"
#include "reconstruct/reconstruct_params.hpp"
#include "reconstruct/reconstruct_support.hpp"

namespace ivr {
namespace {

using test::device;
using test::run_workers;
using test::Small;
using test::WorkerRuns;

// R(x) and ∇R(x) of the device prior on a host vector, in float64.
double prior_at(DensityPrior& prior, int nx, int ny, int nz, double tv, double smooth,
                const std::vector<double>& x, std::vector<double>* grad) {
  Device::Impl& dev = device().impl();
  const cl::Buffer xb = upload_reals(dev, true, x, "x");
  const cl::Buffer gb = upload_reals(dev, true, std::vector<double>(x.size(), 0.0), "g");
  const double value = prior.add_gradient(nx, ny, nz, tv, smooth, 0.05, xb, gb);
  if (grad) *grad = download_reals(dev, true, gb, x.size());
  return value;
}

TEST(ReconstructPartsTest, DensityPriorGradientMatchesCentralDifferences) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  DensityPrior prior(device().impl(), true);
  const int nx = 5, ny = 4, nz = 3;
  std::mt19937_64 rng(7);
  std::vector<double> x(std::size_t(nx * ny * nz));
  for (double& v : x) v = double(rng() >> 11) * 0x1.0p-53;
  std::vector<double> g;
  prior_at(prior, nx, ny, nz, 0.7, 0.3, x, &g);
  for (std::size_t i = 0; i < x.size(); ++i) {
    std::vector<double> a = x, b = x;
    a[i] += 1e-6;
    b[i] -= 1e-6;
    const double fd = (prior_at(prior, nx, ny, nz, 0.7, 0.3, a, nullptr) -
                       prior_at(prior, nx, ny, nz, 0.7, 0.3, b, nullptr)) /
                      2e-6;
    EXPECT_NEAR(g[i], fd, 1e-8 + 1e-6 * std::abs(fd)) << "voxel " << i;
  }
}

TEST(ReconstructPartsTest, DensityPriorClosedForms) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  DensityPrior prior(device().impl(), true);
  const int nx = 6, ny = 3, nz = 2;
  std::vector<double> g;
  EXPECT_EQ(prior_at(prior, nx, ny, nz, 1, 1, std::vector<double>(36, 0.4), &g), 0.0);
  for (double v : g) EXPECT_EQ(v, 0.0);
  // A ramp along x with slope a: every voxel but the last column has D = (a, 0, 0).
  const double a = 0.3, eps = 0.05;
  std::vector<double> ramp;
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int i = 0; i < nx; ++i) ramp.push_back(a * i);
  const double interior = double((nx - 1) * ny * nz) / double(nx * ny * nz);
  EXPECT_NEAR(prior_at(prior, nx, ny, nz, 1, 0, ramp, nullptr),
              interior * (std::sqrt(a * a + eps * eps) - eps), 1e-14);
  EXPECT_NEAR(prior_at(prior, nx, ny, nz, 0, 1, ramp, nullptr), interior * a * a, 1e-14);
}

TEST(ReconstructPartsTest, LbfgsFindsTheProjectedMinimumOfABoundedQuadratic) {
  // f = Σ c_i (x_i − t_i)² with t outside the box for two coordinates: the minimum is t clamped.
  const std::vector<double> c = {1, 10, 100, 1000}, t = {0.5, -2, 3, 0.25};
  const std::vector<double> lo = {0, 0, 0, 0}, hi = {1, 1, 1, 1};
  auto f = [&](const std::vector<double>& x, std::vector<double>& g) {
    double v = 0;
    g.resize(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
      v += c[i] * (x[i] - t[i]) * (x[i] - t[i]);
      g[i] = 2 * c[i] * (x[i] - t[i]);
    }
    return v;
  };
  Lbfgs l(lo, hi, 5, 0.1);
  std::vector<double> x = {0.9, 0.9, 0.1, 0.9};
  for (int k = 0; k < 60; ++k) l.step(x, f);
  const std::vector<double> want = {0.5, 0, 1, 0.25};
  for (std::size_t i = 0; i < x.size(); ++i) EXPECT_NEAR(x[i], want[i], 1e-8) << "x" << i;
}

TEST(ReconstructPartsTest, LbfgsSolvesRosenbrock) {
  auto f = [](const std::vector<double>& x, std::vector<double>& g) {
    const double a = 1 - x[0], b = x[1] - x[0] * x[0];
    g = {-2 * a - 400 * x[0] * b, 200 * b};
    return a * a + 100 * b * b;
  };
  const double inf = std::numeric_limits<double>::infinity();
  Lbfgs l({-inf, -inf}, {inf, inf}, 10, 0.1);
  std::vector<double> x = {-1.2, 1};
  double value = 0;
  for (int k = 0; k < 200; ++k) value = l.step(x, f);
  EXPECT_NEAR(x[0], 1, 1e-6);
  EXPECT_NEAR(x[1], 1, 1e-6);
  EXPECT_LT(value, 1e-12);
}

TEST(ReconstructPartsTest, ResampleKeepsConstantsAndLinearRamps) {
  Volume v;
  v.nx = 8;
  v.ny = 4;
  v.nz = 4;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 8; ++x) v.data.push_back(float(0.25 + 0.1 * x));
  // Down by 2: each coarse cell averages two fine cells of the ramp: 0.25 + 0.1·(2i + 0.5).
  const Volume down = resample_volume(v, 4, 2, 2);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(down.at(i, 1, 1), 0.25 + 0.1 * (2 * i + 0.5), 1e-6);
  // Up by 2 and back: interior cells of a linear ramp are reproduced exactly.
  const Volume up = resample_volume(v, 16, 8, 8);
  for (int i = 2; i < 14; ++i)
    EXPECT_NEAR(up.at(i, 3, 3), 0.25 + 0.1 * ((i + 0.5) / 2 - 0.5), 1e-6) << "cell " << i;
  EXPECT_THROW(resample_volume(v, 0, 1, 1), Error);
}

// A small density problem shared by the tests below: 16³ phantom, 8 views of 24².
TEST(ReconstructPartsTest, BatchesAndJointDensityAndTf) {
  const Small p;
  Scene start = p.scene;
  std::vector<double> tf = tf_parameters(start.tf);
  for (double& v : tf) v *= 0.8;
  set_tf_parameters(start.tf, tf);
  ReconstructOptions o;
  o.tf = true;
  o.iterations = 40;
  o.batch = 3;
  o.init = Init::constant;
  Reconstruction r(device(), start, p.targets, o);
  EXPECT_EQ(r.options().optimizer.kind, OptimizerKind::adam);
  while (!r.done()) EXPECT_EQ(r.step().views, 3);
  const std::vector<IterationRecord>& h = r.history();
  EXPECT_LT(h.back().loss, 0.1 * h.front().loss);
  EXPECT_GT(h.back().device_bytes, 16u * 16 * 16 * 4 * 3);
  const std::vector<double> got = tf_parameters(r.result().tf);
  EXPECT_NE(got, tf);  // the TF moved
}

// Data-parallel over views (ReconstructOptions::workers; what mpirun -np N ivr reconstruct runs):
// two workers on threads, each with its own context and half of every batch, summing through a
// rendezvous, follow the one-process run — density and TF, batches of 3 views split 2 + 1.
TEST(ReconstructPartsTest, WorkersSharingTheBatchFollowOneProcess) {
  const Small p;
  const Precision precision = device().info().fp64 ? Precision::f64 : Precision::f32;
  ReconstructOptions o;
  o.tf = true;
  o.iterations = 8;
  o.batch = 3;
  o.init = Init::constant;
  o.precision = precision;
  Reconstruction one(device(), p.scene, p.targets, o);
  while (!one.done()) one.step();
  const WorkerRuns runs = run_workers(2, p.scene, p.targets, o);
  const std::vector<std::vector<IterationRecord>>& histories = runs.histories;
  const std::vector<std::vector<double>>& densities = runs.densities;
  const std::vector<std::string>& errors = runs.errors;
  ASSERT_EQ(errors, (std::vector<std::string>{"", ""}));
  const double tol = precision == Precision::f64 ? 1e-10 : 1e-4;
  for (int w = 0; w < 2; ++w) {
    ASSERT_EQ(histories[w].size(), one.history().size());
    for (std::size_t k = 0; k < histories[w].size(); ++k) {
      EXPECT_EQ(histories[w][k].views, 3);
      EXPECT_NEAR(histories[w][k].loss, one.history()[k].loss, tol * one.history()[k].loss)
          << "worker " << w << ", iteration " << k + 1;
    }
  }
  EXPECT_EQ(densities[0], densities[1]);  // the same step on both workers
  const std::vector<float>& a = one.result().volume.data;
  ASSERT_EQ(a.size(), densities[0].size());
  double worst = 0, scale = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, std::abs(a[i] - densities[0][i])), scale = std::max(scale, double(std::abs(a[i])));
  EXPECT_LE(worst, (precision == Precision::f64 ? 1e-6 : 1e-3) * scale);
}

// Deterministic (fixed-point) density gradients shared by workers are the one process's bit for
// bit (FixedShare: the batch's normaliser, ray count and target range in every share's scale, the
// passes agreed, the integer sums added exactly), so a density reconstruction by 2 or 3 workers
// ends at the one process's densities exactly — batches of 5 views split 3 + 2 and 2 + 2 + 1.
TEST(ReconstructPartsTest, DeterministicWorkersEqualOneProcessBitForBit) {
  const Small p;
  for (Precision precision : {Precision::f64, Precision::f32}) {
    if (precision == Precision::f64 && !device().info().fp64) continue;
    ReconstructOptions o;
    o.iterations = 5;
    o.batch = 5;
    o.init = Init::constant;
    o.precision = precision;
    o.deterministic = true;
    AdjointOptions fixed;
    fixed.deterministic = true;
    if (!adjoint(device(), p.scene, p.targets, fixed).deterministic)
      GTEST_SKIP() << "fixed point needs 64-bit integer atomics";
    Reconstruction one(device(), p.scene, p.targets, o);
    while (!one.done()) EXPECT_TRUE(one.step().deterministic);
    const std::vector<float>& a = one.result().volume.data;
    const std::vector<double> want(a.begin(), a.end());
    for (int workers : {2, 3}) {
      const WorkerRuns runs = run_workers(workers, p.scene, p.targets, o);
      ASSERT_EQ(runs.errors, std::vector<std::string>(std::size_t(workers)));
      for (int w = 0; w < workers; ++w) {
        const std::string what = std::string(test::name(precision)) + ", worker " + std::to_string(w) +
                                 " of " + std::to_string(workers);
        EXPECT_EQ(runs.densities[std::size_t(w)], want) << what;
        EXPECT_TRUE(runs.histories[std::size_t(w)].back().deterministic) << what;
        ASSERT_EQ(runs.histories[std::size_t(w)].size(), one.history().size()) << what;
        for (std::size_t k = 0; k < one.history().size(); ++k)
          EXPECT_NEAR(runs.histories[std::size_t(w)][k].loss, one.history()[k].loss,
                      1e-5 * one.history()[k].loss)
              << what << ", iteration " << k + 1;
      }
    }
  }
}

// In forward mode the loss gradient is reduced in a fixed order (no atomics): resuming from a
// checkpoint reproduces the uninterrupted run bit for bit (Adam and L-BFGS). (The planner picks
// the adjoint for this 12-parameter TF with the default cost model; its atomic adds would make
// two uninterrupted runs differ in the last bits.)
TEST(ReconstructPartsTest, TfResumeIsBitForBit) {
  const Small p;
  Scene start = p.scene;
  std::vector<double> tf = tf_parameters(start.tf);
  for (double& v : tf) v *= 0.7;
  set_tf_parameters(start.tf, tf);
  const std::string dir = test::temp_dir("tf_resume");
  for (OptimizerKind kind : {OptimizerKind::adam, OptimizerKind::lbfgs}) {
    ReconstructOptions o;
    o.density = false;
    o.tf = true;
    o.iterations = 9;
    o.automatic_optimizer = false;
    o.optimizer.kind = kind;
    o.mode = Mode::forward;
    Reconstruction whole(device(), start, p.targets, o);
    while (!whole.done()) whole.step();
    Reconstruction first(device(), start, p.targets, o);
    for (int k = 0; k < 4; ++k) first.step();
    first.save_checkpoint(dir + "/tf");
    Reconstruction second(device(), start, p.targets, o);
    second.resume(dir + "/tf");
    EXPECT_EQ(second.iteration(), 4);
    while (!second.done()) second.step();
    EXPECT_EQ(tf_parameters(second.result().tf), tf_parameters(whole.result().tf))
        << optimizer_name(kind);
    ASSERT_EQ(second.history().size(), whole.history().size());
    for (std::size_t i = 0; i < whole.history().size(); ++i)
      EXPECT_EQ(second.history()[i].loss, whole.history()[i].loss) << "iteration " << i + 1;
  }
}

// The fixed-point density gradient: the same bits on every run (PoCL's threads add in a
// different order each time, which changes the float atomics' last bits), within float
// rounding of the float-atomic gradient, in both precisions.
TEST(ReconstructPartsTest, DeterministicGradientRepeatsBitForBit) {
  const Small p;
  Scene s = p.scene;
  for (float& d : s.volume.data) d = 0.8f * d + 0.1f;  // away from the targets
  for (Precision precision : {Precision::f32, Precision::f64}) {
    if (precision == Precision::f64 && !device().info().fp64) continue;
    AdjointOptions o;
    o.precision = precision;
    o.deterministic = true;
    const AdjointGradient a = adjoint(device(), s, p.targets, o);
    ASSERT_TRUE(a.deterministic) << "PoCL has cl_khr_int64_base_atomics";
    for (int run = 0; run < 3; ++run)
      EXPECT_EQ(adjoint(device(), s, p.targets, o).density, a.density) << test::name(precision);
    o.deterministic = false;
    const AdjointGradient f = adjoint(device(), s, p.targets, o);
    EXPECT_FALSE(f.deterministic);
    double largest = 0;
    for (float v : f.density) largest = std::max(largest, double(std::abs(v)));
    ASSERT_GT(largest, 0);
    for (std::size_t i = 0; i < f.density.size(); ++i)
      ASSERT_NEAR(a.density[i], f.density[i], 1e-5 * largest + 1e-4 * std::abs(f.density[i]))
          << test::name(precision) << " voxel " << i;
    EXPECT_DOUBLE_EQ(a.loss, f.loss);
  }
}

// Densities: the checkpoint restores the level, the densities and Adam's moments exactly, and
// with the deterministic gradient (the default; its fixed-point scale a function of each
// iteration's inputs) the continuation is the uninterrupted run, bit for bit, whatever PoCL's
// thread scheduling.
TEST(ReconstructPartsTest, DensityResumeContinuesTheRun) {
  const Small p;
  const std::string dir = test::temp_dir("density_resume");
  ReconstructOptions o;
  o.iterations = 14;
  o.levels = 2;
  o.batch = 5;
  o.tv = 1e-4;
  o.init = Init::constant;
  Reconstruction whole(device(), p.scene, p.targets, o);
  while (!whole.done()) whole.step();
  Reconstruction first(device(), p.scene, p.targets, o);
  for (int k = 0; k < 6; ++k) first.step();
  first.save_checkpoint(dir + "/d");
  const Scene at_six = first.result();
  Reconstruction second(device(), p.scene, p.targets, o);
  second.resume(dir + "/d");
  const Scene restored = second.result();
  EXPECT_EQ(restored.volume.data, at_six.volume.data);  // the saved state itself is exact
  while (!second.done()) second.step();
  EXPECT_EQ(second.result().volume.data, whole.result().volume.data);
  ASSERT_EQ(second.history().size(), 14u);
  for (std::size_t i = 0; i < 14; ++i)
    EXPECT_EQ(second.history()[i].loss, whole.history()[i].loss) << "iteration " << i + 1;
}

TEST(ReconstructPartsTest, BadOptionsAreNamed) {
  const Small p;
  auto message = [&](ReconstructOptions o, const Image& targets) {
    try {
      Reconstruction r(device(), p.scene, targets, o);
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument);
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ReconstructOptions o;
  o.optimizer.lr = -0.1;
  EXPECT_NE(message(o, p.targets).find("lr must be > 0"), std::string::npos);
  o = {};
  o.density = false;
  EXPECT_NE(message(o, p.targets).find("nothing to optimise"), std::string::npos);
  o = {};
  o.automatic_optimizer = false;
  o.optimizer.kind = OptimizerKind::lbfgs;
  EXPECT_NE(message(o, p.targets).find("lbfgs is for small parameter sets"), std::string::npos);
  o = {};
  o.automatic_optimizer = false;
  o.optimizer.kind = OptimizerKind::sgd;
  EXPECT_NE(message(o, p.targets).find("sgd needs an explicit lr"), std::string::npos);
  o = {};
  o.density = false;
  o.tf = true;
  o.batch = 2;
  EXPECT_NE(message(o, p.targets).find("lbfgs needs every view"), std::string::npos);
  o = {};
  o.iterations = 0;
  EXPECT_NE(message(o, p.targets).find("iterations must be >= 1"), std::string::npos);
  o = {};
  o.tv = -1;
  EXPECT_NE(message(o, p.targets).find("tv must be >= 0"), std::string::npos);
  Image wrong = p.targets;
  wrong.views = 7;
  wrong.pixels.resize(wrong.pixels.size() / 8 * 7);
  EXPECT_NE(message({}, wrong).find("target"), std::string::npos);
  EXPECT_THROW(parse_optimizer("adamw"), Error);
  o = {};
  o.workers = 2;
  EXPECT_NE(message(o, p.targets).find("need a sum"), std::string::npos);
  o.worker = 2;
  EXPECT_NE(message(o, p.targets).find("worker 2 of 2"), std::string::npos);
  o = {};
  o.workers = 2, o.sum = [](std::vector<double>&) {}, o.batch = 1;
  EXPECT_NE(message(o, p.targets).find("each needs one"), std::string::npos);

  // A checkpoint of other options is refused, naming the option.
  const std::string dir = test::temp_dir("resume_mismatch");
  ReconstructOptions a;
  a.iterations = 3;
  Reconstruction r(device(), p.scene, p.targets, a);
  r.step();
  r.save_checkpoint(dir + "/x");
  ReconstructOptions b = a;
  b.optimizer.lr = 0.5;
  Reconstruction other(device(), p.scene, p.targets, b);
  try {
    other.resume(dir + "/x");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lr"), std::string::npos) << e.what();
  }
  EXPECT_THROW(other.resume(dir + "/missing"), Error);
}

}  // namespace
}  // namespace ivr
