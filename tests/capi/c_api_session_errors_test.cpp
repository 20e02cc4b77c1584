// c_api_session_errors_test.cpp — C API sessions: bad input gives its status and changes nothing.
#include <gtest/gtest.h>

#include <limits>

#include "capi/c_api_session_support.hpp"

namespace ivr::test {
namespace {

// --- helpers for bad input -----------------------------------------------------------------------

// The loss against the session's own target (a cheap forward-mode gradient), to see which
// target is in place; -1 where the call fails.
double target_loss(ivr_session* s) {
  ivr_array* loss = nullptr;
  ivr_array* group = nullptr;
  EXPECT_EQ(ivr_session_gradient(s, nullptr, "background", IVR_MODE_FORWARD, IVR_LOSS_MSE, 0, &loss,
                                 &group, 1, nullptr, nullptr),
            IVR_OK)
      << ivr_last_error();
  const ArrayPtr a(loss), b(group);
  return loss ? doubles(loss).at(0) : -1.0;
}

// The status, and a one-line message naming the function and `words`, for this thread and (when
// the handle's context is known) for the context.
void expect_error(ivr_status got, ivr_status want, const char* function, const std::string& words,
                  ivr_context* ctx = nullptr) {
  EXPECT_EQ(got, want) << ivr_status_string(got) << ": " << ivr_last_error();
  const std::string message = ivr_last_error();
  EXPECT_TRUE(has(message, function)) << message;
  EXPECT_TRUE(has(message, words)) << "wanted '" << words << "' in: " << message;
  EXPECT_FALSE(has(message, "\n")) << message;
  if (ctx) EXPECT_EQ(std::string(ivr_context_last_error(ctx)), message);
}

// What a failed setter must leave as it was: the render (bit for bit) and both shapes.
struct SessionState {
  std::vector<float> image;
  std::vector<int64_t> image_shape, volume_shape;
};
SessionState state_of(ivr_session* s) {
  return {session_render(s), image_shape(s), volume_shape(s)};
}
void expect_unchanged(ivr_session* s, const SessionState& before, const std::string& after) {
  EXPECT_EQ(image_shape(s), before.image_shape) << "after " << after;
  EXPECT_EQ(volume_shape(s), before.volume_shape) << "after " << after;
  EXPECT_TRUE(session_render(s) == before.image) << "the render changed after " << after;
}

// --- bad input -----------------------------------------------------------------------------------

TEST_F(CApiSession, BadVolumesAreRefusedAndLeaveTheSessionAsItWas) {
  const SessionState before = state_of(session_);
  const char* f = "ivr_session_set_volume";
  const int64_t zero[3] = {16, 0, 20}, negative[3] = {-16, 18, 20};
  expect_error(ivr_session_set_volume(session_, volume_.data(), IVR_FLOAT32, zero),
               IVR_ERROR_INVALID_ARGUMENT, f, "(16, 0, 20)", ctx_);
  expect_error(ivr_session_set_volume(session_, volume_.data(), IVR_FLOAT64, negative),
               IVR_ERROR_INVALID_ARGUMENT, f, "(-16, 18, 20)", ctx_);
  expect_error(ivr_session_set_volume(session_, volume_.data(), IVR_UINT8, zero),
               IVR_ERROR_INVALID_ARGUMENT, f, "(16, 0, 20)", ctx_);
  expect_error(ivr_session_set_volume(session_, volume_.data(), static_cast<ivr_dtype>(9), kShape),
               IVR_ERROR_INVALID_ARGUMENT, f, "unknown dtype 9", ctx_);
  expect_error(ivr_session_set_volume(session_, nullptr, IVR_FLOAT32, kShape),
               IVR_ERROR_NULL_POINTER, f, "data is NULL", ctx_);
  expect_error(ivr_session_set_volume(session_, volume_.data(), IVR_FLOAT32, nullptr),
               IVR_ERROR_NULL_POINTER, f, "shape is NULL", ctx_);
  expect_unchanged(session_, before, "bad shapes and dtypes");

  // Bad values are named by the voxel's (x, y, z); the first one when there are several.
  std::vector<float> bad(volume_);
  bad[(7 * 18 + 5) * 20 + 3] = std::numeric_limits<float>::quiet_NaN();
  bad[kVoxels - 1] = -1.f;
  expect_error(ivr_session_set_volume(session_, bad.data(), IVR_FLOAT32, kShape),
               IVR_ERROR_INVALID_ARGUMENT, f, "(x, y, z) = (3, 5, 7) is nan", ctx_);
  bad = volume_;
  bad[kVoxels - 1] = std::numeric_limits<float>::infinity();
  expect_error(ivr_session_set_volume(session_, bad.data(), IVR_FLOAT32, kShape),
               IVR_ERROR_INVALID_ARGUMENT, f, "(x, y, z) = (19, 17, 15) is inf", ctx_);
  bad = volume_;
  bad[0] = -0.25f;
  expect_error(ivr_session_set_volume(session_, bad.data(), IVR_FLOAT32, kShape),
               IVR_ERROR_INVALID_ARGUMENT, f, "(x, y, z) = (0, 0, 0) is -0.25", ctx_);
  // float64 data, and a new shape: the coordinates are those of the new grid.
  std::vector<double> bad64(volume_.begin(), volume_.end());
  bad64[(2 * 20 + 4) * 18 + 6] = -std::numeric_limits<double>::infinity();
  const int64_t other[3] = {16, 20, 18};
  expect_error(ivr_session_set_volume(session_, bad64.data(), IVR_FLOAT64, other),
               IVR_ERROR_INVALID_ARGUMENT, f, "(x, y, z) = (6, 4, 2) is -inf", ctx_);
  expect_unchanged(session_, before, "bad densities");

  // From device arrays: a rank-2 one, one with a NaN, one of another context, a released one.
  const char* fa = "ivr_session_set_volume_array";
  const ArrayPtr flat = make_array(ctx_, {16, 360}, volume_);
  expect_error(ivr_session_set_volume_array(session_, flat.get()), IVR_ERROR_INVALID_ARGUMENT, fa,
               "(16, 360)", ctx_);
  bad = volume_;
  bad[(1 * 18 + 2) * 20 + 3] = std::numeric_limits<float>::quiet_NaN();
  const ArrayPtr nan_array = make_array(ctx_, {16, 18, 20}, bad);
  expect_error(ivr_session_set_volume_array(session_, nan_array.get()), IVR_ERROR_INVALID_ARGUMENT,
               fa, "(x, y, z) = (3, 2, 1) is nan", ctx_);
  ivr_context* other_ctx = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &other_ctx), IVR_OK);
  const ArrayPtr foreign = make_array(other_ctx, {16, 18, 20}, volume_);
  EXPECT_EQ(ivr_context_release(other_ctx), IVR_OK);  // the array holds it
  expect_error(ivr_session_set_volume_array(session_, foreign.get()), IVR_ERROR_WRONG_CONTEXT, fa,
               "another context", ctx_);
  ivr_array* released = make_array(ctx_, {16, 18, 20}, volume_).release();
  ASSERT_EQ(ivr_array_release(released), IVR_OK);
  expect_error(ivr_session_set_volume_array(session_, released), IVR_ERROR_INVALID_HANDLE, fa,
               "not a live ivr_array", ctx_);
  expect_error(ivr_session_set_volume_array(session_, nullptr), IVR_ERROR_NULL_POINTER, fa,
               "densities is NULL", ctx_);
  expect_unchanged(session_, before, "bad density arrays");
}

