// c_api_weighted_slabs_test.cpp — slabs sized by weight through the C API and its C++ wrapper
// (ivr_domain_slab_weighted, ivr_render_split_weighted, ivr_gradient_split_weighted and
// ivr_gradient_split_deterministic, ivr_tomo_split_weighted, ivr_scene_set_volume_slab_weighted,
// ivr_reconstruction_create_weighted over slabs): two workers on threads weighted 1:3 hold the
// planes of the weighted split and give one process's results (the fixed-point density its bits);
// mismatched and bad weights are refused by name.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "capi_split_support.hpp"
#include "ivr/ivr.h"
#include "ivr/ivr.hpp"
#include "ivr/ivr_reconstruct.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// Emission–absorption, trapezoid (a segment's near sample crosses each slab face), 12 planes.
const char* const kScene = R"({
  "volume": {"synthetic": "shepp_logan", "dims": [8, 10, 12]}, "model": "emission_absorption",
  "tf": {"type": "piecewise_linear", "points": [
    {"density": 0.05, "color": [0.1, 0, 0], "extinction": 0.5},
    {"density": 1, "color": [1, 0.7, 0.4], "extinction": 6},
    {"density": 2, "color": [0.5, 0.8, 1], "extinction": 12}]},
  "background": [0.2, 0.3, 0.1],
  "cameras": [
    {"eye": [2, 0.1, 0.05], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
     "fov_y": 40},
    {"eye": [0.3, -0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "width": 9, "height": 7,
     "fov_y": 45}],
  "integrator": {"scheme": "trapezoid", "step": 0.4, "min_transmittance": 0}})";
constexpr int kPlanes = 12;
constexpr std::size_t kPlane = 8 * 10, kPixels = 2 * 9 * 7 * 4;  // (RGBA)
// 11 cells 1:3 → 2.75 and 8.25, the remainder to the larger fraction: planes 0..3 and 3..11
// (equal slabs: 0..5 and 5..11).
const double kShares[2] = {1, 3};
constexpr int kFirst[2] = {0, 3}, kLast[2] = {3, 11};

using Worker = CapiWorker;  // (its sum: capi_summed)
constexpr ivr_sum_fn summed = capi_summed;

// Two workers' slabs (planes × kPlane values each) as the whole volume, the shared plane's parts
// added (a gradient) or taken once (values).
std::vector<double> joined(const std::vector<double>& a, const std::vector<double>& b, bool add) {
  std::vector<double> out(a);
  for (std::size_t i = 0; i < kPlane; ++i)
    if (add) out[out.size() - kPlane + i] += b[i];
  out.insert(out.end(), b.begin() + std::ptrdiff_t(kPlane), b.end());
  return out;
}

TEST(CApiWeightedSlabs, SlabsFollowTheWeights) {
  int first = -1, last = -1;
  for (int r = 0; r < 2; ++r) {
    ASSERT_EQ(ivr_domain_slab_weighted(kPlanes, r, 2, kShares, &first, &last), IVR_OK)
        << ivr_last_error();
    EXPECT_EQ(first, kFirst[r]);
    EXPECT_EQ(last, kLast[r]);
    // NULL and equal weights: ivr_domain_slab's runs.
    int f = 0, l = 0;
    ASSERT_EQ(ivr_domain_slab(kPlanes, r, 2, &f, &l), IVR_OK);
    const double equal[2] = {2.5, 2.5};
    for (const double* w : {static_cast<const double*>(nullptr), equal}) {
      ASSERT_EQ(ivr_domain_slab_weighted(kPlanes, r, 2, w, &first, &last), IVR_OK);
      EXPECT_EQ(first, f);
      EXPECT_EQ(last, l);
    }
  }
  // A weight of 1000 against 1 still leaves the slow worker a cell.
  const double lopsided[3] = {1000, 1, 1};
  ASSERT_EQ(ivr_domain_slab_weighted(4, 1, 3, lopsided, &first, &last), IVR_OK);
  EXPECT_EQ(last - first, 1);
  const double zero[2] = {1, 0}, nan[2] = {std::nan(""), 1};
  for (const double* w : {zero, nan}) {
    EXPECT_EQ(ivr_domain_slab_weighted(kPlanes, 0, 2, w, &first, &last),
              IVR_ERROR_INVALID_ARGUMENT);
    EXPECT_TRUE(has(ivr_last_error(), "ivr_domain_slab_weighted")) << ivr_last_error();
    EXPECT_TRUE(has(ivr_last_error(), "shares[")) << ivr_last_error();
  }
  EXPECT_EQ(ivr_domain_slab_weighted(kPlanes, 0, 2, kShares, nullptr, &last),
            IVR_ERROR_NULL_POINTER);
  EXPECT_EQ(ivr_domain_slab_weighted(kPlanes, 2, 2, kShares, &first, &last),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "worker 2 of 2")) << ivr_last_error();
}

