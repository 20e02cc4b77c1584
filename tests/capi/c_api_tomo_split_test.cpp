// c_api_tomo_split_test.cpp — the C API's split operations (workers sharing the work through a sum
// callback, as bindings under MPI call them): ivr_tomo_split by two workers on threads, each with
// its own context, over views and over slabs, gives one process's ivr_tomo, one worker alone too;
// ivr_render_slabs by one worker gives ivr_render; bad arguments are refused with a status and a
// message.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "ivr/ivr.h"
#include "ivr/ivr.hpp"
#include "capi_split_support.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

std::string scene_json(const std::vector<int>& views) {
  const char* const cameras[] = {
      R"({"eye": [2, 0.1, 0.05], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
          "projection": "orthographic", "ortho_height": 1.3})",
      R"({"eye": [0.2, 2, -0.3], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
          "projection": "orthographic", "ortho_height": 1.3})",
      R"({"eye": [0.3, -0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "width": 9, "height": 7,
          "fov_y": 45})"};
  std::string list;
  for (int v : views) list += (list.empty() ? "" : ", ") + std::string(cameras[v]);
  return R"({"volume": {"synthetic": "shepp_logan", "dims": [8, 10, 12]}, "model": "absorption",
             "tf": {"type": "identity", "extinction_scale": 2, "color_scale": 1},
             "cameras": [)" +
         list + "]}";
}
constexpr std::size_t kPlane = 8 * 10, kVoxels = kPlane * 12, kViewRays = 9 * 7;

// The workers' sum: every worker's values added in rank order, handed to every worker.
using Summit = WorkerSum;

using Worker = CapiWorker;  // (its sum: capi_summed)
constexpr ivr_sum_fn summed = capi_summed;

int failing_sum(double*, size_t, void*) {
  return 0;
}

ivr_tomo_options options() {
  ivr_tomo_options o;
  EXPECT_EQ(ivr_tomo_options_init(&o), IVR_OK);
  o.precision = IVR_PRECISION_F64;
  o.iterations = 5;
  o.tikhonov = 1e-3;
  return o;
}

// The projections of the scene's own volume (all three views), and one process's reconstruction.
struct Reference {
  std::vector<float> lines, volume;
};

Reference reference() {
  Reference r;
  ivr_context* ctx = nullptr;
  ivr_scene* scene = nullptr;
  EXPECT_EQ(ivr_context_create(nullptr, &ctx), IVR_OK) << ivr_last_error();
  EXPECT_EQ(ivr_scene_from_json(ctx, scene_json({0, 1, 2}).c_str(), nullptr, &scene), IVR_OK);
  r.lines.resize(3 * kViewRays);
  EXPECT_EQ(ivr_project(ctx, scene, IVR_PRECISION_F64, nullptr, 0, r.lines.data(), r.lines.size()),
            IVR_OK);
  for (std::size_t i = 0; i < r.lines.size(); ++i) r.lines[i] *= 1.0f + 0.05f * std::sin(float(i));
  r.volume.resize(kVoxels);
  const ivr_tomo_options o = options();
  EXPECT_EQ(ivr_tomo(ctx, scene, &o, r.lines.data(), r.lines.size(), r.volume.data(),
                     r.volume.size(), nullptr, nullptr, nullptr, 0, nullptr),
            IVR_OK)
      << ivr_last_error();
  ivr_scene_release(scene);
  ivr_context_release(ctx);
  return r;
}

// Worker `rank` of `ranks`: its scene and lines, its result into `out`.
void run_worker(ivr_split split, int rank, int ranks, Summit* summit, const Reference& ref,
                std::vector<float>& out, std::string& error) {
  ivr_context* ctx = nullptr;
  ivr_scene* scene = nullptr;
  if (ivr_context_create(nullptr, &ctx) != IVR_OK) return void(error = ivr_last_error());
  // Over views: worker 0 views 0 and 1, worker 1 view 2 (one worker: all three).
  const std::vector<int> views = split == IVR_SPLIT_SLABS || ranks == 1
                                     ? std::vector<int>{0, 1, 2}
                                     : (rank == 0 ? std::vector<int>{0, 1} : std::vector<int>{2});
  std::vector<float> lines(ref.lines.begin() + std::ptrdiff_t(views.front() * kViewRays),
                           ref.lines.begin() + std::ptrdiff_t((views.back() + 1) * kViewRays));
  Worker w{summit, rank};
  const ivr_tomo_options o = options();
  if (ivr_scene_from_json(ctx, scene_json(views).c_str(), nullptr, &scene) != IVR_OK ||
      ivr_tomo_split(ctx, scene, &o, split, rank, ranks, summed, &w, lines.data(), lines.size(),
                     out.data(), out.size(), nullptr, nullptr, nullptr, 0, nullptr) != IVR_OK)
    error = ivr_last_error();
  ivr_scene_release(scene);
  ivr_context_release(ctx);
}