TEST_F(CApiSession, BadTargetsAreRefusedAndTheOldTargetStays) {
  const std::vector<float> target = perturbed_target();
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  const double loss = target_loss(session_);
  const SessionState before = state_of(session_);
  const char* f = "ivr_session_set_target";
  expect_error(ivr_session_set_target(session_, target.data(), target.size() - 1),
               IVR_ERROR_INVALID_ARGUMENT, f, "2559 floats; the session renders 2560", ctx_);
  std::vector<float> bad(target);
  bad[77] = std::numeric_limits<float>::quiet_NaN();
  expect_error(ivr_session_set_target(session_, bad.data(), bad.size()), IVR_ERROR_INVALID_ARGUMENT,
               f, "target element 77 is not finite", ctx_);
  expect_error(ivr_session_set_target(session_, nullptr, target.size()), IVR_ERROR_NULL_POINTER, f,
               "target is NULL", ctx_);
  const char* fa = "ivr_session_set_target_array";
  const ArrayPtr wrong = make_array(ctx_, {2, 20, 16, 4}, target);
  expect_error(ivr_session_set_target_array(session_, wrong.get()), IVR_ERROR_INVALID_ARGUMENT, fa,
               "(2, 20, 16, 4)", ctx_);
  bad[77] = 0.f;
  bad[1234] = -std::numeric_limits<float>::infinity();
  const ArrayPtr inf_array = make_array(ctx_, {2, 16, 20, 4}, bad);
  expect_error(ivr_session_set_target_array(session_, inf_array.get()), IVR_ERROR_INVALID_ARGUMENT,
               fa, "target element 1234 is not finite", ctx_);
  EXPECT_EQ(target_loss(session_), loss);
  expect_unchanged(session_, before, "bad targets");
  // Negative targets are fine (only the render is >= 0).
  bad[1234] = -0.5f;
  const ArrayPtr negative = make_array(ctx_, {2, 16, 20, 4}, bad);
  EXPECT_EQ(ivr_session_set_target_array(session_, negative.get()), IVR_OK) << ivr_last_error();
  EXPECT_NE(target_loss(session_), loss);
}