// A worker's (or one process's) image, density gradient (its planes), TF and background parts.
struct Outcome {
  std::vector<float> image = std::vector<float>(kPixels, -1.0f);
  std::vector<double> density, tf, background;
  std::string error;
};

std::vector<double> array_of(const ivr_result* r, const char* name) {
  size_t count = 0;
  EXPECT_EQ(ivr_result_array_count(r, &count), IVR_OK);
  for (size_t i = 0; i < count; ++i) {
    const char* n = nullptr;
    int rank = 0;
    int64_t shape[5] = {};
    EXPECT_EQ(ivr_result_array_shape(r, i, &n, &rank, shape), IVR_OK);
    if (std::string(n) != name) continue;
    size_t size = 1;
    for (int d = 0; d < rank; ++d) size *= size_t(shape[d]);
    std::vector<double> v(size);
    EXPECT_EQ(ivr_result_array_data(r, i, v.data(), size), IVR_OK);
    return v;
  }
  ADD_FAILURE() << "no array " << name;
  return {};
}

// ranks 0: one process; else worker `rank` of 2 weighted kShares over `split`, its scene whole or
// (slab_alone) holding its planes alone.
// `deterministic`: the density gradient in fixed point (ivr_gradient_shared for one process,
// ivr_gradient_split_deterministic for a worker) at `precision`.
Outcome run(ivr_split split, int rank, int ranks, bool slab_alone, WorkerSum* sum,
            const std::vector<float>& target, bool deterministic = false,
            ivr_precision precision = IVR_PRECISION_F64) {
  Outcome out;
  ivr_context* c = nullptr;
  ivr_scene* scene = nullptr;
  ivr_result* result = nullptr;
  Worker w{sum, rank};
  const char* wrt = "density,tf,background";
  bool ok = ivr_context_create(nullptr, &c) == IVR_OK &&
            ivr_scene_from_json(c, kScene, nullptr, &scene) == IVR_OK;
  std::vector<float> values(kPlane * kPlanes);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.5f + 0.4f * std::sin(0.3f * float(i));
  const int64_t shape[3] = {kPlanes, 10, 8}, slab_shape[3] = {kLast[rank] - kFirst[rank] + 1, 10, 8};
  if (ok && slab_alone)
    ok = ivr_scene_set_volume_slab_weighted(scene,
                                            values.data() + kPlane * std::size_t(kFirst[rank]),
                                            IVR_FLOAT32, slab_shape, kPlanes, rank, 2,
                                            kShares) == IVR_OK;
  else if (ok)
    ok = ivr_scene_set_volume(scene, values.data(), IVR_FLOAT32, shape) == IVR_OK;
  if (ranks == 0)
    ok = ok && ivr_render(c, scene, precision, 0, out.image.data(), kPixels) == IVR_OK &&
         (deterministic
              ? ivr_gradient_shared(c, scene, target.data(), kPixels, wrt, IVR_MODE_ADJOINT,
                                    IVR_LOSS_MSE, precision, 0, 1, 0, 1, nullptr, nullptr, &result)
              : ivr_gradient(c, scene, target.data(), kPixels, wrt, IVR_MODE_ADJOINT, IVR_LOSS_MSE,
                             precision, 0, &result)) == IVR_OK;
  else
    ok = ok &&
         ivr_render_split_weighted(c, scene, precision, 0, split, rank, ranks, kShares, summed, &w,
                                   out.image.data(), kPixels) == IVR_OK &&
         (deterministic ? ivr_gradient_split_deterministic(
                              c, scene, target.data(), kPixels, wrt, IVR_LOSS_MSE, precision, 0,
                              split, 1, rank, ranks, kShares, summed, &w, &result)
                        : ivr_gradient_split_weighted(
                              c, scene, target.data(), kPixels, wrt, IVR_LOSS_MSE, precision, 0,
                              split, rank, ranks, kShares, summed, &w, &result)) == IVR_OK;
  if (ok) {
    out.density = array_of(result, "density");
    out.tf = array_of(result, "tf");
    out.background = array_of(result, "background");
  } else {
    out.error = ivr_last_error();
    if (sum) sum->abort();
  }
  ivr_result_release(result);
  ivr_scene_release(scene);
  ivr_context_release(c);
  return out;
}