TEST(CApiTomoSplit, WorkersOverViewsAndSlabsGiveOneProcess) {
  if (!device().info().fp64) GTEST_SKIP() << "float64 needed for the comparison";
  const Reference ref = reference();
  double scale = 0;
  for (float v : ref.volume) scale = std::max(scale, std::abs(double(v)));
  ASSERT_GT(scale, 0.0);
  for (ivr_split split : {IVR_SPLIT_VIEWS, IVR_SPLIT_SLABS})
    for (int ranks : {1, 2}) {
      const std::string what = std::string(split == IVR_SPLIT_VIEWS ? "views" : "slabs") + ", " +
                               std::to_string(ranks) + " worker(s)";
      Summit summit(ranks);
      std::vector<std::vector<float>> out(static_cast<std::size_t>(ranks));
      std::vector<std::string> errors(static_cast<std::size_t>(ranks));
      std::vector<std::thread> threads;
      for (int r = 0; r < ranks; ++r) {
        int first = 0, last = 11;
        if (split == IVR_SPLIT_SLABS)
          ASSERT_EQ(ivr_domain_slab(12, r, ranks, &first, &last), IVR_OK);
        out[std::size_t(r)].assign(kPlane * std::size_t(last - first + 1), -1.0f);
      }
      for (int r = 0; r < ranks; ++r)
        threads.emplace_back(run_worker, split, r, ranks, &summit, std::cref(ref),
                             std::ref(out[std::size_t(r)]), std::ref(errors[std::size_t(r)]));
      for (std::thread& t : threads) t.join();
      for (int r = 0; r < ranks; ++r) ASSERT_EQ(errors[std::size_t(r)], "") << what;
      // The whole volume: every worker's over views; the slabs joined (a shared plane once).
      std::vector<float> got = out[0];
      if (split == IVR_SPLIT_SLABS)
        for (int r = 1; r < ranks; ++r)
          got.insert(got.end(), out[std::size_t(r)].begin() + std::ptrdiff_t(kPlane),
                     out[std::size_t(r)].end());
      else
        for (int r = 1; r < ranks; ++r) EXPECT_EQ(out[std::size_t(r)], out[0]) << what;
      ASSERT_EQ(got.size(), kVoxels) << what;
      double worst = 0;
      for (std::size_t i = 0; i < kVoxels; ++i)
        worst = std::max(worst, std::abs(double(got[i]) - ref.volume[i]));
      EXPECT_LE(worst, 1e-6 * scale) << what;  // float32 outputs of float64 iterates
    }
}

