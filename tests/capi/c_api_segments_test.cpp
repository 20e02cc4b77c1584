// c_api_segments_test.cpp — the C API's slab marches by name (ivr_render_split, ivr_gradient_split):
// two and three workers on threads over independent segments (IVR_SPLIT_SEGMENTS) and over passed
// states (IVR_SPLIT_SLABS) give one process's ivr_render and ivr_gradient (float64, 1e-12); the C++
// wrapper's Workers::split reaches them; bad splits are refused by name.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "ivr/ivr.h"
#include "ivr/ivr.hpp"
#include "ivr/ivr_session.h"
#include "capi_split_support.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// Emission–absorption through a TF with colour and extinction, trapezoid (its segments carry a
// near sample across each slab face), two perspective views and an orthographic one.
const char* const kScene = R"({
  "volume": {"synthetic": "shepp_logan", "dims": [8, 10, 12]}, "model": "emission_absorption",
  "tf": {"type": "piecewise_linear", "points": [
    {"density": 0, "color": [0.1, 0, 0], "extinction": 0.5},
    {"density": 1, "color": [1, 0.7, 0.4], "extinction": 6},
    {"density": 2, "color": [0.5, 0.8, 1], "extinction": 12}]},
  "background": [0.2, 0.3, 0.1],
  "cameras": [
    {"eye": [2, 0.1, 0.05], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
     "fov_y": 40},
    {"eye": [0.3, -0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "width": 9, "height": 7,
     "fov_y": 45},
    {"eye": [0.2, 2, -1.3], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
     "projection": "orthographic", "ortho_height": 1.3}],
  "integrator": {"scheme": "trapezoid", "step": 0.4, "min_transmittance": 0}})";
constexpr std::size_t kPlane = 8 * 10, kPlanes = 12, kPixels = 3 * 9 * 7 * 4;  // (RGBA)

using Worker = CapiWorker;  // (its sum: capi_summed)
constexpr ivr_sum_fn summed = capi_summed;

// A worker's (or the one process's) image, loss and gradients "density" (its planes), "tf" (its
// part) and "background".
struct Outcome {
  std::vector<float> image;
  int render_sums = 0;  // the sum's calls during the render (the exchanges' collectives)
  double loss = 0;
  std::vector<double> density, tf, background;
  std::string error;
};

void read_arrays(const ivr_result* result, Outcome& out) {
  size_t count = 0;
  ivr_mode mode = IVR_MODE_AUTO;
  double seconds = 0;
  if (ivr_result_info(result, &out.loss, &mode, &seconds) != IVR_OK ||
      ivr_result_array_count(result, &count) != IVR_OK)
    return void(out.error = ivr_last_error());
  for (size_t i = 0; i < count; ++i) {
    const char* name = nullptr;
    int rank = 0;
    int64_t shape[5] = {};
    if (ivr_result_array_shape(result, i, &name, &rank, shape) != IVR_OK)
      return void(out.error = ivr_last_error());
    size_t n = 1;
    for (int d = 0; d < rank; ++d) n *= size_t(shape[d]);
    const std::string which = name;
    std::vector<double>& to =
        which == "density" ? out.density : which == "tf" ? out.tf : out.background;
    to.resize(n);
    if (ivr_result_array_data(result, i, to.data(), n) != IVR_OK)
      return void(out.error = ivr_last_error());
  }
}

