// c_api_reconstruct_test.cpp — the C API's reconstruction handle (create, step, run, volume, TF,
// result scene, checkpoints), viewpoint selection, entropy and PSNR, and their C++ wrappers: the
// loss falls, a callback stops a run, a resumed run ends where the uninterrupted one does, and
// every bad argument gives its status and a message.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "ivr/ivr.h"
#include "ivr/ivr.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A 16³ Shepp–Logan phantom under an emission–absorption TF, 8 views of 32² on a tilted orbit.
const char* const kScene = R"({
  "volume": {"synthetic": "shepp_logan", "dims": [16, 16, 16]}, "model": "emission_absorption",
  "tf": {"type": "piecewise_linear", "points": [
    {"density": 0, "color": [0, 0, 0], "extinction": 0},
    {"density": 1, "color": [1, 0.7, 0.4], "extinction": 8},
    {"density": 2, "color": [0.5, 0.8, 1], "extinction": 16}]},
  "background": [0, 0, 0],
  "cameras": [{"orbit": {"views": 8, "axis": [0.3, 0.2, 1], "start": 5, "radius": 2.2,
               "fov_y": 40, "width": 32, "height": 32}}],
  "integrator": {"scheme": "midpoint", "step": 0.5}})";
// The same TF 30 % off in colour and extinction: where a TF reconstruction starts.
const char* const kWrongTf = R"({"type": "piecewise_linear", "points": [
    {"density": 0, "color": [0, 0, 0], "extinction": 0},
    {"density": 1, "color": [0.7, 0.9, 0.28], "extinction": 10.4},
    {"density": 2, "color": [0.35, 0.56, 0.7], "extinction": 11.2}]})";
constexpr std::size_t kVoxels = 16 * 16 * 16, kPixels = 8 * 32 * 32 * 4;

double relative_error(const std::vector<float>& a, const std::vector<float>& b) {
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    diff += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    norm += double(b[i]) * b[i];
  }
  return std::sqrt(diff / norm);
}

// The status and a message naming the function and `part`.
void expect_error(ivr_status got, ivr_status want, const char* function,
                  const std::string& part = "") {
  EXPECT_EQ(got, want) << ivr_status_string(got) << ": " << ivr_last_error();
  const std::string message = ivr_last_error();
  EXPECT_NE(message.find(function), std::string::npos) << message;
  EXPECT_NE(message.find(part), std::string::npos) << message << " (expected '" << part << "')";
}

class CApiReconstruct : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(ivr_context_create(nullptr, &ctx_), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_scene_from_json(ctx_, kScene, nullptr, &scene_), IVR_OK) << ivr_last_error();
    targets_.assign(kPixels, -1.0f);
    ASSERT_EQ(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, targets_.data(), targets_.size()),
              IVR_OK)
        << ivr_last_error();
    truth_.assign(kVoxels, -1.0f);
    const int64_t shape[3] = {16, 16, 16};
    ivr_volume* v = nullptr;
    ASSERT_EQ(ivr_volume_from_json(ctx_, R"({"synthetic": "shepp_logan", "dims": [16, 16, 16]})",
                                   nullptr, &v),
              IVR_OK);
    int64_t got[3] = {};
    ASSERT_EQ(ivr_volume_shape(v, got), IVR_OK);
    ASSERT_TRUE(std::equal(got, got + 3, shape));
    ASSERT_EQ(ivr_volume_data(v, truth_.data(), truth_.size()), IVR_OK);
    ASSERT_EQ(ivr_volume_release(v), IVR_OK);
  }
  void TearDown() override {
    if (scene_) EXPECT_EQ(ivr_scene_release(scene_), IVR_OK);
    if (ctx_) EXPECT_EQ(ivr_context_release(ctx_), IVR_OK);
  }
  // Density from a constant 0.5, `iterations` in total.
  ivr_reconstruct_options density_options(int iterations) {
    ivr_reconstruct_options o;
    EXPECT_EQ(ivr_reconstruct_options_init(&o), IVR_OK);
    o.iterations = iterations;
    o.init = IVR_INIT_CONSTANT;
    return o;
  }
  ivr_reconstruction* create(const ivr_reconstruct_options& o) {
    ivr_reconstruction* r = nullptr;
    EXPECT_EQ(ivr_reconstruction_create(ctx_, scene_, targets_.data(), targets_.size(), &o, &r),
              IVR_OK)
        << ivr_last_error();
    return r;
  }
  std::vector<float> volume(const ivr_reconstruction* r) {
    std::vector<float> v(kVoxels, NAN);
    int64_t shape[3] = {};
    EXPECT_EQ(ivr_reconstruction_volume(r, v.data(), v.size(), shape), IVR_OK) << ivr_last_error();
    EXPECT_EQ(shape[0] * shape[1] * shape[2], int64_t(kVoxels));
    return v;
  }
  ivr_context* ctx_ = nullptr;
  ivr_scene* scene_ = nullptr;
  std::vector<float> targets_, truth_;
};