TEST(CApiWeightedSlabs, WorkersByWeightGiveOneProcess) {
  if (!device().info().fp64) GTEST_SKIP() << "float64 needed for the comparison";
  std::vector<float> target(kPixels);
  for (std::size_t i = 0; i < kPixels; ++i) target[i] = 0.3f + 0.2f * std::sin(0.7f * float(i));
  const Outcome one = run(IVR_SPLIT_SLABS, 0, 0, false, nullptr, target);
  ASSERT_EQ(one.error, "");
  for (ivr_split split : {IVR_SPLIT_SLABS, IVR_SPLIT_SEGMENTS})
    for (bool slab_alone : {false, true}) {
      const std::string what = std::string(split == IVR_SPLIT_SLABS ? "states" : "segments") +
                               (slab_alone ? ", slabs held alone" : ", whole scenes");
      WorkerSum sum(2);
      Outcome parts[2];
      std::thread other([&] { parts[1] = run(split, 1, 2, slab_alone, &sum, target); });
      parts[0] = run(split, 0, 2, slab_alone, &sum, target);
      other.join();
      ASSERT_EQ(parts[0].error + parts[1].error, "") << what;
      for (int r = 0; r < 2; ++r) {
        // Each worker's density part holds its weighted planes (equal slabs would be 6 and 7).
        EXPECT_EQ(parts[r].density.size(), kPlane * std::size_t(kLast[r] - kFirst[r] + 1)) << what;
        double worst = 0, scale = 0;
        for (std::size_t i = 0; i < kPixels; ++i) {
          worst = std::max(worst, std::abs(double(parts[r].image[i]) - one.image[i]));
          scale = std::max(scale, std::abs(double(one.image[i])));
        }
        EXPECT_LE(worst, 1e-6 * scale) << what << ", worker " << r;  // (float32 images)
        EXPECT_LE(worst_relative(parts[r].background, one.background), 1e-10) << what;
      }
      ASSERT_EQ(parts[0].density.size() + parts[1].density.size(), one.density.size() + kPlane);
      EXPECT_LE(worst_relative(joined(parts[0].density, parts[1].density, true), one.density),
                1e-10)
          << what;
      std::vector<double> tf = parts[0].tf;
      for (std::size_t i = 0; i < tf.size(); ++i) tf[i] += parts[1].tf[i];
      EXPECT_LE(worst_relative(tf, one.tf), 1e-10) << what;
    }
}

// ivr_gradient_split_deterministic over states: the workers' density parts (a shared plane whole
// on the upper worker, 0 on the lower) add up to one process's fixed-point gradient bit for bit,
// float32 and float64, whole scenes and slabs held alone.
TEST(CApiWeightedSlabs, DeterministicSlabsAreOneProcesssBits) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "no 64-bit integer atomics";
  std::vector<float> target(kPixels);
  for (std::size_t i = 0; i < kPixels; ++i) target[i] = 0.3f + 0.2f * std::sin(0.7f * float(i));
  for (ivr_precision precision : {IVR_PRECISION_F32, IVR_PRECISION_F64}) {
    if (precision == IVR_PRECISION_F64 && !device().info().fp64) continue;
    const Outcome one = run(IVR_SPLIT_SLABS, 0, 0, false, nullptr, target, true, precision);
    ASSERT_EQ(one.error, "");
    for (bool slab_alone : {false, true}) {
      const std::string what = std::string(precision == IVR_PRECISION_F32 ? "f32" : "f64") +
                               (slab_alone ? ", slabs held alone" : ", whole scenes");
      WorkerSum sum(2);
      Outcome parts[2];
      std::thread other([&] {
        parts[1] = run(IVR_SPLIT_SLABS, 1, 2, slab_alone, &sum, target, true, precision);
      });
      parts[0] = run(IVR_SPLIT_SLABS, 0, 2, slab_alone, &sum, target, true, precision);
      other.join();
      ASSERT_EQ(parts[0].error + parts[1].error, "") << what;
      const std::vector<double>& lower = parts[0].density;
      ASSERT_GE(lower.size(), kPlane) << what;
      EXPECT_TRUE(std::all_of(lower.end() - std::ptrdiff_t(kPlane), lower.end(),
                              [](double v) { return v == 0; }))
          << what << ": the lower worker's part of the shared plane";
      EXPECT_EQ(joined(parts[0].density, parts[1].density, true), one.density) << what;
    }
  }
}