// ranks 0: one process (ivr_render, ivr_gradient); else worker `rank` of `ranks` over `split`.
Outcome run(ivr_split split, int rank, int ranks, WorkerSum* sum, const std::vector<float>& target) {
  Outcome out;
  ivr_context* ctx = nullptr;
  ivr_scene* scene = nullptr;
  ivr_result* result = nullptr;
  Worker w{sum, rank};
  out.image.assign(kPixels, -1.0f);
  const char* wrt = "density,tf,background";
  bool ok = ivr_context_create(nullptr, &ctx) == IVR_OK &&
            ivr_scene_from_json(ctx, kScene, nullptr, &scene) == IVR_OK &&
            (ranks == 0 ? ivr_render(ctx, scene, IVR_PRECISION_F64, 0, out.image.data(), kPixels)
                        : ivr_render_split(ctx, scene, IVR_PRECISION_F64, 0, split, rank, ranks,
                                           summed, &w, out.image.data(), kPixels)) == IVR_OK;
  out.render_sums = w.calls;
  ok = ok &&
      (ranks == 0 ? ivr_gradient(ctx, scene, target.data(), kPixels, wrt, IVR_MODE_ADJOINT,
                                 IVR_LOSS_MSE, IVR_PRECISION_F64, 0, &result)
                  : ivr_gradient_split(ctx, scene, target.data(), kPixels, wrt, IVR_LOSS_MSE,
                                       IVR_PRECISION_F64, 0, split, rank, ranks, summed, &w,
                                       &result)) == IVR_OK;
  if (!ok) {
    out.error = ivr_last_error();
    sum->abort();
  } else {
    read_arrays(result, out);
  }
  ivr_result_release(result);
  ivr_scene_release(scene);
  ivr_context_release(ctx);
  return out;
}


TEST(CApiSegments, WorkersGiveOneProcess) {
  if (!device().info().fp64) GTEST_SKIP() << "float64 needed for the comparison";
  std::vector<float> target(kPixels);
  for (std::size_t i = 0; i < kPixels; ++i) target[i] = 0.3f + 0.25f * std::sin(0.41f * float(i));
  WorkerSum none(1);
  const Outcome one = run(IVR_SPLIT_SLABS, 0, 0, &none, target);
  ASSERT_EQ(one.error, "");
  ASSERT_EQ(one.density.size(), kPlane * kPlanes);
  int segments_sums = 0;
  for (int ranks : {2, 3})
    for (ivr_split split : {IVR_SPLIT_SEGMENTS, IVR_SPLIT_SLABS}) {
      const std::string what = std::string(split == IVR_SPLIT_SEGMENTS ? "segments" : "slabs") +
                               ", " + std::to_string(ranks) + " workers";
      WorkerSum sum(ranks);
      std::vector<Outcome> parts(static_cast<std::size_t>(ranks));
      std::vector<std::thread> threads;
      for (int r = 0; r < ranks; ++r)
        threads.emplace_back([&, r] { parts[std::size_t(r)] = run(split, r, ranks, &sum, target); });
      for (std::thread& t : threads) t.join();
      std::vector<double> density, tf(one.tf.size(), 0.0);
      // Over segments the halo's and the segments' exchanges, whatever the workers; over passed
      // states one exchange a sweep, a sweep a slab here (3 workers: more than the segments').
      if (split == IVR_SPLIT_SEGMENTS && ranks == 2) segments_sums = parts[0].render_sums;
      if (split == IVR_SPLIT_SEGMENTS && ranks == 3)
        EXPECT_EQ(parts[0].render_sums, segments_sums) << what;
      if (split == IVR_SPLIT_SLABS && ranks == 3)
        EXPECT_GT(parts[0].render_sums, segments_sums) << what << ": not the segments' march?";
      for (int r = 0; r < ranks; ++r) {
        const Outcome& p = parts[std::size_t(r)];
        ASSERT_EQ(p.error, "") << what << ", worker " << r;
        double worst = 0;
        for (std::size_t i = 0; i < kPixels; ++i)
          worst = std::max(worst, std::abs(double(p.image[i]) - one.image[i]));
        EXPECT_LE(worst, 1e-6) << what << ", worker " << r << ": image (float32 of float64)";
        EXPECT_NEAR(p.loss, one.loss, 1e-12 * one.loss) << what << ", worker " << r;
        EXPECT_LE(worst_relative(p.background, one.background), 1e-12) << what << ", worker " << r;
        // The slabs joined (a shared plane the two parts' sum), the TF parts summed.
        int first = 0, last = 0;
        ASSERT_EQ(ivr_domain_slab(int(kPlanes), r, ranks, &first, &last), IVR_OK);
        ASSERT_EQ(p.density.size(), kPlane * std::size_t(last - first + 1)) << what;
        density.resize(kPlane * std::size_t(last + 1), 0.0);
        for (std::size_t i = 0; i < p.density.size(); ++i)
          density[kPlane * std::size_t(first) + i] += p.density[i];
        ASSERT_EQ(p.tf.size(), tf.size()) << what;
        for (std::size_t i = 0; i < tf.size(); ++i) tf[i] += p.tf[i];
      }
      EXPECT_LE(worst_relative(density, one.density), 1e-12) << what << ": density";
      EXPECT_LE(worst_relative(tf, one.tf), 1e-12) << what << ": tf";
    }
}