TEST_F(CApiSession, BadCamerasIntegratorsAndBackgroundsAreRefused) {
  const std::vector<float> target = perturbed_target();
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  const double loss = target_loss(session_);
  const SessionState before = state_of(session_);
  const char* fj = "ivr_session_set_cameras_json";
  expect_error(ivr_session_set_cameras_json(session_, "[{\"eye\": [0, 0, 2]"), IVR_ERROR_IO, fj,
               "malformed JSON", ctx_);
  expect_error(
      ivr_session_set_cameras_json(session_, R"([{"eye": [0.5, 0.5, 0.5], "target": [0.5, 0.5, 0.5],
                                  "width": 20, "height": 16}])"),
      IVR_ERROR_INVALID_ARGUMENT, fj, "eye equals target", ctx_);
  expect_error(ivr_session_set_cameras_json(session_, "[]"), IVR_ERROR_INVALID_ARGUMENT, fj,
               "at least one camera", ctx_);
  expect_error(ivr_session_set_cameras_json(session_, R"([{"eye": [0, 0, 2], "width": 8},
                                                          {"eye": [0, 2, 0.1], "width": 9}])"),
               IVR_ERROR_INVALID_ARGUMENT, fj, "share width and height", ctx_);
  expect_error(ivr_session_set_cameras_json(session_, R"([{"eye": [0, 0, 2], "zoom": 2}])"),
               IVR_ERROR_INVALID_ARGUMENT, fj, "zoom", ctx_);
  expect_error(ivr_session_set_cameras_json(session_, nullptr), IVR_ERROR_NULL_POINTER, fj,
               "json is NULL", ctx_);
  const char* fc = "ivr_session_set_cameras";
  ivr_camera cam = {};
  cam.eye[2] = 2;
  cam.up[1] = 1;
  cam.fov_y = 40;
  cam.width = 20;
  cam.height = 16;
  expect_error(ivr_session_set_cameras(session_, &cam, 0), IVR_ERROR_INVALID_ARGUMENT, fc,
               "count is 0", ctx_);
  expect_error(ivr_session_set_cameras(session_, nullptr, 1), IVR_ERROR_NULL_POINTER, fc,
               "cameras is NULL", ctx_);
  cam.up[1] = 0;
  cam.up[2] = 1;  // parallel to the view direction
  expect_error(ivr_session_set_cameras(session_, &cam, 1), IVR_ERROR_INVALID_ARGUMENT, fc,
               "up is parallel", ctx_);
  cam.up[2] = 0;
  cam.up[1] = 1;
  cam.width = 0;
  expect_error(ivr_session_set_cameras(session_, &cam, 1), IVR_ERROR_INVALID_ARGUMENT, fc,
               "cameras[0]", ctx_);
  const char* fi = "ivr_session_set_integrator_json";
  expect_error(ivr_session_set_integrator_json(session_, R"({"scheme": "midpoint", "step": 0})"),
               IVR_ERROR_INVALID_ARGUMENT, fi, "integrator.step", ctx_);
  expect_error(ivr_session_set_integrator_json(session_, R"({"scheme": "simpson"})"),
               IVR_ERROR_INVALID_ARGUMENT, fi, "simpson", ctx_);
  expect_error(
      ivr_session_set_integrator_json(session_, R"({"step": 0.5, "min_transmittance": 1})"),
      IVR_ERROR_INVALID_ARGUMENT, fi, "min_transmittance", ctx_);
  expect_error(ivr_session_set_integrator_json(session_, "{"), IVR_ERROR_IO, fi, "malformed JSON",
               ctx_);
  const char* fb = "ivr_session_set_background";
  const double nan_background[3] = {0.1, std::nan(""), 0.3};
  expect_error(ivr_session_set_background(session_, nan_background), IVR_ERROR_INVALID_ARGUMENT, fb,
               "finite", ctx_);
  expect_error(ivr_session_set_background(session_, nullptr), IVR_ERROR_NULL_POINTER, fb,
               "background is NULL", ctx_);
  expect_unchanged(session_, before, "bad cameras, integrators and backgrounds");
  // The target stays too (cameras of a new image size would have dropped it).
  EXPECT_EQ(target_loss(session_), loss);
}