TEST_F(CApiReconstruct, DensityStepRunVolumeAndTf) {
  ivr_reconstruct_options o;
  ASSERT_EQ(ivr_reconstruct_options_init(&o), IVR_OK);
  EXPECT_EQ(o.density, 1);
  EXPECT_EQ(o.tf, 0);
  EXPECT_EQ(o.iterations, 300);
  EXPECT_EQ(o.optimizer, IVR_OPTIMIZER_AUTO);
  EXPECT_EQ(o.lr, 0.0);
  EXPECT_EQ(o.init, IVR_INIT_SCENE);
  EXPECT_EQ(o.seed, 1u);
  ivr_reconstruction* r = create(density_options(30));
  ASSERT_NE(r, nullptr);

  ivr_reconstruct_info info{};
  ASSERT_EQ(ivr_reconstruction_info(r, &info), IVR_OK);
  EXPECT_EQ(info.iteration, 0);
  EXPECT_EQ(info.iterations, 30);
  EXPECT_EQ(info.levels, 3);  // 4³ → 8³ → 16³
  EXPECT_EQ(info.optimizer, IVR_OPTIMIZER_ADAM);
  EXPECT_GT(info.lr, 0);
  int64_t level_shape[3] = {};
  ASSERT_EQ(ivr_reconstruction_level_shape(r, 0, level_shape), IVR_OK);
  EXPECT_EQ(level_shape[0], 4);
  EXPECT_EQ(level_shape[2], 4);
  const std::vector<float> start = volume(r);
  for (float v : start) ASSERT_FLOAT_EQ(v, 0.5f);

  ivr_reconstruct_iteration first{};
  ASSERT_EQ(ivr_reconstruction_step(r, &first), IVR_OK) << ivr_last_error();
  EXPECT_EQ(first.iteration, 1);
  EXPECT_EQ(first.level, 0);
  EXPECT_EQ(first.views, 8);
  EXPECT_GT(first.loss, 0);
  EXPECT_EQ(first.lr, info.lr);
  ASSERT_EQ(ivr_reconstruction_step(r, nullptr), IVR_OK);  // the record is optional

  ivr_reconstruct_summary summary{};
  ASSERT_EQ(ivr_reconstruction_run(r, nullptr, nullptr, &summary), IVR_OK) << ivr_last_error();
  EXPECT_EQ(summary.iterations, 30);
  EXPECT_EQ(summary.steps, 28);
  EXPECT_STREQ(summary.stop_reason, "done");
  EXPECT_LT(summary.loss, 0.5 * first.loss);
  int done = 0;
  ASSERT_EQ(ivr_reconstruction_done(r, &done), IVR_OK);
  EXPECT_EQ(done, 1);

  size_t count = 0;
  ASSERT_EQ(ivr_reconstruction_history(r, nullptr, 0, &count), IVR_OK);
  ASSERT_EQ(count, 30u);
  std::vector<ivr_reconstruct_iteration> h(count);
  ASSERT_EQ(ivr_reconstruction_history(r, h.data(), h.size(), &count), IVR_OK);
  EXPECT_EQ(h.front().loss, first.loss);
  EXPECT_EQ(h.back().iteration, 30);
  EXPECT_EQ(h.back().level, 2);
  EXPECT_EQ(h.back().loss, summary.loss);

  const std::vector<float> got = volume(r);
  for (float v : got) ASSERT_TRUE(std::isfinite(v) && v >= 0);
  EXPECT_LT(relative_error(got, truth_), 0.9 * relative_error(start, truth_));

  // Density only: the TF is the scene's, 3 rows [r, g, b, extinction].
  int64_t tf_shape[2] = {};
  ASSERT_EQ(ivr_reconstruction_tf(r, nullptr, 0, tf_shape), IVR_OK);
  EXPECT_EQ(tf_shape[0], 3);
  EXPECT_EQ(tf_shape[1], 4);
  std::vector<double> tf(12);
  ASSERT_EQ(ivr_reconstruction_tf(r, tf.data(), tf.size(), nullptr), IVR_OK);
  EXPECT_EQ(tf[7], 8.0);
  EXPECT_EQ(tf[8], 0.5);

  // The result as a scene of the context renders like the volume it holds.
  ivr_scene* result = nullptr;
  ASSERT_EQ(ivr_reconstruction_result_scene(r, &result), IVR_OK) << ivr_last_error();
  std::vector<float> image(kPixels), from_volume(kPixels);
  ASSERT_EQ(ivr_render(ctx_, result, IVR_PRECISION_F32, 0, image.data(), image.size()), IVR_OK);
  const int64_t shape[3] = {16, 16, 16};
  ASSERT_EQ(ivr_scene_set_volume(result, got.data(), IVR_FLOAT32, shape), IVR_OK);
  ASSERT_EQ(ivr_render(ctx_, result, IVR_PRECISION_F32, 0, from_volume.data(), image.size()),
            IVR_OK);
  EXPECT_EQ(image, from_volume);
  double db = 0;
  ASSERT_EQ(ivr_psnr(image.data(), targets_.data(), image.size(), &db), IVR_OK);
  EXPECT_GT(db, 20);
  EXPECT_EQ(ivr_scene_release(result), IVR_OK);

  // Used and released after the scene and context it came from: it holds its own reference.
  EXPECT_EQ(ivr_scene_release(scene_), IVR_OK);
  EXPECT_EQ(ivr_context_release(ctx_), IVR_OK);
  scene_ = nullptr;
  ctx_ = nullptr;
  EXPECT_EQ(volume(r), got);
  EXPECT_EQ(ivr_reconstruction_release(r), IVR_OK);
  expect_error(ivr_reconstruction_step(r, nullptr), IVR_ERROR_INVALID_HANDLE,
               "ivr_reconstruction_step", "not a live ivr_reconstruction");
}

