// reconstruct_domain_test.cpp — the reconstruction over slabs of z planes (ReconstructOptions::
// slabs, what mpirun ivr reconstruct --split slabs runs): 1, 2 and 3 workers on threads follow one
// process — densities with both priors (their differences crossing the slabs counted once),
// jointly with the TF, an endpoint scheme — each worker resumes from its own checkpoint, and the
// refusals are named.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "brick/domain_support.hpp"
#include "reconstruct/reconstruct_support.hpp"

namespace ivr {
namespace {

using test::device;
using test::run_workers;
using test::Small;
using test::WorkerRuns;

// The workers' planes joined (a shared plane taken from the lower worker) against one process's
// densities: the largest difference over the largest density. Each plane neighbours share must be
// the same on both (their gradients joined before the same step).
double worst_relative(const WorkerRuns& runs, const Scene& scene, const std::vector<float>& want) {
  const Volume& v = scene.volume;
  const std::size_t plane = std::size_t(v.nx) * std::size_t(v.ny);
  for (std::size_t w = 0; w + 1 < runs.densities.size(); ++w) {
    const std::vector<double>& lower = runs.densities[w];
    const std::vector<double>& upper = runs.densities[w + 1];
    EXPECT_TRUE(std::equal(lower.end() - std::ptrdiff_t(plane), lower.end(), upper.begin()))
        << "the plane workers " << w << " and " << w + 1 << " share";
  }
  const std::vector<double> got = domain_assemble(v.nx, v.ny, v.nz, runs.densities);
  double worst = 0, scale = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    worst = std::max(worst, std::abs(got[i] - double(want[i])));
    scale = std::max(scale, std::abs(double(want[i])));
  }
  return worst / scale;
}

// Runs `o` in one process and over slabs for each worker count: the losses, priors and densities
// of every iteration within `tol` (relative) of the one process's.
void expect_slabs_follow_one_process(const Scene& scene, const Image& targets,
                                     const ReconstructOptions& o, std::initializer_list<int> counts,
                                     double tol) {
  Reconstruction one(device(), scene, targets, o);
  while (!one.done()) one.step();
  const std::vector<IterationRecord>& want = one.history();
  for (int workers : counts) {
    ReconstructOptions os = o;
    os.slabs = true;
    const WorkerRuns runs = run_workers(workers, scene, targets, os);
    const std::string what = std::string(test::name(o.precision)) + ", " +
                             std::to_string(workers) + " worker(s)";
    ASSERT_EQ(runs.errors, std::vector<std::string>(std::size_t(workers))) << what;
    for (int w = 0; w < workers; ++w) {
      const std::vector<IterationRecord>& h = runs.histories[std::size_t(w)];
      ASSERT_EQ(h.size(), want.size()) << what;
      for (std::size_t k = 0; k < h.size(); ++k) {
        EXPECT_NEAR(h[k].loss, want[k].loss, tol * want[k].loss) << what << ", iteration " << k + 1;
        EXPECT_NEAR(h[k].prior, want[k].prior, tol * want[k].prior + 1e-300)
            << what << ", iteration " << k + 1;
      }
    }
    EXPECT_LE(worst_relative(runs, scene, one.result().volume.data), tol) << what;
  }
}

ReconstructOptions slab_options(Precision precision, int levels = 1) {
  ReconstructOptions o;
  o.iterations = 5;
  o.batch = 5;
  o.levels = levels;
  o.init = Init::constant;
  o.precision = precision;
  o.deterministic = false;  // (float sums: FixedPointSlabsAreOneProcesssBitForBit has the bits)
  o.tv = 0.05;
  o.smoothness = 0.02;
  // SGD: its steps are linear in the gradient, so the iterates keep the gradients' agreement
  // (Adam divides each voxel's step by its own gradient's size, and a gradient that is rounding
  // noise of the largest takes a full step either way).
  o.automatic_optimizer = false;
  o.optimizer.kind = OptimizerKind::sgd;
  o.optimizer.lr = 1;
  return o;
}

// Densities with both priors: over 1 (the whole volume as one slab), 2 and 3 slabs of the 16³
// phantom (15 cells: 7 + 8 and 5 + 5 + 5), float64 within 1e-12 and float32 within 1e-5. (Counting
// a shared plane's prior terms on both of its workers fails it at 1e-5.)
TEST(ReconstructDomain, WorkersFollowOneProcessWithThePriors) {
  const Small p;
  if (device().info().fp64)
    expect_slabs_follow_one_process(p.scene, p.targets, slab_options(Precision::f64), {1, 2, 3},
                                    1e-12);
  expect_slabs_follow_one_process(p.scene, p.targets, slab_options(Precision::f32), {2}, 1e-5);
}

// The identity TF's density scale (the unit of the steps) is the whole volume's largest density,
// not each slab's: the densities rising along z give each slab another maximum, equal slabs and
// weighted ones (1:3) alike, and the workers still follow one process to 1e-12 (with the scale
// taken from each slab the lower worker's steps were smaller: 2·10⁻⁵ off after 2 iterations).
// Absorption, one level.
TEST(ReconstructDomain, IdentityTfScaleIsTheWholeVolumes) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  Scene scene = parse_scene(R"({"volume": {"synthetic": "zeros", "dims": [16, 16, 16]},
      "model": "absorption", "tf": {"type": "identity", "extinction_scale": 2, "color_scale": 1},
      "cameras": [)" + test::orbit(8, "[0.2, 0.1, 1]", 3, 24) + "]}",
                              ".", "identity");
  scene.volume = phantom("shepp-logan", 16, 1, 2);
  const Volume& v = scene.volume;
  Scene start = scene;
  for (int z = 0; z < v.nz; ++z)
    for (std::size_t i = 0; i < std::size_t(v.nx) * std::size_t(v.ny); ++i)
      start.volume.data[std::size_t(z) * std::size_t(v.nx) * std::size_t(v.ny) + i] =
          0.2f + 0.02f * float(z) * float(1 + i % 3);
  const Image targets = render(device(), scene);
  ReconstructOptions o = slab_options(Precision::f64);
  o.init = Init::scene;
  o.tv = o.smoothness = 0;
  o.iterations = 2;
  o.optimizer.lr = 0.1;  // (steps that stay clear of the bound at 0)
  expect_slabs_follow_one_process(start, targets, o, {2}, 1e-12);
  o.shares = {1, 3};
  expect_slabs_follow_one_process(start, targets, o, {2}, 1e-12);
}