// The C++ wrapper (ivr.hpp, ivr::api): one worker over slabs is ivr_tomo; a sum that throws is
// rethrown.
TEST(CApiTomoSplit, CppWrapper) {
  if (!device().info().fp64) GTEST_SKIP() << "float64 needed for the comparison";
  const Reference ref = reference();
  api::Context ctx;
  const api::Scene scene = ctx.scene_from_json(scene_json({0, 1, 2}));
  api::TomoOptions o;
  static_cast<ivr_tomo_options&>(o) = options();
  int sums = 0;
  api::Workers workers;
  workers.sum = [&](double*, size_t) { ++sums; };  // one worker: the sum is the values
  for (ivr_split split : {IVR_SPLIT_SLABS, IVR_SPLIT_VIEWS}) {
    workers.split = split;
    const api::TomoResult r = ctx.tomo(scene, ref.lines, o, {}, &workers);
    EXPECT_EQ(r.volume.shape, (std::vector<int64_t>{12, 10, 8}));
    ASSERT_EQ(r.volume.values.size(), ref.volume.size());
    for (std::size_t i = 0; i < ref.volume.size(); ++i)
      ASSERT_NEAR(r.volume.values[i], ref.volume[i],
                  1e-5f * std::max(1.0f, std::abs(ref.volume[i])));
  }
  EXPECT_GT(sums, 0);  // (over views every CGLS step sums)
  workers.sum = [](double*, size_t) { throw std::runtime_error("no network"); };
  EXPECT_THROW(ctx.tomo(scene, ref.lines, o, {}, &workers), std::runtime_error);

  // The render and gradient over slabs: one worker is the plain render and gradient.
  workers.sum = [](double*, size_t) {};
  const api::Array<float> image = ctx.render(scene, {}, workers);
  EXPECT_EQ(image.values, ctx.render(scene).values);
  std::vector<float> target = image.values;
  for (float& v : target) v = 0.9f * v + 0.01f;
  api::GradientOptions go;
  go.wrt = "density";
  go.mode = api::Mode::adjoint;
  const api::Result mine = ctx.gradient(scene, target, go, workers);
  const api::Result whole = ctx.gradient(scene, target, go);
  EXPECT_NEAR(mine.loss(), whole.loss(), 1e-6 * whole.loss());
  const std::vector<double> a = mine.array("density").values, b = whole.array("density").values;
  ASSERT_EQ(a.size(), b.size());
  double scale = 0;
  for (double v : b) scale = std::max(scale, std::abs(v));
  ASSERT_GT(scale, 0.0);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(a[i], b[i], 1e-5 * scale) << i;
  // Fixed point (ivr_gradient_shared): the same bits by either call, near the float gradient.
  go.deterministic = true;
  const std::vector<double> fixed = ctx.gradient(scene, target, go).array("density").values;
  EXPECT_EQ(fixed, ctx.gradient_shared(scene, target.data(), target.size(), go, workers)
                       .array("density")
                       .values);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(fixed[i], b[i], 1e-5 * scale) << i;
}

// The C++ wrapper's shared reconstruction: each step calls the workers' sum (here worker 0 of 2
// whose "sum" adds an identical second share: no rendezvous, so nothing can hang), and what the
// sum throws comes out of the step. (Two real workers: bindings/python/tests/test_mpi.py.)
TEST(CApiTomoSplit, CppSharedReconstruction) {
  api::Context ctx;
  const api::Scene scene = ctx.scene_from_json(scene_json({0, 1, 2}));
  const std::vector<float> targets = ctx.render(scene).values;
  api::ReconstructOptions o;
  o.iterations = 3;
  int sums = 0;
  api::Workers w;
  w.rank = 0, w.ranks = 2;
  w.sum = [&](double* values, size_t count) {
    ++sums;
    for (size_t i = 0; i < count; ++i) values[i] *= 2;
  };
  api::Reconstruction r(ctx, scene, targets, o, w);
  const ivr_reconstruct_iteration first = r.step();
  EXPECT_EQ(first.iteration, 1);
  EXPECT_GT(sums, 0);
  w.sum = [](double*, size_t) { throw std::runtime_error("no network"); };
  api::Reconstruction failing(ctx, scene, targets, o, w);
  EXPECT_THROW(failing.step(), std::runtime_error);
}