TEST_F(CApiSession, ForeignReleasedAndWrongKindsOfHandles) {
  const SessionState before = state_of(session_);
  ivr_context* other = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &other), IVR_OK);
  // A TF, arrays and an optimizer of another context.
  ivr_transfer_function* tf = nullptr;
  ASSERT_EQ(ivr_tf_from_json(other, kGaussianTf, &tf), IVR_OK);
  expect_error(ivr_session_set_tf(session_, tf), IVR_ERROR_WRONG_CONTEXT, "ivr_session_set_tf",
               "tf belongs to another context", ctx_);
  EXPECT_EQ(ivr_tf_release(tf), IVR_OK);
  const std::vector<float> target = perturbed_target();
  const ArrayPtr foreign_target = make_array(other, {2, 16, 20, 4}, target);
  expect_error(ivr_session_set_target_array(session_, foreign_target.get()),
               IVR_ERROR_WRONG_CONTEXT, "ivr_session_set_target_array", "another context", ctx_);
  ivr_array* loss = nullptr;
  ivr_array* groups[1] = {};
  expect_error(ivr_session_gradient(session_, foreign_target.get(), "density", IVR_MODE_AUTO,
                                    IVR_LOSS_MSE, 0, &loss, groups, 1, nullptr, nullptr),
               IVR_ERROR_WRONG_CONTEXT, "ivr_session_gradient", "target belongs to another context",
               ctx_);
  EXPECT_EQ(loss, nullptr);
  const ArrayPtr foreign_volume = make_array(other, {16, 18, 20}, volume_);
  ivr_array* out = nullptr;
  expect_error(ivr_session_project(session_, foreign_volume.get(), &out), IVR_ERROR_WRONG_CONTEXT,
               "ivr_session_project", "another context", ctx_);
  const ArrayPtr foreign_lines =
      make_array(other, {2, 16, 20, 1}, std::vector<float>(2 * 16 * 20, 1.f));
  expect_error(ivr_session_backproject(session_, foreign_lines.get(), &out),
               IVR_ERROR_WRONG_CONTEXT, "ivr_session_backproject", "another context", ctx_);
  const ArrayPtr image = render_array(session_);
  expect_error(ivr_session_loss(session_, image.get(), foreign_target.get(), IVR_LOSS_MSE, &out),
               IVR_ERROR_WRONG_CONTEXT, "ivr_session_loss", "another context", ctx_);
  EXPECT_EQ(out, nullptr);
  ivr_scene* other_scene = nullptr;
  ASSERT_EQ(ivr_scene_from_json(other, SceneParts{}.json().c_str(), nullptr, &other_scene), IVR_OK);
  ASSERT_EQ(ivr_scene_set_volume(other_scene, volume_.data(), IVR_FLOAT32, kShape), IVR_OK);
  ivr_session* other_session = nullptr;
  expect_error(ivr_session_create(ctx_, other_scene, nullptr, &other_session),
               IVR_ERROR_WRONG_CONTEXT, "ivr_session_create", "another context", ctx_);
  ASSERT_EQ(ivr_session_create(other, other_scene, nullptr, &other_session), IVR_OK);
  ivr_density_optimizer* foreign_adam = nullptr;
  ASSERT_EQ(ivr_density_optimizer_create(other_session, IVR_OPTIMIZER_ADAM, 0.01, &foreign_adam),
            IVR_OK);
  const ArrayPtr zeros = make_array(ctx_, {16, 18, 20}, std::vector<float>(kVoxels, 0.f));
  expect_error(ivr_session_step(session_, foreign_adam, zeros.get()), IVR_ERROR_WRONG_CONTEXT,
               "ivr_session_step", "optimizer belongs to another context", ctx_);
  EXPECT_EQ(ivr_density_optimizer_release(foreign_adam), IVR_OK);
  EXPECT_EQ(ivr_session_release(other_session), IVR_OK);
  EXPECT_EQ(ivr_scene_release(other_scene), IVR_OK);
  EXPECT_EQ(ivr_context_release(other), IVR_OK);

  // Released sessions and arrays, and handles of another kind.
  ivr_session* s = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, &s), IVR_OK);
  ASSERT_EQ(ivr_session_retain(s), IVR_OK);
  ASSERT_EQ(ivr_session_release(s), IVR_OK);  // one reference left
  EXPECT_EQ(image_shape(s), (std::vector<int64_t>{2, 16, 20, 4}));
  ivr_array* last_image = nullptr;
  ivr_array* last_view = nullptr;
  ASSERT_EQ(ivr_session_render(s, &last_image), IVR_OK);
  ASSERT_EQ(ivr_session_volume(s, &last_view), IVR_OK);
  ASSERT_EQ(ivr_session_release(s), IVR_OK);  // gone
  // Its arrays outlive it, values and all.
  const ArrayPtr held_image(last_image), held_view(last_view);
  EXPECT_TRUE(floats(last_image) == before.image);
  EXPECT_EQ(floats(last_view), volume_);
  expect_error(ivr_session_render(s, &out), IVR_ERROR_INVALID_HANDLE, "ivr_session_render",
               "not a live ivr_session");
  EXPECT_EQ(out, nullptr);
  const double background[3] = {0, 0, 0};
  expect_error(ivr_session_set_background(s, background), IVR_ERROR_INVALID_HANDLE,
               "ivr_session_set_background", "not a live ivr_session");
  expect_error(ivr_session_release(s), IVR_ERROR_INVALID_HANDLE, "ivr_session_release",
               "not a live ivr_session");
  ivr_array* a = make_array(ctx_, {4}, std::vector<float>(4, 1.f)).release();
  ASSERT_EQ(ivr_array_release(a), IVR_OK);
  float values[4];
  expect_error(ivr_array_download(a, values, IVR_FLOAT32, 4), IVR_ERROR_INVALID_HANDLE,
               "ivr_array_download", "not a live ivr_array");
  expect_error(ivr_array_release(a), IVR_ERROR_INVALID_HANDLE, "ivr_array_release",
               "not a live ivr_array");
  expect_error(ivr_session_render(reinterpret_cast<ivr_session*>(scene_), &out),
               IVR_ERROR_INVALID_HANDLE, "ivr_session_render", "not a live ivr_session");
  expect_error(ivr_session_set_target_array(session_, reinterpret_cast<const ivr_array*>(session_)),
               IVR_ERROR_INVALID_HANDLE, "ivr_session_set_target_array", "not a live ivr_array",
               ctx_);
  expect_error(
      ivr_session_step(session_, reinterpret_cast<ivr_density_optimizer*>(session_), zeros.get()),
      IVR_ERROR_INVALID_HANDLE, "ivr_session_step", "not a live ivr_density_optimizer", ctx_);
  expect_error(ivr_session_render(nullptr, &out), IVR_ERROR_NULL_POINTER, "ivr_session_render",
               "session is NULL");
  expect_error(ivr_session_render(session_, nullptr), IVR_ERROR_NULL_POINTER, "ivr_session_render",
               "image is NULL", ctx_);
  expect_error(ivr_session_create(ctx_, nullptr, nullptr, &s), IVR_ERROR_NULL_POINTER,
               "ivr_session_create", "scene is NULL", ctx_);
  ivr_session_options bad_options;
  ASSERT_EQ(ivr_session_options_init(&bad_options), IVR_OK);
  bad_options.empty_space = 3;
  expect_error(ivr_session_create(ctx_, scene_, &bad_options, &s), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_session_create", "options.empty_space", ctx_);
  expect_unchanged(session_, before, "foreign and released handles");

  // A session keeps its context alive.
  ivr_context* c = nullptr;
  ivr_scene* sc = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &c), IVR_OK);
  ASSERT_EQ(ivr_scene_from_json(c, SceneParts{}.json().c_str(), nullptr, &sc), IVR_OK);
  ASSERT_EQ(ivr_scene_set_volume(sc, volume_.data(), IVR_FLOAT32, kShape), IVR_OK);
  ASSERT_EQ(ivr_session_create(c, sc, nullptr, &s), IVR_OK);
  EXPECT_EQ(ivr_scene_release(sc), IVR_OK);
  EXPECT_EQ(ivr_context_release(c), IVR_OK);
  EXPECT_TRUE(session_render(s) == before.image);
  EXPECT_EQ(ivr_session_release(s), IVR_OK);
}