// A slab held alone must be cut by the shares the call gives; a worker's scene of one split is
// refused by the other's call, by name.
TEST(CApiWeightedSlabs, MismatchedSharesAreRefused) {
  api::Context ctx;
  const api::Scene scene = ctx.scene_from_json(kScene);
  std::vector<float> values(kPlane * (kLast[0] - kFirst[0] + 1), 0.5f);
  const int64_t shape[3] = {kLast[0] - kFirst[0] + 1, 10, 8};
  ASSERT_EQ(ivr_scene_set_volume_slab_weighted(scene.get(), values.data(), IVR_FLOAT32, shape,
                                               kPlanes, 0, 2, kShares),
            IVR_OK)
      << ivr_last_error();
  WorkerSum sum(1);
  Worker w{&sum, 0};
  std::vector<float> image(kPixels);
  const double other[2] = {1, 1};
  EXPECT_EQ(ivr_render_split_weighted(ctx.get(), scene.get(), IVR_PRECISION_F32, 0,
                                      IVR_SPLIT_SLABS, 0, 2, other, summed, &w, image.data(),
                                      image.size()),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "shares")) << ivr_last_error();
  EXPECT_TRUE(has(ivr_last_error(), "planes 0..5")) << ivr_last_error();
  EXPECT_EQ(ivr_render_split(ctx.get(), scene.get(), IVR_PRECISION_F32, 0, IVR_SPLIT_SLABS, 0, 2,
                             summed, &w, image.data(), image.size()),
            IVR_ERROR_INVALID_ARGUMENT);
  // Weights in proportion cut the same planes.
  const double scaled[2] = {10, 30};
  int first = 0, last = 0;
  ASSERT_EQ(ivr_domain_slab_weighted(kPlanes, 0, 2, scaled, &first, &last), IVR_OK);
  EXPECT_EQ(last, kLast[0]);
  // A slab of the equal split's size under these weights: refused with the planes it needs.
  std::vector<float> equal(kPlane * 6, 0.5f);
  const int64_t equal_shape[3] = {6, 10, 8};
  EXPECT_EQ(ivr_scene_set_volume_slab_weighted(scene.get(), equal.data(), IVR_FLOAT32,
                                               equal_shape, kPlanes, 0, 2, kShares),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "planes 0..3")) << ivr_last_error();
  const double bad[2] = {1, -1};
  EXPECT_EQ(ivr_scene_set_volume_slab_weighted(scene.get(), values.data(), IVR_FLOAT32, shape,
                                               kPlanes, 0, 2, bad),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "shares[1]")) << ivr_last_error();
  // Tomography over views takes no shares (each worker passes its own views).
  ivr_tomo_options o;
  ASSERT_EQ(ivr_tomo_options_init(&o), IVR_OK);
  const api::Scene whole = ctx.scene_from_json(kScene);
  std::vector<float> lines(2 * 9 * 7, 0.1f), volume(kPlane * kPlanes);
  EXPECT_EQ(ivr_tomo_split_weighted(ctx.get(), whole.get(), &o, IVR_SPLIT_VIEWS, 0, 1, kShares,
                                    summed, &w, lines.data(), lines.size(), volume.data(),
                                    volume.size(), nullptr, nullptr, nullptr, 0, nullptr),
            IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(has(ivr_last_error(), "over views")) << ivr_last_error();
}