// With the fixed-point density gradient (`deterministic`, the default) over slabs each iteration's
// gradient is one process's bits (lib/brick/bricked_fixed.hpp), and so are the iterates: Adam (the
// automatic optimiser), both priors (each voxel's terms summed whole by the worker that owns it,
// from the plane below its slab), 2 and 3 workers, float32 — every density the one process's
// bits. (With a shared plane's prior terms and data gradient summed as two parts, 13 and 41 of
// the 4096 densities differed.)
TEST(ReconstructDomain, FixedPointSlabsAreOneProcesssBitForBit) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "no 64-bit integer atomics";
  const Small p;
  ReconstructOptions o = slab_options(Precision::f32);
  o.deterministic = true;
  o.automatic_optimizer = true;
  o.optimizer = {};
  Reconstruction one(device(), p.scene, p.targets, o);
  while (!one.done()) one.step();
  ASSERT_TRUE(one.history().back().deterministic);
  const Volume& v = p.scene.volume;
  for (int workers : {2, 3}) {
    ReconstructOptions os = o;
    os.slabs = true;
    const WorkerRuns runs = run_workers(workers, p.scene, p.targets, os);
    ASSERT_EQ(runs.errors, std::vector<std::string>(std::size_t(workers)));
    EXPECT_TRUE(runs.histories[0].back().deterministic) << workers;
    const std::vector<double> got = domain_assemble(v.nx, v.ny, v.nz, runs.densities);
    const std::vector<float>& want = one.result().volume.data;
    ASSERT_EQ(got.size(), want.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < want.size(); ++i) differ += float(got[i]) != want[i];
    EXPECT_EQ(differ, 0u) << workers << " workers: densities that are not one process's bits";
  }
}