TEST_F(CApiSession, BadGradientRequestsAreRefused) {
  const char* f = "ivr_session_gradient";
  ivr_array* loss = nullptr;
  ivr_array* groups[2] = {};
  size_t count = 99;
  expect_error(ivr_session_gradient(session_, nullptr, "density", IVR_MODE_AUTO, IVR_LOSS_MSE, 0,
                                    &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "no target", ctx_);
  const std::vector<float> target = perturbed_target();
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  expect_error(ivr_session_gradient(session_, nullptr, "density,opacity", IVR_MODE_AUTO,
                                    IVR_LOSS_MSE, 0, &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "unknown parameter group 'opacity'", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, "density,tf,background", IVR_MODE_AUTO,
                                    IVR_LOSS_MSE, 0, &loss, groups, 2, &count, nullptr),
               IVR_ERROR_BUFFER_TOO_SMALL, f, "groups hold 2; wrt names 3", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, "density", static_cast<ivr_mode>(7),
                                    IVR_LOSS_MSE, 0, &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "unknown mode 7", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, "density", IVR_MODE_AUTO,
                                    static_cast<ivr_loss>(5), 0, &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "unknown loss 5", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, "tf_points", IVR_MODE_ADJOINT, IVR_LOSS_MSE,
                                    0, &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "mode adjoint cannot compute group 'tf_points'",
               ctx_);
  const ArrayPtr wrong = make_array(ctx_, {1, 16, 20, 4}, std::vector<float>(16 * 20 * 4, 0.f));
  expect_error(ivr_session_gradient(session_, wrong.get(), "density", IVR_MODE_AUTO, IVR_LOSS_MSE,
                                    0, &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "(1, 16, 20, 4)", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, nullptr, IVR_MODE_AUTO, IVR_LOSS_MSE, 0,
                                    &loss, groups, 2, &count, nullptr),
               IVR_ERROR_NULL_POINTER, f, "wrt is NULL", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, "density", IVR_MODE_AUTO, IVR_LOSS_MSE, 0,
                                    nullptr, groups, 2, &count, nullptr),
               IVR_ERROR_NULL_POINTER, f, "loss is NULL", ctx_);
  expect_error(ivr_session_gradient(session_, nullptr, "density", IVR_MODE_AUTO, IVR_LOSS_MSE, 0,
                                    &loss, nullptr, 2, &count, nullptr),
               IVR_ERROR_NULL_POINTER, f, "groups is NULL", ctx_);
  // No handle was handed out by any of the failures.
  EXPECT_EQ(loss, nullptr);
  EXPECT_EQ(groups[0], nullptr);
  EXPECT_EQ(groups[1], nullptr);
  EXPECT_EQ(count, 99u);

  // Changing the image size drops the target of the old shape.
  ASSERT_EQ(ivr_session_set_cameras_json(session_, R"([{"eye": [0, 0, 2], "width": 12,
                                                         "height": 10}])"),
            IVR_OK)
      << ivr_last_error();
  expect_error(ivr_session_gradient(session_, nullptr, "background", IVR_MODE_AUTO, IVR_LOSS_MSE, 0,
                                    &loss, groups, 2, &count, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, f, "no target", ctx_);

  // The other operations' bad requests.
  ivr_array* out = nullptr;
  expect_error(ivr_session_jacobian(session_, "tf,nonsense", &out), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_session_jacobian", "nonsense", ctx_);
  const ArrayPtr odd = make_array(ctx_, {7}, std::vector<float>(7, 0.f));
  const ArrayPtr image = render_array(session_);
  expect_error(ivr_session_loss(session_, image.get(), odd.get(), IVR_LOSS_MSE, &out),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_session_loss", "differ in size", ctx_);
  expect_error(ivr_session_loss(session_, image.get(), image.get(), static_cast<ivr_loss>(4), &out),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_session_loss", "unknown loss 4", ctx_);
  expect_error(ivr_session_project(session_, odd.get(), &out), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_session_project", "(7,)", ctx_);
  expect_error(ivr_session_backproject(session_, odd.get(), &out), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_session_backproject", "(7,)", ctx_);
  expect_error(ivr_session_backproject(session_, nullptr, &out), IVR_ERROR_NULL_POINTER,
               "ivr_session_backproject", "lines is NULL", ctx_);
  EXPECT_EQ(out, nullptr);
}

TEST_F(CApiSession, BadArrayCallsAreRefusedAndLeaveTheArrayAsItWas) {
  const int64_t shape[2] = {2, 3};
  ivr_array* a = nullptr;
  const char* fc = "ivr_array_create";
  expect_error(ivr_array_create(ctx_, 0, shape, IVR_FLOAT32, &a), IVR_ERROR_INVALID_ARGUMENT, fc,
               "rank 0", ctx_);
  expect_error(ivr_array_create(ctx_, 9, shape, IVR_FLOAT32, &a), IVR_ERROR_INVALID_ARGUMENT, fc,
               "rank 9", ctx_);
  expect_error(ivr_array_create(ctx_, 2, shape, IVR_UINT8, &a), IVR_ERROR_INVALID_ARGUMENT, fc,
               "dtype 2", ctx_);
  const int64_t negative[2] = {2, -3};
  expect_error(ivr_array_create(ctx_, 2, negative, IVR_FLOAT32, &a), IVR_ERROR_INVALID_ARGUMENT, fc,
               "(2, -3)", ctx_);
  expect_error(ivr_array_create(ctx_, 2, nullptr, IVR_FLOAT32, &a), IVR_ERROR_NULL_POINTER, fc,
               "shape is NULL", ctx_);
  expect_error(ivr_array_create(ctx_, 2, shape, IVR_FLOAT32, nullptr), IVR_ERROR_NULL_POINTER, fc,
               "array is NULL", ctx_);
  expect_error(ivr_array_create(nullptr, 2, shape, IVR_FLOAT32, &a), IVR_ERROR_NULL_POINTER, fc,
               "context is NULL");
  EXPECT_EQ(a, nullptr);

  const std::vector<float> values = {1, 2, 3, 4, 5, 6};
  const ArrayPtr held = make_array(ctx_, {2, 3}, values);
  a = held.get();
  const char* fu = "ivr_array_upload";
  const std::vector<double> five = {9, 9, 9, 9, 9}, seven = {9, 9, 9, 9, 9, 9, 9};
  expect_error(ivr_array_upload(a, five.data(), IVR_FLOAT64, 5), IVR_ERROR_INVALID_ARGUMENT, fu,
               "5 values for an array of 6", ctx_);
  expect_error(ivr_array_upload(a, seven.data(), IVR_FLOAT64, 7), IVR_ERROR_INVALID_ARGUMENT, fu,
               "7 values for an array of 6", ctx_);
  expect_error(ivr_array_upload(a, seven.data(), IVR_UINT16, 6), IVR_ERROR_INVALID_ARGUMENT, fu,
               "dtype 3", ctx_);
  expect_error(ivr_array_upload(a, nullptr, IVR_FLOAT32, 6), IVR_ERROR_NULL_POINTER, fu,
               "values is NULL", ctx_);
  const char* fd = "ivr_array_download";
  std::vector<float> small(5);
  expect_error(ivr_array_download(a, small.data(), IVR_FLOAT32, small.size()),
               IVR_ERROR_BUFFER_TOO_SMALL, fd, "values hold 5; the array has 6", ctx_);
  std::vector<double> small64(5);
  expect_error(ivr_array_download(a, small64.data(), IVR_FLOAT64, small64.size()),
               IVR_ERROR_BUFFER_TOO_SMALL, fd, "values hold 5; the array has 6", ctx_);
  expect_error(ivr_array_download(a, small64.data(), static_cast<ivr_dtype>(9), 6),
               IVR_ERROR_INVALID_ARGUMENT, fd, "dtype 9", ctx_);
  expect_error(ivr_array_download(a, nullptr, IVR_FLOAT32, 6), IVR_ERROR_NULL_POINTER, fd,
               "values is NULL", ctx_);
  expect_error(ivr_array_info(nullptr, nullptr, nullptr, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_array_info", "array is NULL");
  EXPECT_EQ(floats(a), values);
  EXPECT_EQ(shape_of(a), (std::vector<int64_t>{2, 3}));
}

TEST_F(CApiSession, BadOptimizersAndStepsAreRefused) {
  const SessionState before = state_of(session_);
  const char* fo = "ivr_density_optimizer_create";
  ivr_density_optimizer* o = nullptr;
  expect_error(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_LBFGS, 0.01, &o),
               IVR_ERROR_INVALID_ARGUMENT, fo, "IVR_OPTIMIZER_ADAM or IVR_OPTIMIZER_SGD", ctx_);
  expect_error(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_ADAM, 0, &o),
               IVR_ERROR_INVALID_ARGUMENT, fo, "lr", ctx_);
  expect_error(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_SGD, std::nan(""), &o),
               IVR_ERROR_INVALID_ARGUMENT, fo, "lr", ctx_);
  expect_error(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_ADAM, 0.01, nullptr),
               IVR_ERROR_NULL_POINTER, fo, "optimizer is NULL", ctx_);
  EXPECT_EQ(o, nullptr);

  // An optimizer sized for another session's grid (8 x 8 x 8).
  const std::vector<float> small = test_volume(8, 8, 8, 9);
  const int64_t small_shape[3] = {8, 8, 8};
  ivr_scene* small_scene = nullptr;
  ASSERT_NO_FATAL_FAILURE(
      make_scene(SceneParts{}, small.data(), IVR_FLOAT32, small_shape, &small_scene));
  ivr_session* small_session = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, small_scene, nullptr, &small_session), IVR_OK);
  ASSERT_EQ(ivr_density_optimizer_create(small_session, IVR_OPTIMIZER_ADAM, 0.01, &o), IVR_OK)
      << ivr_last_error();
  const ArrayPtr grad = make_array(ctx_, {16, 18, 20}, std::vector<float>(kVoxels, 0.5f));
  const char* fs = "ivr_session_step";
  expect_error(ivr_session_step(session_, o, grad.get()), IVR_ERROR_INVALID_ARGUMENT, fs,
               "the optimizer has 512 parameters; the densities 5760", ctx_);
  EXPECT_EQ(ivr_density_optimizer_release(o), IVR_OK);
  EXPECT_EQ(ivr_session_release(small_session), IVR_OK);
  EXPECT_EQ(ivr_scene_release(small_scene), IVR_OK);

  // A gradient of the wrong shape, or none.
  ASSERT_EQ(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_ADAM, 0.01, &o), IVR_OK);
  const ArrayPtr image = render_array(session_);
  expect_error(ivr_session_step(session_, o, image.get()), IVR_ERROR_INVALID_ARGUMENT, fs,
               "the gradient has shape (2, 16, 20, 4)", ctx_);
  expect_error(ivr_session_step(session_, o, nullptr), IVR_ERROR_NULL_POINTER, fs,
               "gradient is NULL", ctx_);
  expect_error(ivr_session_step(session_, nullptr, grad.get()), IVR_ERROR_NULL_POINTER, fs,
               "optimizer is NULL", ctx_);
  EXPECT_EQ(ivr_density_optimizer_release(o), IVR_OK);
  expect_error(ivr_density_optimizer_release(o), IVR_ERROR_INVALID_HANDLE,
               "ivr_density_optimizer_release", "not a live ivr_density_optimizer");
  expect_unchanged(session_, before, "refused steps");
}