TEST(CApiTomoSplit, BadArgumentsAreRefused) {
  ivr_context* ctx = nullptr;
  ivr_scene* scene = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &ctx), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_scene_from_json(ctx, scene_json({0, 1, 2}).c_str(), nullptr, &scene), IVR_OK);
  std::vector<float> lines(3 * kViewRays, 0.1f), volume(kVoxels);
  ivr_tomo_options o = options();
  o.precision = IVR_PRECISION_F32;
  auto call = [&](ivr_split split, int rank, int ranks, ivr_sum_fn sum, std::size_t capacity) {
    Summit summit(1);
    Worker w{&summit, 0};
    return ivr_tomo_split(ctx, scene, &o, split, rank, ranks, sum, &w, lines.data(), lines.size(),
                          volume.data(), capacity, nullptr, nullptr, nullptr, 0, nullptr);
  };
  EXPECT_EQ(call(IVR_SPLIT_VIEWS, 0, 1, nullptr, kVoxels), IVR_ERROR_NULL_POINTER);
  EXPECT_TRUE(has(ivr_last_error(), "sum")) << ivr_last_error();
  EXPECT_EQ(call(ivr_split(7), 0, 1, summed, kVoxels), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "split 7")) << ivr_last_error();
  EXPECT_EQ(call(IVR_SPLIT_SLABS, 2, 2, summed, kVoxels), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "worker 2 of 2")) << ivr_last_error();
  EXPECT_EQ(call(IVR_SPLIT_VIEWS, 0, 1, summed, kVoxels - 1), IVR_ERROR_BUFFER_TOO_SMALL);
  EXPECT_EQ(call(IVR_SPLIT_VIEWS, 0, 1, failing_sum, kVoxels), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "sum")) << ivr_last_error();
  o.tikhonov = 0, o.tv = 1e-3;  // (TV over slabs: each worker the rows of its own planes)
  EXPECT_EQ(call(IVR_SPLIT_SLABS, 0, 1, summed, kVoxels), IVR_OK) << ivr_last_error();
  // The render and gradient over slabs (their results: bindings/python/tests/test_mpi.py).
  std::vector<float> image(3 * kViewRays);
  EXPECT_EQ(ivr_render_slabs(ctx, scene, IVR_PRECISION_F32, 0, 0, 1, nullptr, nullptr, image.data(),
                             image.size()),
            IVR_ERROR_NULL_POINTER);
  Summit one(1);
  Worker w{&one, 0};
  EXPECT_EQ(ivr_render_slabs(ctx, scene, IVR_PRECISION_F32, 0, 2, 2, summed, &w, image.data(),
                             image.size()),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "worker 2 of 2")) << ivr_last_error();
  EXPECT_EQ(ivr_render_slabs(ctx, scene, IVR_PRECISION_F32, 0, 0, 1, summed, &w, image.data(),
                             image.size() - 1),
            IVR_ERROR_BUFFER_TOO_SMALL);
  ASSERT_EQ(ivr_render_slabs(ctx, scene, IVR_PRECISION_F32, 0, 0, 1, summed, &w, image.data(),
                             image.size()),
            IVR_OK)
      << ivr_last_error();
  std::vector<float> in_core(image.size());
  ASSERT_EQ(ivr_render(ctx, scene, IVR_PRECISION_F32, 0, in_core.data(), in_core.size()), IVR_OK);
  for (std::size_t i = 0; i < image.size(); ++i)
    EXPECT_NEAR(image[i], in_core[i], 1e-5f * std::max(1.0f, std::abs(in_core[i])));
  ivr_result* result = nullptr;
  EXPECT_EQ(ivr_gradient_slabs(ctx, scene, image.data(), image.size(), "nothing", IVR_LOSS_MSE,
                               IVR_PRECISION_F32, 0, 0, 1, summed, &w, &result),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(result, nullptr);
  EXPECT_EQ(ivr_gradient_slabs(ctx, scene, image.data(), image.size() - 1, "density", IVR_LOSS_MSE,
                               IVR_PRECISION_F32, 0, 0, 1, summed, &w, &result),
            IVR_ERROR_INVALID_ARGUMENT);
  // A reconstruction whose workers share each batch's views (their results:
  // bindings/python/tests/test_mpi.py test_reconstruct_follows_one_process).
  ivr_reconstruct_options ro;
  ASSERT_EQ(ivr_reconstruct_options_init(&ro), IVR_OK);
  ro.iterations = 2;
  ivr_reconstruction* rec = nullptr;
  EXPECT_EQ(ivr_reconstruction_create_shared(ctx, scene, image.data(), image.size(), &ro, 0, 1,
                                             nullptr, nullptr, &rec),
            IVR_ERROR_NULL_POINTER);
  EXPECT_EQ(ivr_reconstruction_create_shared(ctx, scene, image.data(), image.size(), &ro, 2, 2,
                                             summed, &w, &rec),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "worker 2 of 2")) << ivr_last_error();
  EXPECT_EQ(rec, nullptr);
  ASSERT_EQ(ivr_reconstruction_create_shared(ctx, scene, image.data(), image.size(), &ro, 0, 1,
                                             summed, &w, &rec),
            IVR_OK)
      << ivr_last_error();
  ivr_reconstruct_iteration it;
  EXPECT_EQ(ivr_reconstruction_step(rec, &it), IVR_OK) << ivr_last_error();
  EXPECT_EQ(ivr_reconstruction_release(rec), IVR_OK);
  // Over slabs (ivr_reconstruction_create_split): one worker's planes; a bad split named, and no
  // result scene (it would hold one slab).
  rec = nullptr;
  EXPECT_EQ(ivr_reconstruction_create_split(ctx, scene, image.data(), image.size(), &ro,
                                            ivr_split(7), 0, 1, summed, &w, &rec),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "split 7")) << ivr_last_error();
  ro.levels = 1;
  ASSERT_EQ(ivr_reconstruction_create_split(ctx, scene, image.data(), image.size(), &ro,
                                            IVR_SPLIT_SLABS, 0, 1, summed, &w, &rec),
            IVR_OK)
      << ivr_last_error();
  EXPECT_EQ(ivr_reconstruction_step(rec, &it), IVR_OK) << ivr_last_error();
  int64_t shape[3] = {0, 0, 0};
  EXPECT_EQ(ivr_reconstruction_volume(rec, nullptr, 0, shape), IVR_OK);
  EXPECT_EQ(shape[0] * shape[1] * shape[2], int64_t(kVoxels));  // (one worker: every plane)
  ivr_scene* whole = nullptr;
  EXPECT_EQ(ivr_reconstruction_result_scene(rec, &whole), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "one slab")) << ivr_last_error();
  EXPECT_EQ(ivr_reconstruction_release(rec), IVR_OK);
  int first = 0, last = 0;
  EXPECT_EQ(ivr_domain_slab(4, 0, 4, &first, &last), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(ivr_domain_slab(12, 1, 2, nullptr, &last), IVR_ERROR_NULL_POINTER);
  ivr_scene_release(scene);
  ivr_context_release(ctx);
}