// Coarse to fine over 4³ (3 cells: one per worker), 8³ and 16³ grids, from the scene's densities:
// the start gathered and resampled once, each coarse grid gathered when its level ends, each worker
// keeping its planes of the next — one process's levels to 1e-12 (float64).
TEST(ReconstructDomain, CoarseToFineLevelsFollowOneProcess) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  const Small p;
  Scene start = p.scene;
  for (std::size_t i = 0; i < start.volume.data.size(); ++i)
    start.volume.data[i] = 0.5f * start.volume.data[i] + 0.2f;
  ReconstructOptions o = slab_options(Precision::f64, 3);
  o.init = Init::scene;
  o.iterations = 7;  // (1 + 2 + 4 over the levels)
  Reconstruction one(device(), start, p.targets, o);
  ASSERT_EQ(one.levels(), 3);
  expect_slabs_follow_one_process(start, p.targets, o, {2, 3}, 1e-12);
  ReconstructOptions four = o;  // (4 workers: the coarsest grid would have 3 cells, so 2 levels)
  four.slabs = true;
  const WorkerRuns runs = run_workers(4, start, p.targets, four);
  ASSERT_EQ(runs.errors, std::vector<std::string>(4));
  EXPECT_EQ(runs.histories[0].back().level, 1);
}

// The TF jointly (each slab's samples' part summed over the workers) under the trapezoid scheme,
// whose bricks reach a plane into the neighbours' slabs.
TEST(ReconstructDomain, DensityAndTfUnderAnEndpointScheme) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  Small p;
  p.scene.integrator.scheme = Scheme::trapezoid;
  p.targets = render(device(), p.scene);
  Scene start = p.scene;
  std::vector<double> tf = tf_parameters(start.tf);
  for (double& v : tf) v *= 0.8;
  set_tf_parameters(start.tf, tf);
  ReconstructOptions o = slab_options(Precision::f64);
  o.tf = true;
  o.tf_smoothness = 0.1;
  expect_slabs_follow_one_process(start, p.targets, o, {2}, 1e-12);
}

// Each worker's checkpoint holds its planes and their optimiser state (its own prefix; the slab
// in the fingerprint): two workers stopped after 2 of 5 iterations, resumed by new ones, end where
// uninterrupted workers do — bit for bit with the bricks' fixed-point density sums
// (`deterministic`, where the device has 64-bit integer atomics), else within 1e-12 in float64
// (float atomic sums vary in the last bits); resuming another worker's checkpoint is refused.
TEST(ReconstructDomain, EachWorkerResumesFromItsOwnCheckpoint) {
  if (!device().info().fp64) GTEST_SKIP() << "needs cl_khr_fp64";
  const Small p;
  ReconstructOptions o = slab_options(Precision::f64);
  o.slabs = true;
  o.deterministic = has_int64_atomics(device().impl());
  const WorkerRuns whole = run_workers(2, p.scene, p.targets, o);
  ASSERT_EQ(whole.errors, std::vector<std::string>(2));
  for (int w = 0; w < 2; ++w)
    for (const IterationRecord& r : whole.histories[std::size_t(w)])
      EXPECT_EQ(r.deterministic, o.deterministic) << "worker " << w << ", iteration " << r.iteration;
  const std::string dir = test::temp_dir("slab_resume");
  std::vector<std::vector<double>> resumed(2);
  std::vector<std::string> errors(2), swapped(2);
  WorkerSum first(2), second(2);
  std::vector<std::thread> threads;
  for (int w = 0; w < 2; ++w)
    threads.emplace_back([&, w] {
      try {
        Device d(std::to_string(device().info().index));
        ReconstructOptions ow = o;
        ow.worker = w, ow.workers = 2, ow.sum = first.of(w);
        const Scene mine = domain_share(p.scene, w, 2);
        {
          Reconstruction r(d, mine, p.targets, ow);
          r.step();
          r.step();
          r.save_checkpoint(dir + "/w" + std::to_string(w));
        }
        ow.sum = second.of(w);
        Reconstruction r(d, mine, p.targets, ow);
        try {
          r.resume(dir + "/w" + std::to_string(1 - w));  // (the other worker's: refused)
        } catch (const Error& e) {
          swapped[std::size_t(w)] = e.what();
        }
        r.resume(dir + "/w" + std::to_string(w));
        EXPECT_EQ(r.iteration(), 2);
        while (!r.done()) r.step();
        const std::vector<float>& v = r.result().volume.data;
        resumed[std::size_t(w)].assign(v.begin(), v.end());
      } catch (const std::exception& e) {
        errors[std::size_t(w)] = e.what();
        first.abort();
        second.abort();
      }
    });
  for (std::thread& t : threads) t.join();
  ASSERT_EQ(errors, std::vector<std::string>(2));
  for (int w = 0; w < 2; ++w) {
    EXPECT_NE(swapped[std::size_t(w)], "") << "worker " << w << " resumed the other's checkpoint";
    const std::vector<double>& a = whole.densities[std::size_t(w)];
    const std::vector<double>& b = resumed[std::size_t(w)];
    ASSERT_EQ(a.size(), b.size());
    if (o.deterministic) EXPECT_EQ(a, b) << "worker " << w << ": not bit for bit";
    double worst = 0, scale = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
      worst = std::max(worst, std::abs(a[i] - b[i])), scale = std::max(scale, std::abs(a[i]));
    EXPECT_LE(worst, 1e-12 * scale) << "worker " << w;
  }
}