// The C++ wrapper: Workers::split IVR_SPLIT_SEGMENTS reaches the segments (3 workers on threads:
// fewer sums than over passed states, which any other value means), the camera's forward lanes
// included; a bad split is refused by every entry.
TEST(CApiSegments, SplitsAreNamedAndBadOnesRefused) {
  api::Context ctx;
  const api::Scene scene = ctx.scene_from_json(kScene);
  // Worker 0's sum calls over a render and a camera gradient by 3 workers through the wrapper.
  auto sums_of = [&](ivr_split split) {
    WorkerSum sum(3);
    std::vector<int> calls(3, 0);
    std::vector<std::string> errors(3);
    auto work = [&](int w) {
      try {
        api::Context mine;
        const api::Scene sc = mine.scene_from_json(kScene);
        api::Workers part;
        part.rank = w, part.ranks = 3, part.split = split;
        part.sum = [&, w](double* values, size_t count) {
          ++calls[std::size_t(w)];
          std::vector<double> v(values, values + count);
          sum.sum(w, v);
          std::copy(v.begin(), v.end(), values);
        };
        const api::Array<float> image = mine.render(sc, {}, part);
        api::GradientOptions go;
        go.wrt = "camera";
        mine.gradient(sc, image.values, go, part);
      } catch (const std::exception& e) {
        errors[std::size_t(w)] = e.what();
        sum.abort();
      }
    };
    std::thread a(work, 1), b(work, 2);
    work(0);
    a.join(), b.join();
    for (const std::string& e : errors) EXPECT_EQ(e, "");
    return calls[0];
  };
  const int segments = sums_of(IVR_SPLIT_SEGMENTS), states = sums_of(IVR_SPLIT_VIEWS);
  EXPECT_GT(segments, 0);
  EXPECT_LT(segments, states) << "Workers::split did not reach the segments";
  const api::Array<float> image = ctx.render(scene);

  ivr_context* c = ctx.get();
  WorkerSum sum(1);
  Worker w{&sum, 0};
  std::vector<float> out(kPixels);
  for (ivr_split bad : {IVR_SPLIT_VIEWS, ivr_split(7)}) {
    const std::string name = "split " + std::to_string(int(bad));
    EXPECT_EQ(ivr_render_split(c, scene.get(), IVR_PRECISION_F32, 0, bad, 0, 1, summed, &w,
                               out.data(), out.size()),
              IVR_ERROR_INVALID_ARGUMENT);
    EXPECT_TRUE(has(ivr_last_error(), name)) << ivr_last_error();
    ivr_result* result = nullptr;
    EXPECT_EQ(ivr_gradient_split(c, scene.get(), image.values.data(), image.size(), "density",
                                 IVR_LOSS_MSE, IVR_PRECISION_F32, 0, bad, 0, 1, summed, &w,
                                 &result),
              IVR_ERROR_INVALID_ARGUMENT);
    EXPECT_TRUE(has(ivr_last_error(), name)) << ivr_last_error();
    EXPECT_EQ(result, nullptr);
  }
  EXPECT_EQ(ivr_render_split(c, scene.get(), IVR_PRECISION_F32, 0, IVR_SPLIT_SEGMENTS, 0, 1,
                             nullptr, nullptr, out.data(), out.size()),
            IVR_ERROR_NULL_POINTER);
  // Tomography has no segments (a line's slab parts add in one sum already).
  ivr_tomo_options o;
  ASSERT_EQ(ivr_tomo_options_init(&o), IVR_OK);
  std::vector<float> lines(3 * 9 * 7, 0.1f), volume(kPlane * kPlanes);
  EXPECT_EQ(ivr_tomo_split(c, scene.get(), &o, IVR_SPLIT_SEGMENTS, 0, 1, summed, &w, lines.data(),
                           lines.size(), volume.data(), volume.size(), nullptr, nullptr, nullptr,
                           0, nullptr),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "split 2")) << ivr_last_error();
  // A reconstruction over segments is made (its runs: bindings/python/tests/test_mpi.py); a bad
  // split named.
  ivr_reconstruct_options ro;
  ASSERT_EQ(ivr_reconstruct_options_init(&ro), IVR_OK);
  ro.iterations = 1;
  ivr_reconstruction* rec = nullptr;
  EXPECT_EQ(ivr_reconstruction_create_split(c, scene.get(), image.values.data(), image.size(), &ro,
                                            ivr_split(5), 0, 1, summed, &w, &rec),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "split 5")) << ivr_last_error();
  ASSERT_EQ(ivr_reconstruction_create_split(c, scene.get(), image.values.data(), image.size(), &ro,
                                            IVR_SPLIT_SEGMENTS, 0, 1, summed, &w, &rec),
            IVR_OK)
      << ivr_last_error();
  EXPECT_EQ(ivr_reconstruction_step(rec, nullptr), IVR_OK) << ivr_last_error();
  ivr_reconstruction_release(rec);
}