// ivr_gradient_shared: two workers on threads (views 0 and 1, then view 2), each with its own
// context and the whole scene and target, get one process's density gradient bit for bit with
// `deterministic` (and the loss to rounding); bad workers are refused by name.
TEST(CApiTomoSplit, SharedGradientIsOneProcessBitForBit) {
  const std::string json = scene_json({0, 1, 2});
  std::vector<float> target(3 * kViewRays);
  for (std::size_t i = 0; i < target.size(); ++i) target[i] = 0.4f + 0.3f * std::sin(0.37f * float(i));
  // Worker `rank` of `ranks` (ranks 1: no sum): its density gradient, its loss.
  auto run = [&](int rank, int ranks, Summit* summit, std::vector<double>& density, double& loss,
                 std::string& error, const double* shares) {
    ivr_context* ctx = nullptr;
    ivr_scene* scene = nullptr;
    ivr_result* result = nullptr;
    Worker w{summit, rank};
    if (ivr_context_create(nullptr, &ctx) != IVR_OK ||
        ivr_scene_from_json(ctx, json.c_str(), nullptr, &scene) != IVR_OK ||
        ivr_gradient_shared_weighted(ctx, scene, target.data(), target.size(), "density",
                                     IVR_MODE_ADJOINT, IVR_LOSS_MSE, IVR_PRECISION_F32, 0, 1, rank,
                                     ranks, shares, ranks > 1 ? summed : nullptr, &w,
                                     &result) != IVR_OK) {
      error = ivr_last_error();
    } else {
      ivr_mode mode = IVR_MODE_AUTO;
      double seconds = 0;
      density.resize(kVoxels);
      if (ivr_result_info(result, &loss, &mode, &seconds) != IVR_OK ||
          ivr_result_array_data(result, 0, density.data(), density.size()) != IVR_OK)
        error = ivr_last_error();
    }
    ivr_result_release(result);
    ivr_scene_release(scene);
    ivr_context_release(ctx);
  };
  std::vector<double> one;
  double one_loss = 0;
  std::string error;
  run(0, 1, nullptr, one, one_loss, error, nullptr);
  ASSERT_EQ(error, "");
  // Equal shares (2 and 1 views), and weighted 1 : 2 (ivr_gradient_shared_weighted: 1 and 2).
  const double weights[] = {1.0, 2.0};
  for (const double* shares : {static_cast<const double*>(nullptr), weights}) {
    Summit summit(2);
    std::vector<std::vector<double>> density(2);
    std::vector<double> loss(2);
    std::vector<std::string> errors(2);
    std::vector<std::thread> threads;
    for (int r = 0; r < 2; ++r)
      threads.emplace_back([&, r] { run(r, 2, &summit, density[r], loss[r], errors[r], shares); });
    for (std::thread& t : threads) t.join();
    for (int r = 0; r < 2; ++r) {
      ASSERT_EQ(errors[r], "") << "worker " << r;
      EXPECT_EQ(density[r], one) << "worker " << r << ": not one process's bits";
      EXPECT_NEAR(loss[r], one_loss, 1e-6 * one_loss) << "worker " << r;
    }
  }
  ivr_context* ctx = nullptr;
  ivr_scene* scene = nullptr;
  ivr_result* result = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &ctx), IVR_OK);
  ASSERT_EQ(ivr_scene_from_json(ctx, json.c_str(), nullptr, &scene), IVR_OK);
  EXPECT_EQ(ivr_gradient_shared(ctx, scene, target.data(), target.size(), "density",
                                IVR_MODE_AUTO, IVR_LOSS_MSE, IVR_PRECISION_F32, 0, 1, 2, 2,
                                summed, nullptr, &result),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "worker 2 of 2")) << ivr_last_error();
  EXPECT_EQ(ivr_gradient_shared(ctx, scene, target.data(), target.size(), "density",
                                IVR_MODE_AUTO, IVR_LOSS_MSE, IVR_PRECISION_F32, 0, 1, 0, 2,
                                nullptr, nullptr, &result),
            IVR_ERROR_NULL_POINTER);
  EXPECT_TRUE(has(ivr_last_error(), "sum")) << ivr_last_error();
  const double bad[] = {1.0, 0.0};
  EXPECT_EQ(ivr_gradient_shared_weighted(ctx, scene, target.data(), target.size(), "density",
                                         IVR_MODE_AUTO, IVR_LOSS_MSE, IVR_PRECISION_F32, 0, 1, 0,
                                         2, bad, summed, nullptr, &result),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "shares[1]")) << ivr_last_error();
  EXPECT_EQ(result, nullptr);
  double speed = 0;
  ASSERT_EQ(ivr_context_samples_per_second(ctx, &speed), IVR_OK);
  EXPECT_GT(speed, 0);
  EXPECT_TRUE(std::isfinite(speed));
  ivr_scene_release(scene);
  ivr_context_release(ctx);
}