// Counts the calls and stops after the third.
int stop_after_three(const ivr_reconstruct_iteration* it, void* user) {
  static_cast<std::vector<ivr_reconstruct_iteration>*>(user)->push_back(*it);
  return it->iteration < 3;
}

TEST_F(CApiReconstruct, ProgressCallbackStopsAndALaterRunContinues) {
  ivr_reconstruction* r = create(density_options(6));
  std::vector<ivr_reconstruct_iteration> calls;
  ivr_reconstruct_summary s{};
  ASSERT_EQ(ivr_reconstruction_run(r, stop_after_three, &calls, &s), IVR_OK) << ivr_last_error();
  ASSERT_EQ(calls.size(), 3u);
  EXPECT_EQ(s.steps, 3);
  EXPECT_EQ(s.iterations, 3);
  EXPECT_STREQ(s.stop_reason, "interrupted");
  EXPECT_EQ(s.loss, calls.back().loss);
  int done = 1;
  ASSERT_EQ(ivr_reconstruction_done(r, &done), IVR_OK);
  EXPECT_EQ(done, 0);
  ASSERT_EQ(ivr_reconstruction_run(r, nullptr, nullptr, &s), IVR_OK);
  EXPECT_EQ(s.steps, 3);
  EXPECT_EQ(s.iterations, 6);
  EXPECT_STREQ(s.stop_reason, "done");
  expect_error(ivr_reconstruction_step(r, nullptr), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_reconstruction_step", "done");
  EXPECT_EQ(ivr_reconstruction_release(r), IVR_OK);
}

TEST_F(CApiReconstruct, ResumedRunEndsWhereTheUninterruptedOneDoes) {
  const std::string prefix = temp_dir("c_api_reconstruct") + "/run";
  const ivr_reconstruct_options o = density_options(20);
  ivr_reconstruction* a = create(o);
  for (int k = 0; k < 10; ++k) ASSERT_EQ(ivr_reconstruction_step(a, nullptr), IVR_OK);
  ASSERT_EQ(ivr_reconstruction_save_checkpoint(a, prefix.c_str()), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_reconstruction_run(a, nullptr, nullptr, nullptr), IVR_OK);
  std::vector<ivr_reconstruct_iteration> ha(20);
  ASSERT_EQ(ivr_reconstruction_history(a, ha.data(), ha.size(), nullptr), IVR_OK);

  ivr_reconstruction* b = create(o);
  ASSERT_EQ(ivr_reconstruction_resume(b, prefix.c_str()), IVR_OK) << ivr_last_error();
  ivr_reconstruct_info info{};
  ASSERT_EQ(ivr_reconstruction_info(b, &info), IVR_OK);
  EXPECT_EQ(info.iteration, 10);
  size_t count = 0;
  std::vector<ivr_reconstruct_iteration> hb(20);
  ASSERT_EQ(ivr_reconstruction_history(b, hb.data(), hb.size(), &count), IVR_OK);
  EXPECT_EQ(count, 10u);
  for (int k = 0; k < 10; ++k) EXPECT_EQ(hb[k].loss, ha[k].loss) << "iteration " << k + 1;
  ivr_reconstruct_summary s{};
  ASSERT_EQ(ivr_reconstruction_run(b, nullptr, nullptr, &s), IVR_OK) << ivr_last_error();
  EXPECT_EQ(s.iterations, 20);
  EXPECT_EQ(s.steps, 10);
  // The adjoint's float atomics sum in thread order: close, not necessarily bit-equal.
  const std::vector<float> va = volume(a), vb = volume(b);
  EXPECT_LT(relative_error(vb, va), 1e-3);
  EXPECT_NEAR(s.loss, ha[19].loss, 1e-3 * ha[19].loss);

  // A checkpoint of other options is refused, naming the option.
  ivr_reconstruct_options other = o;
  other.seed = 2;
  ivr_reconstruction* c = create(other);
  expect_error(ivr_reconstruction_resume(c, prefix.c_str()), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_reconstruction_resume", "seed");
  expect_error(ivr_reconstruction_resume(c, (prefix + "_missing").c_str()), IVR_ERROR_IO,
               "ivr_reconstruction_resume");
  for (ivr_reconstruction* r : {a, b, c}) EXPECT_EQ(ivr_reconstruction_release(r), IVR_OK);
}

TEST_F(CApiReconstruct, TfAloneWithLbfgsLowersTheLoss) {
  ivr_transfer_function* wrong = nullptr;
  ASSERT_EQ(ivr_tf_from_json(ctx_, kWrongTf, &wrong), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_scene_set_tf(scene_, wrong), IVR_OK);
  ASSERT_EQ(ivr_tf_release(wrong), IVR_OK);
  ivr_reconstruct_options o;
  ASSERT_EQ(ivr_reconstruct_options_init(&o), IVR_OK);
  o.density = 0;
  o.tf = 1;
  o.iterations = 8;
  ivr_reconstruction* r = create(o);
  ivr_reconstruct_info info{};
  ASSERT_EQ(ivr_reconstruction_info(r, &info), IVR_OK);
  EXPECT_EQ(info.optimizer, IVR_OPTIMIZER_LBFGS);
  EXPECT_EQ(info.levels, 1);
  ivr_reconstruct_summary s{};
  ASSERT_EQ(ivr_reconstruction_run(r, nullptr, nullptr, &s), IVR_OK) << ivr_last_error();
  std::vector<ivr_reconstruct_iteration> h(8);
  ASSERT_EQ(ivr_reconstruction_history(r, h.data(), h.size(), nullptr), IVR_OK);
  EXPECT_LT(h.back().loss, 0.2 * h.front().loss);
  int64_t shape[2] = {};
  std::vector<double> tf(12, NAN);
  ASSERT_EQ(ivr_reconstruction_tf(r, tf.data(), tf.size(), shape), IVR_OK);
  EXPECT_EQ(shape[0], 3);
  EXPECT_EQ(shape[1], 4);
  EXPECT_NE(tf[7], 10.4);  // the extinction at density 1 moved
  // The volume is the scene's own, untouched.
  EXPECT_EQ(volume(r), truth_);
  std::vector<double> small(4);
  expect_error(ivr_reconstruction_tf(r, small.data(), small.size(), nullptr),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_reconstruction_tf", "12 parameters");
  EXPECT_EQ(ivr_reconstruction_release(r), IVR_OK);
}

TEST_F(CApiReconstruct, ErrorsHaveAStatusAndAMessage) {
  const ivr_reconstruct_options o = density_options(5);
  ivr_reconstruction* r = nullptr;
  const auto create_with = [&](const ivr_reconstruct_options& opt, size_t count) {
    return ivr_reconstruction_create(ctx_, scene_, targets_.data(), count, &opt, &r);
  };
  expect_error(ivr_reconstruction_create(nullptr, scene_, targets_.data(), kPixels, &o, &r),
               IVR_ERROR_NULL_POINTER, "ivr_reconstruction_create", "context is NULL");
  expect_error(ivr_reconstruction_create(ctx_, nullptr, targets_.data(), kPixels, &o, &r),
               IVR_ERROR_NULL_POINTER, "ivr_reconstruction_create", "scene is NULL");
  expect_error(ivr_reconstruction_create(ctx_, scene_, nullptr, kPixels, &o, &r),
               IVR_ERROR_NULL_POINTER, "ivr_reconstruction_create", "targets is NULL");
  expect_error(ivr_reconstruction_create(ctx_, scene_, targets_.data(), kPixels, &o, nullptr),
               IVR_ERROR_NULL_POINTER, "ivr_reconstruction_create", "reconstruction is NULL");
  expect_error(create_with(o, kPixels - 4), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "the scene renders 32768 (8 views of 32 x 32 x 4)");
  EXPECT_EQ(r, nullptr);
  ivr_reconstruct_options bad = o;
  bad.lr = -0.1;
  expect_error(create_with(bad, kPixels), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "lr must be > 0");
  bad = o;
  bad.optimizer = IVR_OPTIMIZER_LBFGS;
  expect_error(create_with(bad, kPixels), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "lbfgs is for small parameter sets");
  bad = o;
  bad.density = 0;
  expect_error(create_with(bad, kPixels), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "nothing to optimise");
  bad = o;
  bad.optimizer = ivr_optimizer(9);
  expect_error(create_with(bad, kPixels), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "options.optimizer 9 is unknown (IVR_OPTIMIZER_AUTO,");
  bad = o;
  bad.iterations = 0;
  expect_error(create_with(bad, kPixels), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "iterations must be >= 1");
  bad = o;
  bad.schedule = ivr_schedule(5);
  expect_error(create_with(bad, kPixels), IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "options.schedule 5 is unknown (IVR_SCHEDULE_CONSTANT,");
  std::vector<float> nan_targets = targets_;
  nan_targets[17] = NAN;
  expect_error(ivr_reconstruction_create(ctx_, scene_, nan_targets.data(), kPixels, &o, &r),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_reconstruction_create",
               "target element 17 is not finite");
  EXPECT_EQ(r, nullptr);
  EXPECT_NE(std::string(ivr_context_last_error(ctx_)).find("ivr_reconstruction_create"),
            std::string::npos);

  ivr_context* other = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &other), IVR_OK);
  expect_error(ivr_reconstruction_create(other, scene_, targets_.data(), kPixels, &o, &r),
               IVR_ERROR_WRONG_CONTEXT, "ivr_reconstruction_create", "another context");
  EXPECT_EQ(ivr_context_release(other), IVR_OK);

  // Handles: NULL, and a pointer that never was one.
  expect_error(ivr_reconstruction_step(nullptr, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_reconstruction_step", "reconstruction is NULL");
  expect_error(ivr_reconstruction_run(nullptr, nullptr, nullptr, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_reconstruction_run");
  expect_error(ivr_reconstruction_release(nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_reconstruction_release");
  auto* fake = reinterpret_cast<ivr_reconstruction*>(scene_);
  expect_error(ivr_reconstruction_done(fake, nullptr), IVR_ERROR_INVALID_HANDLE,
               "ivr_reconstruction_done", "not a live ivr_reconstruction");

  ASSERT_EQ(create_with(o, kPixels), IVR_OK) << ivr_last_error();
  int done = 0;
  expect_error(ivr_reconstruction_done(r, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_reconstruction_done", "done is NULL");
  EXPECT_EQ(ivr_reconstruction_done(r, &done), IVR_OK);
  std::vector<float> small(10);
  expect_error(ivr_reconstruction_volume(r, small.data(), small.size(), nullptr),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_reconstruction_volume", "4096 voxels");
  expect_error(ivr_reconstruction_volume(r, nullptr, 0, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_reconstruction_volume", "shape is NULL");
  int64_t shape[3] = {};
  EXPECT_EQ(ivr_reconstruction_volume(r, nullptr, 0, shape), IVR_OK);  // the shape alone
  EXPECT_EQ(shape[0], 16);
  expect_error(ivr_reconstruction_level_shape(r, 3, shape), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_reconstruction_level_shape", "level 3 does not exist");
  expect_error(ivr_reconstruction_save_checkpoint(r, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_reconstruction_save_checkpoint", "prefix is NULL");
  expect_error(ivr_reconstruction_save_checkpoint(r, "/nonexistent-ivr-folder/run"), IVR_ERROR_IO,
               "ivr_reconstruction_save_checkpoint");
  EXPECT_EQ(ivr_reconstruction_retain(r), IVR_OK);
  EXPECT_EQ(ivr_reconstruction_release(r), IVR_OK);
  EXPECT_EQ(ivr_reconstruction_info(r, nullptr), IVR_ERROR_NULL_POINTER);  // still live
  EXPECT_EQ(ivr_reconstruction_release(r), IVR_OK);

  double value = 0;
  expect_error(ivr_psnr(targets_.data(), targets_.data(), 0, &value), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_psnr", "count is 0");
  const int64_t bad_shape[4] = {1, 0, 32, 4};
  expect_error(ivr_image_entropy(targets_.data(), bad_shape, 1, &value), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_image_entropy", "shape[1] = 0");
}

int count_steps(const ivr_viewpoint_step*, void* user) {
  ++*static_cast<int*>(user);
  return 1;
}

TEST_F(CApiReconstruct, ViewpointRaisesTheEntropyOnTheOrbit) {
  ivr_viewpoint_options o;
  ASSERT_EQ(ivr_viewpoint_options_init(&o), IVR_OK);
  EXPECT_EQ(o.iterations, 40);
  EXPECT_EQ(o.optimizer, IVR_OPTIMIZER_AUTO);
  o.iterations = 6;
  o.view = 2;
  std::vector<ivr_viewpoint_step> history(7);
  ivr_viewpoint_result result{};
  int calls = 0;
  ASSERT_EQ(ivr_select_viewpoint(ctx_, scene_, &o, count_steps, &calls, history.data(),
                                 history.size(), &result),
            IVR_OK)
      << ivr_last_error();
  EXPECT_EQ(calls, 7);
  EXPECT_EQ(result.iterations, 6);
  EXPECT_EQ(history[0].iteration, 0);
  EXPECT_EQ(history[0].entropy, result.entropy_start);
  EXPECT_GE(result.entropy_best, result.entropy_start);
  EXPECT_GT(result.entropy_start, 0);
  EXPECT_LE(result.entropy_best, 1);
  for (const ivr_viewpoint_step& s : history) EXPECT_LE(s.entropy, result.entropy_best);
  EXPECT_EQ(result.camera.width, 32);
  EXPECT_EQ(result.camera.height, 32);
  EXPECT_EQ(result.camera.orthographic, 0);
  EXPECT_EQ(result.camera.fov_y, 40);
  double r2 = 0;
  for (int i = 0; i < 3; ++i)
    r2 += (result.camera.eye[i] - result.camera.target[i]) *
          (result.camera.eye[i] - result.camera.target[i]);
  EXPECT_NEAR(std::sqrt(r2), 2.2, 1e-9);

  // The entropy it reports is ivr_image_entropy's of view 0 of the camera's image.
  std::vector<float> image(kPixels);
  ASSERT_EQ(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, image.data(), image.size()), IVR_OK);
  const int64_t one_view[4] = {1, 32, 32, 4};
  double h = 0;
  ASSERT_EQ(ivr_image_entropy(image.data() + 2 * 32 * 32 * 4, one_view, 1, &h), IVR_OK);
  EXPECT_NEAR(h, result.entropy_start, 1e-6);

  o.view = 8;
  expect_error(ivr_select_viewpoint(ctx_, scene_, &o, nullptr, nullptr, nullptr, 0, &result),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_select_viewpoint", "view 8 does not exist");
  o.view = 0;
  expect_error(ivr_select_viewpoint(ctx_, scene_, &o, nullptr, nullptr, history.data(), 3, &result),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_select_viewpoint", "history holds 3");
  o.lr = -1;
  expect_error(ivr_select_viewpoint(ctx_, scene_, &o, nullptr, nullptr, nullptr, 0, &result),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_select_viewpoint", "lr");
  expect_error(ivr_select_viewpoint(ctx_, scene_, nullptr, nullptr, nullptr, nullptr, 0, nullptr),
               IVR_ERROR_NULL_POINTER, "ivr_select_viewpoint", "result is NULL");
}

TEST_F(CApiReconstruct, CppWrappers) {
  api::Context context;
  api::Scene scene = context.scene_from_json(kScene);
  const api::Array<float> targets = context.render(scene);
  api::ReconstructOptions o;
  o.iterations = 8;
  o.init = IVR_INIT_CONSTANT;
  api::Reconstruction r(context, scene, targets.values, o);
  EXPECT_EQ(r.info().optimizer, IVR_OPTIMIZER_ADAM);
  EXPECT_EQ(r.level_shape(1), (std::vector<int64_t>{8, 8, 8}));
  const ivr_reconstruct_iteration first = r.step();
  EXPECT_EQ(first.iteration, 1);
  int calls = 0;
  const api::ReconstructSummary s = r.run([&](const ivr_reconstruct_iteration& it) {
    ++calls;
    return it.iteration < 4;
  });
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(s.stop_reason, "interrupted");
  EXPECT_FALSE(r.done());
  // An exception in the callback stops the run and reaches the caller.
  EXPECT_THROW(r.run([](const ivr_reconstruct_iteration&) -> bool { throw std::logic_error("x"); }),
               std::logic_error);
  EXPECT_EQ(r.info().iteration, 5);
  EXPECT_EQ(r.run().stop_reason, "done");
  EXPECT_TRUE(r.done());
  EXPECT_EQ(r.history().size(), 8u);
  EXPECT_LT(r.history().back().loss, first.loss);
  const api::Array<float> v = r.volume();
  EXPECT_EQ(v.shape, (std::vector<int64_t>{16, 16, 16}));
  EXPECT_EQ(r.tf().shape, (std::vector<int64_t>{3, 4}));
  const api::Array<float> image = context.render(r.result_scene());
  EXPECT_GT(api::psnr(image.values, targets.values), 15);
  EXPECT_EQ(api::psnr(targets.values, targets.values), INFINITY);
  try {
    r.step();
    ADD_FAILURE() << "step after done did not throw";
  } catch (const api::Exception& e) {
    EXPECT_EQ(e.status(), IVR_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(e.what()).find("done"), std::string::npos) << e.what();
  }
  api::ReconstructOptions bad = o;
  bad.lr = -1;
  EXPECT_THROW(api::Reconstruction(context, scene, targets.values, bad), api::Exception);

  api::ViewpointOptions vo;
  vo.iterations = 3;
  const api::ViewpointResult best = api::select_viewpoint(context, scene, vo);
  EXPECT_EQ(best.history.size(), 4u);
  EXPECT_GE(best.entropy_best, best.entropy_start);
  const api::Array<float> view0{{1, 32, 32, 4},
                                {targets.values.begin(), targets.values.begin() + 32 * 32 * 4}};
  EXPECT_NEAR(api::image_entropy(view0), best.entropy_start, 1e-6);
}

}  // namespace
}  // namespace ivr::test