// ivr_scene_set_volume_slab: workers holding their planes alone render and differentiate as
// workers given the whole volume do (2 workers on threads, over segments and over states); other
// operations and other workers refuse the scene by name; ivr_scene_set_volume makes it whole.
TEST(CApiSegments, AWorkerHoldsItsSlabAlone) {
  std::vector<float> values(kPlane * kPlanes);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.5f + 0.4f * std::sin(0.3f * float(i));
  const int64_t shape[3] = {int64_t(kPlanes), 10, 8};
  // Worker `rank` of 2: its image and density part, its scene whole or its slab alone.
  struct Part {
    std::vector<float> image = std::vector<float>(kPixels);
    Outcome gradient;
    std::string error;
  };
  auto worker = [&](ivr_split split, int rank, bool slab_alone, WorkerSum* sum, Part& out) {
    ivr_context* c = nullptr;
    ivr_scene* scene = nullptr;
    ivr_result* result = nullptr;
    Worker w{sum, rank};
    int first = 0, last = 0;
    const int64_t planes[3] = {0, 10, 8};
    bool ok = ivr_context_create(nullptr, &c) == IVR_OK &&
              ivr_scene_from_json(c, kScene, nullptr, &scene) == IVR_OK &&
              ivr_domain_slab(int(kPlanes), rank, 2, &first, &last) == IVR_OK;
    if (ok && slab_alone) {
      const int64_t slab_shape[3] = {last - first + 1, planes[1], planes[2]};
      ok = ivr_scene_set_volume_slab(scene, values.data() + kPlane * std::size_t(first),
                                     IVR_FLOAT32, slab_shape, int64_t(kPlanes), rank,
                                     2) == IVR_OK;
    } else if (ok) {
      ok = ivr_scene_set_volume(scene, values.data(), IVR_FLOAT32, shape) == IVR_OK;
    }
    ok = ok &&
         ivr_render_split(c, scene, IVR_PRECISION_F32, 0, split, rank, 2, summed, &w,
                          out.image.data(), kPixels) == IVR_OK &&
         ivr_gradient_split(c, scene, out.image.data(), kPixels, "density", IVR_LOSS_L1,
                            IVR_PRECISION_F32, 0, split, rank, 2, summed, &w, &result) == IVR_OK;
    if (ok) read_arrays(result, out.gradient);
    if (!ok) {
      out.error = ivr_last_error();
      sum->abort();
    }
    ivr_result_release(result);
    ivr_scene_release(scene);
    ivr_context_release(c);
  };
  for (ivr_split split : {IVR_SPLIT_SEGMENTS, IVR_SPLIT_SLABS}) {
    std::vector<std::vector<Part>> runs;
    for (bool slab_alone : {false, true}) {
      WorkerSum sum(2);
      std::vector<Part> parts(2);
      std::thread other([&] { worker(split, 1, slab_alone, &sum, parts[1]); });
      worker(split, 0, slab_alone, &sum, parts[0]);
      other.join();
      for (const Part& p : parts) ASSERT_EQ(p.error, "") << parts[0].error << " / " << parts[1].error;
      runs.push_back(std::move(parts));
    }
    for (int r = 0; r < 2; ++r) {
      EXPECT_EQ(runs[0][r].image, runs[1][r].image) << "worker " << r;
      EXPECT_FALSE(runs[1][r].gradient.density.empty());
      EXPECT_EQ(runs[0][r].gradient.density, runs[1][r].gradient.density) << "worker " << r;
    }
  }
  // Refused: another worker's call, the whole-volume operations, a slab of the wrong size.
  api::Context ctx;
  ivr_context* c = ctx.get();
  const api::Scene slab = ctx.scene_from_json(kScene);
  int first = 0, last = 0;
  ASSERT_EQ(ivr_domain_slab(int(kPlanes), 1, 2, &first, &last), IVR_OK);
  const int64_t slab_shape[3] = {last - first + 1, 10, 8};
  ASSERT_EQ(ivr_scene_set_volume_slab(slab.get(), values.data() + kPlane * std::size_t(first),
                                      IVR_FLOAT32, slab_shape, int64_t(kPlanes), 1, 2),
            IVR_OK)
      << ivr_last_error();
  WorkerSum sum(1);
  Worker w{&sum, 0};
  std::vector<float> b(kPixels);
  EXPECT_EQ(ivr_render_split(c, slab.get(), IVR_PRECISION_F32, 0, IVR_SPLIT_SLABS, 0, 2, summed,
                             &w, b.data(), b.size()),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "not worker 0 of 2")) << ivr_last_error();
  EXPECT_EQ(ivr_render(c, slab.get(), IVR_PRECISION_F32, 0, b.data(), b.size()),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "ivr_scene_set_volume_slab")) << ivr_last_error();
  ivr_session* session = nullptr;
  EXPECT_EQ(ivr_session_create(c, slab.get(), nullptr, &session), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(session, nullptr);
  EXPECT_EQ(ivr_scene_set_volume_slab(slab.get(), values.data(), IVR_FLOAT32, shape,
                                      int64_t(kPlanes), 1, 2),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "planes")) << ivr_last_error();
  EXPECT_EQ(ivr_scene_set_volume_slab(slab.get(), values.data(), IVR_FLOAT32, slab_shape,
                                      int64_t(kPlanes), 2, 2),
            IVR_ERROR_INVALID_ARGUMENT);
  ASSERT_EQ(ivr_scene_set_volume(slab.get(), values.data(), IVR_FLOAT32, shape), IVR_OK);
  EXPECT_EQ(ivr_render(c, slab.get(), IVR_PRECISION_F32, 0, b.data(), b.size()), IVR_OK)
      << ivr_last_error();
}

}  // namespace
}  // namespace ivr::test