// ivr_view_shares: the weighted split, every worker at least one view with `each`; bad input.
TEST(CApiTomoSplit, ViewSharesFollowTheWeights) {
  std::size_t counts[3] = {9, 9, 9};
  const double w19[] = {1.0, 9.0};
  ASSERT_EQ(ivr_view_shares(4, w19, 2, 0, counts), IVR_OK);
  EXPECT_EQ(counts[0], 0u);
  EXPECT_EQ(counts[1], 4u);
  ASSERT_EQ(ivr_view_shares(4, w19, 2, 1, counts), IVR_OK);
  EXPECT_EQ(counts[0], 1u);
  EXPECT_EQ(counts[1], 3u);
  ASSERT_EQ(ivr_view_shares(7, nullptr, 3, 0, counts), IVR_OK);  // (equal: 3, 2, 2)
  EXPECT_EQ(counts[0], 3u);
  EXPECT_EQ(counts[1], 2u);
  EXPECT_EQ(counts[2], 2u);
  const double bad[] = {1.0, -1.0};
  EXPECT_EQ(ivr_view_shares(4, bad, 2, 1, counts), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "shares[1]")) << ivr_last_error();
  EXPECT_EQ(ivr_view_shares(4, w19, 0, 1, counts), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(ivr_view_shares(4, w19, 2, 1, nullptr), IVR_ERROR_NULL_POINTER);
}

}  // namespace
}  // namespace ivr::test