// ivr_tomo_split_weighted (through the C++ wrapper's Workers::shares) and
// ivr_reconstruction_create_weighted over slabs: two workers weighted 1:3 hold the weighted
// planes and give one process's volume.
TEST(CApiWeightedSlabs, TomographyAndReconstructionByWeight) {
  if (!device().info().fp64) GTEST_SKIP() << "float64 needed for the comparison";
  const std::string absorption = R"({
    "volume": {"synthetic": "shepp_logan", "dims": [8, 10, 12]}, "model": "absorption",
    "tf": {"type": "identity", "extinction_scale": 2, "color_scale": 1},
    "cameras": [
      {"eye": [2, 0.1, 0.05], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
       "projection": "orthographic", "ortho_height": 1.3},
      {"eye": [0.3, -0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "width": 9, "height": 7,
       "fov_y": 45}]})";
  api::Context ctx;
  const api::Scene scene = ctx.scene_from_json(absorption);
  const std::vector<float> lines = ctx.project(scene, api::Precision::f64).values;
  api::TomoOptions o;
  o.precision = IVR_PRECISION_F64;
  o.iterations = 4;
  o.tikhonov = 1e-3;
  const api::TomoResult whole = ctx.tomo(scene, lines, o);
  const std::vector<float> targets = ctx.render(scene).values;
  api::ReconstructOptions ro;
  ro.iterations = 3;
  ro.levels = 2;  // (the coarse level's slabs weighted too)
  ro.precision = IVR_PRECISION_F64;
  ro.init = IVR_INIT_CONSTANT;
  // SGD keeps the gradients' agreement in the iterates (Adam would magnify the fixed-point
  // rounding by which the slabs' bricked sums differ from the in-core ones).
  ro.optimizer = IVR_OPTIMIZER_SGD;
  ro.lr = 1;
  api::Reconstruction one(ctx, scene, targets, ro);
  one.run();
  const api::Array<float> one_volume = one.volume();

  WorkerSum tomo_sum(2), rec_sum(2);
  api::TomoResult tomo_parts[2];
  api::Array<float> rec_parts[2];
  std::string errors[2];
  auto worker = [&](int rank) {
    try {
      api::Context c;
      const api::Scene s = c.scene_from_json(absorption);
      api::Workers w;
      w.split = IVR_SPLIT_SLABS, w.rank = rank, w.ranks = 2;
      w.shares.assign(kShares, kShares + 2);
      w.sum = [&, rank](double* v, size_t n) {
        std::vector<double> values(v, v + n);
        tomo_sum.sum(rank, values);
        std::copy(values.begin(), values.end(), v);
      };
      tomo_parts[rank] = c.tomo(s, lines, o, {}, &w);
      w.sum = [&, rank](double* v, size_t n) {
        std::vector<double> values(v, v + n);
        rec_sum.sum(rank, values);
        std::copy(values.begin(), values.end(), v);
      };
      api::Reconstruction r(c, s, targets, ro, w);
      r.run();
      rec_parts[rank] = r.volume();
    } catch (const std::exception& e) {
      errors[rank] = e.what();
      tomo_sum.abort();
      rec_sum.abort();
    }
  };
  std::thread other(worker, 1);
  worker(0);
  other.join();
  ASSERT_EQ(errors[0] + errors[1], "");
  for (int r = 0; r < 2; ++r) {
    EXPECT_EQ(tomo_parts[r].volume.shape, (std::vector<int64_t>{kLast[r] - kFirst[r] + 1, 10, 8}));
    EXPECT_EQ(rec_parts[r].shape[0], kLast[r] - kFirst[r] + 1);
  }
  auto doubles = [](const std::vector<float>& v) { return std::vector<double>(v.begin(), v.end()); };
  const std::vector<double> tomo_joined = joined(doubles(tomo_parts[0].volume.values),
                                                 doubles(tomo_parts[1].volume.values), false);
  EXPECT_LE(worst_relative(tomo_joined, doubles(whole.volume.values)), 1e-6);
  const std::vector<double> rec_joined =
      joined(doubles(rec_parts[0].values), doubles(rec_parts[1].values), false);
  EXPECT_LE(worst_relative(rec_joined, doubles(one_volume.values)), 1e-6);
}

}  // namespace
}  // namespace ivr::test