// A worker's checkpoint over slabs by weight records its planes: resumed over equal slabs, or
// over other weights, it is refused by name (not by a size mismatch further on). (Saved before
// any step: construction and resume take no collective here — an identity TF's would gather the
// workers' largest densities.)
TEST(ReconstructDomain, WeightedSlabCheckpointNamesItsPlanes) {
  const Small p;  // 16 planes: 15 cells, 1:3 gives worker 0 planes 0..4
  ReconstructOptions o = slab_options(Precision::f32);
  o.slabs = true;
  o.worker = 0, o.workers = 2;
  o.sum = [](std::vector<double>&) {};
  o.shares = {1, 3};
  const std::string path = test::temp_dir("slab_planes") + "/w0";
  {
    Reconstruction r(device(), domain_share(p.scene, 0, 2, o.shares), p.targets, o);
    r.save_checkpoint(path);
  }
  ReconstructOptions equal = o;
  equal.shares.clear();
  Reconstruction e(device(), domain_share(p.scene, 0, 2), p.targets, equal);
  test::expect_error([&] { e.resume(path); }, Status::invalid_argument,
               "written with slab_planes = [0,4], this run has equal slabs");
  ReconstructOptions other = o;
  other.shares = {1, 1.5};
  Reconstruction w(device(), domain_share(p.scene, 0, 2, other.shares), p.targets, other);
  test::expect_error([&] { w.resume(path); }, Status::invalid_argument, "slab_planes");
  Reconstruction same(device(), domain_share(p.scene, 0, 2, o.shares), p.targets, o);
  same.resume(path);
  EXPECT_EQ(same.iteration(), 0);
}

TEST(ReconstructDomain, RefusalsNameWhatIsMissing) {
  const Small p;
  ReconstructOptions o = slab_options(Precision::f32);
  o.slabs = true;
  o.workers = 2;
  o.sum = [](std::vector<double>&) {};  // (never reached: each refusal comes first)
  const Scene mine = domain_share(p.scene, 0, 2);
  auto message = [&](const Scene& s, const ReconstructOptions& with) {
    try {
      Reconstruction r(device(), s, p.targets, with);
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument);
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ReconstructOptions tf_alone = o;
  tf_alone.density = false;
  tf_alone.tf = true;
  EXPECT_NE(message(mine, tf_alone).find("the TF alone"), std::string::npos);
  // The whole volume where worker 0's planes 0..7 are wanted.
  EXPECT_NE(message(p.scene, o).find("holds planes 0..7"), std::string::npos);
  Scene tolerance = mine;
  tolerance.integrator.tolerance = 1e-3;
  EXPECT_NE(message(tolerance, o).find("give a step"), std::string::npos);
  ReconstructOptions alone = o;
  alone.sum = nullptr;
  EXPECT_NE(message(mine, alone).find("need a sum over the workers"), std::string::npos);
}

}  // namespace
}  // namespace ivr