// A scene made without "volume" gives a session without densities: operations that march them
// say so until set_volume.
TEST_F(CApiSession, ASessionWithoutDensitiesWaitsForSetVolume) {
  ivr_scene* dims_only = nullptr;
  ASSERT_EQ(ivr_scene_from_json(ctx_, SceneParts{}.json().c_str(), nullptr, &dims_only), IVR_OK);
  ivr_session* s = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, dims_only, nullptr, &s), IVR_OK) << ivr_last_error();
  ivr_array* out = nullptr;
  expect_error(ivr_session_render(s, &out), IVR_ERROR_INVALID_ARGUMENT, "ivr_session_render",
               "no densities", ctx_);
  expect_error(ivr_session_volume(s, &out), IVR_ERROR_INVALID_ARGUMENT, "ivr_session_volume",
               "no densities", ctx_);
  ASSERT_EQ(ivr_session_set_volume(s, volume_.data(), IVR_FLOAT32, kShape), IVR_OK)
      << ivr_last_error();
  EXPECT_TRUE(session_render(s) == one_shot_render(ctx_, scene_));
  EXPECT_EQ(ivr_session_release(s), IVR_OK);
  EXPECT_EQ(ivr_scene_release(dims_only), IVR_OK);
}

}  // namespace
}  // namespace ivr::test
