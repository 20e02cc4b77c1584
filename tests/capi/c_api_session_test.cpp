// c_api_session_test.cpp — C API session results equal the one-shot calls'; steps lower a loss.
#include <gtest/gtest.h>

#include "capi/c_api_session_support.hpp"

namespace ivr::test {
namespace {

// --- results -------------------------------------------------------------------------------------

TEST_F(CApiSession, RenderEqualsTheOneShotRenderAndArraysReportTheirShapeAndDtype) {
  const ArrayPtr image = render_array(session_);
  ASSERT_TRUE(image);
  int rank = 0;
  int64_t shape[8];
  ivr_dtype dtype = IVR_UINT8;
  ASSERT_EQ(ivr_array_info(image.get(), &rank, shape, &dtype), IVR_OK) << ivr_last_error();
  EXPECT_EQ(rank, 4);
  EXPECT_EQ(std::vector<int64_t>(shape, shape + 4), (std::vector<int64_t>{2, 16, 20, 4}));
  EXPECT_EQ(dtype, IVR_FLOAT32);
  EXPECT_EQ(image_shape(session_), (std::vector<int64_t>{2, 16, 20, 4}));
  EXPECT_EQ(volume_shape(session_), (std::vector<int64_t>(kShape, kShape + 3)));

  // The same kernel on the same data: the same bits as the one-shot render.
  const std::vector<float> want = one_shot_render(ctx_, scene_);
  const std::vector<float> got = floats(image.get());
  EXPECT_TRUE(got == want) << "session render differs from ivr_render";
  EXPECT_GT(max_abs(want), 0.1);  // not a blank image
  // float64 downloads are the float32 values widened, exactly.
  const std::vector<double> wide = doubles(image.get());
  ASSERT_EQ(wide.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) ASSERT_EQ(wide[i], double(want[i])) << i;
  // A larger buffer is fine; the values go to its front.
  std::vector<float> roomy(want.size() + 3, -7.f);
  ASSERT_EQ(ivr_array_download(image.get(), roomy.data(), IVR_FLOAT32, roomy.size()), IVR_OK);
  EXPECT_TRUE(std::equal(want.begin(), want.end(), roomy.begin()));
  EXPECT_EQ(roomy.back(), -7.f);
  EXPECT_EQ(ivr_array_wait(image.get()), IVR_OK);
  // Every argument may be left out of ivr_array_info.
  EXPECT_EQ(ivr_array_info(image.get(), nullptr, nullptr, nullptr), IVR_OK);
}

TEST_F(CApiSession, ArraysUploadAndDownloadInBothDtypes) {
  // Ranks 1 .. 8; info pads the shape with 1s.
  for (int rank = 1; rank <= 8; ++rank) {
    std::vector<int64_t> shape(size_t(rank), 1);
    shape[0] = 3;
    shape[size_t(rank) - 1] += 1;
    ivr_array* a = nullptr;
    ASSERT_EQ(ivr_array_create(ctx_, rank, shape.data(), IVR_FLOAT64, &a), IVR_OK)
        << ivr_last_error();
    const ArrayPtr held(a);
    int got_rank = 0;
    int64_t got[8];
    ivr_dtype dtype = IVR_FLOAT32;
    ASSERT_EQ(ivr_array_info(a, &got_rank, got, &dtype), IVR_OK);
    EXPECT_EQ(got_rank, rank);
    EXPECT_EQ(std::vector<int64_t>(got, got + rank), shape);
    for (int i = rank; i < 8; ++i) EXPECT_EQ(got[i], 1) << "rank " << rank;
    EXPECT_EQ(dtype, IVR_FLOAT64);
    // New arrays are zero-filled.
    EXPECT_EQ(doubles(a), std::vector<double>(count_of(shape), 0.0)) << "rank " << rank;
  }
  // float64 values through a float32 array are rounded once; through a float64 array kept.
  const std::vector<double> values = {0.1, -2.5, 1e-30, 3.0e30, 1.0 / 3.0, 0.0};
  const ArrayPtr f32 = make_array(ctx_, {2, 3}, IVR_FLOAT32, values);
  const ArrayPtr f64 = make_array(ctx_, {6}, IVR_FLOAT64, values);
  std::vector<float> rounded(values.begin(), values.end());
  EXPECT_EQ(floats(f32.get()), rounded);
  EXPECT_EQ(doubles(f32.get()), std::vector<double>(rounded.begin(), rounded.end()));
  EXPECT_EQ(doubles(f64.get()), values);
  EXPECT_EQ(floats(f64.get()), rounded);
  // float32 uploads into a float64 array are widened exactly.
  const std::vector<float> small = {1.5f, -0.25f, 7.f, 0.1f, 2.f, 3.f};
  ASSERT_EQ(ivr_array_upload(f64.get(), small.data(), IVR_FLOAT32, small.size()), IVR_OK)
      << ivr_last_error();
  EXPECT_EQ(doubles(f64.get()), std::vector<double>(small.begin(), small.end()));
}

// After each setter the session renders what the one-shot call renders for a scene changed the
// same way; every render array handed out earlier keeps its values.
TEST_F(CApiSession, EverySetterGivesTheRenderOfTheSceneChangedTheSameWay) {
  SceneParts parts;
  struct Kept {
    ArrayPtr array;
    std::vector<float> values;
    std::string step;
  };
  std::vector<Kept> kept;
  const auto check = [&](const std::string& step, const void* data, ivr_dtype dtype,
                         const int64_t shape[3]) {
    ArrayPtr image = render_array(session_);
    ASSERT_TRUE(image) << step;
    const std::vector<float> want = reference_render(parts, data, dtype, shape);
    const std::vector<float> got = floats(image.get());
    EXPECT_EQ(shape_of(image.get()), image_shape(session_)) << step;
    EXPECT_EQ(volume_shape(session_), (std::vector<int64_t>(shape, shape + 3))) << step;
    EXPECT_TRUE(got == want) << "after " << step << ": the session's render differs";
    EXPECT_GT(max_abs(want), 0.05) << step;
    kept.push_back({std::move(image), got, step});
  };
  check("creation", volume_.data(), IVR_FLOAT32, kShape);

  // float64 host data, the same shape.
  const std::vector<float> second = test_volume(16, 18, 20, 2);
  const std::vector<double> v64(second.begin(), second.end());
  ASSERT_EQ(ivr_session_set_volume(session_, v64.data(), IVR_FLOAT64, kShape), IVR_OK)
      << ivr_last_error();
  check("set_volume float64", v64.data(), IVR_FLOAT64, kShape);

  // uint8 host data of another shape (mapped to [0, 1]; the default box follows the grid).
  const int64_t shape8[3] = {20, 16, 18};
  std::vector<uint8_t> v8(20 * 16 * 18);
  {
    const std::vector<float> f = test_volume(20, 16, 18, 3);
    for (size_t i = 0; i < v8.size(); ++i) v8[i] = uint8_t(std::lround(255 * f[i]));
  }
  ASSERT_EQ(ivr_session_set_volume(session_, v8.data(), IVR_UINT8, shape8), IVR_OK)
      << ivr_last_error();
  check("set_volume uint8", v8.data(), IVR_UINT8, shape8);

  // float32 host data, back to a third shape.
  const int64_t shape32[3] = {17, 16, 19};
  const std::vector<float> v32 = test_volume(17, 16, 19, 4);
  ASSERT_EQ(ivr_session_set_volume(session_, v32.data(), IVR_FLOAT32, shape32), IVR_OK)
      << ivr_last_error();
  check("set_volume float32", v32.data(), IVR_FLOAT32, shape32);

  // A device array (float32, then float64): copied, so later uploads into it do not reach the
  // session.
  const std::vector<float> va = test_volume(16, 18, 20, 5);
  ArrayPtr densities = make_array(ctx_, {16, 18, 20}, va);
  ASSERT_EQ(ivr_session_set_volume_array(session_, densities.get()), IVR_OK) << ivr_last_error();
  const std::vector<double> scribble(kVoxels, 0.75);
  ASSERT_EQ(ivr_array_upload(densities.get(), scribble.data(), IVR_FLOAT64, kVoxels), IVR_OK);
  check("set_volume_array float32", va.data(), IVR_FLOAT32, kShape);
  const std::vector<float> vb = test_volume(16, 18, 20, 6);
  const ArrayPtr densities64 =
      make_array(ctx_, {16, 18, 20}, IVR_FLOAT64, std::vector<double>(vb.begin(), vb.end()));
  ASSERT_EQ(ivr_session_set_volume_array(session_, densities64.get()), IVR_OK) << ivr_last_error();
  check("set_volume_array float64", vb.data(), IVR_FLOAT32, kShape);

  // Transfer function handles: one with a wider zero range, then the first one again (the
  // occupancy grid of the first must be rebuilt, not kept), then a Gaussian one.
  for (const char* json : {kHighTf, kTf, kGaussianTf}) {
    ivr_transfer_function* tf = nullptr;
    ASSERT_EQ(ivr_tf_from_json(ctx_, json, &tf), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_session_set_tf(session_, tf), IVR_OK) << ivr_last_error();
    EXPECT_EQ(ivr_tf_release(tf), IVR_OK);  // the session has its own copy
    parts.tf = json;
    check(std::string("set_tf ") + (json == kHighTf ? "(zero below 0.6)"
                                    : json == kTf   ? "(zero below 0.1)"
                                                    : "(gaussian)"),
          vb.data(), IVR_FLOAT32, kShape);
  }

  // Cameras from JSON: an orbit of 3 views of another image size.
  const char* orbit =
      R"([{"orbit": {"views": 3, "radius": 2.2, "axis": [0, 1, 0], "start": 10, "fov_y": 35,
                     "width": 24, "height": 18}}])";
  ASSERT_EQ(ivr_session_set_cameras_json(session_, orbit), IVR_OK) << ivr_last_error();
  parts.cameras = orbit;
  EXPECT_EQ(image_shape(session_), (std::vector<int64_t>{3, 18, 24, 4}));
  check("set_cameras_json (orbit, 24 x 18)", vb.data(), IVR_FLOAT32, kShape);

  // Cameras from structs: a perspective and an orthographic view, 20 x 16.
  ivr_camera cams[2] = {};
  const double eye0[3] = {0.2, -0.5, 1.9}, eye1[3] = {1.6, 1.1, -0.4};
  for (int k = 0; k < 3; ++k) {
    cams[0].eye[k] = eye0[k];
    cams[1].eye[k] = eye1[k];
  }
  cams[0].up[1] = 1;
  cams[1].up[1] = 1;
  cams[1].target[0] = 0.05;
  cams[0].fov_y = 38;
  cams[1].fov_y = 40;  // unused by an orthographic camera
  cams[1].orthographic = 1;
  cams[1].ortho_height = 1.4;
  for (ivr_camera& c : cams) c.width = 20, c.height = 16;
  ASSERT_EQ(ivr_session_set_cameras(session_, cams, 2), IVR_OK) << ivr_last_error();
  parts.cameras =
      R"([{"eye": [0.2, -0.5, 1.9], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 38,
           "width": 20, "height": 16},
          {"eye": [1.6, 1.1, -0.4], "target": [0.05, 0, 0], "up": [0, 1, 0],
           "projection": "orthographic", "ortho_height": 1.4, "width": 20, "height": 16}])";
  EXPECT_EQ(image_shape(session_), (std::vector<int64_t>{2, 16, 20, 4}));
  check("set_cameras (structs, one orthographic)", vb.data(), IVR_FLOAT32, kShape);

  // The integrator.
  const char* integrator = R"({"scheme": "trapezoid", "step": 0.35, "min_transmittance": 0.001})";
  ASSERT_EQ(ivr_session_set_integrator_json(session_, integrator), IVR_OK) << ivr_last_error();
  parts.integrator = integrator;
  check("set_integrator_json", vb.data(), IVR_FLOAT32, kShape);

  // The background.
  const double background[3] = {0.6, 0.3, 0.1};
  ASSERT_EQ(ivr_session_set_background(session_, background), IVR_OK) << ivr_last_error();
  parts.background = "[0.6, 0.3, 0.1]";
  check("set_background", vb.data(), IVR_FLOAT32, kShape);

  // Every render handed out on the way still holds its own values.
  for (const Kept& k : kept)
    EXPECT_TRUE(floats(k.array.get()) == k.values) << "the render after " << k.step << " changed";
}

// A box the scene's JSON gave stays when the grid changes shape (the default box follows it:
// above).
TEST_F(CApiSession, AnExplicitBoxIsKeptWhenTheGridChanges) {
  SceneParts parts;
  parts.box = R"({"min": [-0.6, -0.5, -0.4], "max": [0.5, 0.55, 0.45]})";
  ivr_scene* boxed = nullptr;
  ASSERT_NO_FATAL_FAILURE(make_scene(parts, volume_.data(), IVR_FLOAT32, kShape, &boxed));
  ivr_session* s = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, boxed, nullptr, &s), IVR_OK) << ivr_last_error();
  EXPECT_TRUE(session_render(s) == one_shot_render(ctx_, boxed));
  EXPECT_EQ(ivr_scene_release(boxed), IVR_OK);
  const int64_t shape[3] = {20, 16, 18};
  const std::vector<float> v = test_volume(20, 16, 18, 51);
  ASSERT_EQ(ivr_session_set_volume(s, v.data(), IVR_FLOAT32, shape), IVR_OK) << ivr_last_error();
  EXPECT_TRUE(session_render(s) == reference_render(parts, v.data(), IVR_FLOAT32, shape))
      << "set_volume";
  const ArrayPtr a = make_array(ctx_, {16, 18, 20}, volume_);
  ASSERT_EQ(ivr_session_set_volume_array(s, a.get()), IVR_OK) << ivr_last_error();
  EXPECT_TRUE(session_render(s) == reference_render(parts, volume_.data(), IVR_FLOAT32, kShape))
      << "set_volume_array";
  EXPECT_EQ(ivr_session_release(s), IVR_OK);
}

// An integrator with a tolerance: the step is chosen as the one-shot render chooses it, and
// chosen again after the densities, the TF or the background change.
TEST_F(CApiSession, ATolerancesStepIsChosenAgainAfterEveryChange) {
  SceneParts parts;
  parts.integrator = R"({"scheme": "trapezoid", "tolerance": 0.01})";
  ASSERT_EQ(ivr_session_set_integrator_json(session_, parts.integrator.c_str()), IVR_OK)
      << ivr_last_error();
  const auto check = [&](const std::string& after, const std::vector<float>& volume) {
    ivr_scene* s = nullptr;
    make_scene(parts, volume.data(), IVR_FLOAT32, kShape, &s);
    ASSERT_TRUE(s);
    double want_step = 0;
    ASSERT_EQ(ivr_scene_step(ctx_, s, IVR_PRECISION_F32, &want_step, nullptr), IVR_OK)
        << ivr_last_error();
    const std::vector<float> want = one_shot_render(ctx_, s);
    EXPECT_EQ(ivr_scene_release(s), IVR_OK);
    EXPECT_TRUE(session_render(session_) == want) << "after " << after;
    ivr_operation_stats stats = {};
    ASSERT_EQ(ivr_session_last_stats(session_, &stats), IVR_OK) << ivr_last_error();
    EXPECT_EQ(stats.step, want_step) << "after " << after;
    EXPECT_GT(stats.kernel_seconds, 0.0);
    EXPECT_GT(stats.samples, 0u);
  };
  check("set_integrator_json", volume_);
  // Sparser densities: a different step may suit them.
  std::vector<float> thin(volume_);
  for (float& d : thin) d *= 0.3f;
  ASSERT_EQ(ivr_session_set_volume(session_, thin.data(), IVR_FLOAT32, kShape), IVR_OK);
  check("set_volume", thin);
  ivr_transfer_function* tf = nullptr;
  ASSERT_EQ(ivr_tf_from_json(ctx_, kGaussianTf, &tf), IVR_OK);
  ASSERT_EQ(ivr_session_set_tf(session_, tf), IVR_OK);
  EXPECT_EQ(ivr_tf_release(tf), IVR_OK);
  parts.tf = kGaussianTf;
  check("set_tf", thin);
  const double background[3] = {0.9, 0.9, 0.2};
  ASSERT_EQ(ivr_session_set_background(session_, background), IVR_OK);
  parts.background = "[0.9, 0.9, 0.2]";
  check("set_background", thin);
}

// An absorption scene's background is I_in: set_background's first value.
TEST_F(CApiSession, AbsorptionBackgroundIsTheIncomingIntensity) {
  SceneParts parts;
  parts.model = "absorption";
  parts.background = "[1]";
  ivr_scene* scene = nullptr;
  ASSERT_NO_FATAL_FAILURE(make_scene(parts, volume_.data(), IVR_FLOAT32, kShape, &scene));
  ivr_session* s = nullptr;
  ASSERT_EQ(ivr_session_create(ctx_, scene, nullptr, &s), IVR_OK) << ivr_last_error();
  EXPECT_EQ(image_shape(s), (std::vector<int64_t>{2, 16, 20, 1}));
  EXPECT_TRUE(session_render(s) == one_shot_render(ctx_, scene));
  const double background[3] = {0.7, 0, 0};
  ASSERT_EQ(ivr_session_set_background(s, background), IVR_OK) << ivr_last_error();
  parts.background = "[0.7]";
  EXPECT_TRUE(session_render(s) == reference_render(parts, volume_.data(), IVR_FLOAT32, kShape));
  EXPECT_EQ(ivr_session_release(s), IVR_OK);
  EXPECT_EQ(ivr_scene_release(scene), IVR_OK);
}

// The session's loss and gradients equal ivr_gradient's, for every group, both modes and both
// losses, against a target array and against the session's own target.
TEST_F(CApiSession, GradientsEqualTheOneShotGradient) {
  const std::vector<float> target = perturbed_target();
  const ArrayPtr target_array = make_array(ctx_, {2, 16, 20, 4}, target);
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK)
      << ivr_last_error();
  const std::string voxels = "voxels:" + std::to_string(kCentre) + "," +
                             std::to_string(kCentre + 1) + "-" + std::to_string(kCentre + 3);
  const struct {
    std::string wrt;
    ivr_mode mode;
    ivr_loss loss;
  } cases[] = {
      {"density,tf,background,camera", IVR_MODE_ADJOINT, IVR_LOSS_MSE},
      {"density,tf,background,camera", IVR_MODE_ADJOINT, IVR_LOSS_L1},
      {"tf,background,camera," + voxels, IVR_MODE_FORWARD, IVR_LOSS_MSE},
      {"background,tf," + voxels, IVR_MODE_FORWARD, IVR_LOSS_L1},
      {"density", IVR_MODE_FORWARD, IVR_LOSS_MSE},
      {"background,camera", IVR_MODE_AUTO, IVR_LOSS_MSE},
  };
  for (const auto& c : cases) {
    const std::string label = c.wrt +
                              (c.mode == IVR_MODE_FORWARD   ? " forward"
                               : c.mode == IVR_MODE_ADJOINT ? " adjoint"
                                                            : " auto") +
                              (c.loss == IVR_LOSS_L1 ? " l1" : " mse");
    SCOPED_TRACE(label);
    ivr_result* r = nullptr;
    ASSERT_EQ(ivr_gradient(ctx_, scene_, target.data(), target.size(), c.wrt.c_str(), c.mode,
                           c.loss, IVR_PRECISION_F32, 0, &r),
              IVR_OK)
        << ivr_last_error();
    double want_loss = 0;
    ivr_mode want_mode = IVR_MODE_AUTO;
    ASSERT_EQ(ivr_result_info(r, &want_loss, &want_mode, nullptr), IVR_OK);
    size_t want_count = 0;
    ASSERT_EQ(ivr_result_array_count(r, &want_count), IVR_OK);
    EXPECT_GT(want_loss, 1e-5);
    for (const bool own_target : {false, true}) {
      SCOPED_TRACE(own_target ? "the session's target" : "a target array");
      ivr_array* loss = nullptr;
      ivr_array* groups[6] = {};
      size_t count = 0;
      ivr_mode ran = IVR_MODE_AUTO;
      ASSERT_EQ(
          ivr_session_gradient(session_, own_target ? nullptr : target_array.get(), c.wrt.c_str(),
                               c.mode, c.loss, 0, &loss, groups, 6, &count, &ran),
          IVR_OK)
          << ivr_last_error();
      const ArrayPtr held_loss(loss);
      std::vector<ArrayPtr> held;
      for (size_t i = 0; i < count; ++i) held.emplace_back(groups[i]);
      EXPECT_EQ(ran, want_mode);
      if (c.mode != IVR_MODE_AUTO) EXPECT_EQ(ran, c.mode);
      EXPECT_EQ(shape_of(loss), (std::vector<int64_t>{1}));
      const std::vector<double> got_loss = doubles(loss);
      ASSERT_EQ(got_loss.size(), 1u);
      // The same reductions; the adjoint's atomics may add in another order.
      EXPECT_NEAR(got_loss[0], want_loss, 1e-6 * want_loss);
      ASSERT_EQ(count, want_count);
      for (size_t i = 0; i < count; ++i) {
        const char* name = nullptr;
        int rank = 0;
        int64_t shape[5];
        ASSERT_EQ(ivr_result_array_shape(r, i, &name, &rank, shape), IVR_OK);
        SCOPED_TRACE(name);
        EXPECT_EQ(shape_of(groups[i]), std::vector<int64_t>(shape, shape + rank));
        std::vector<double> want(count_of(std::vector<int64_t>(shape, shape + rank)));
        ASSERT_EQ(ivr_result_array_data(r, i, want.data(), want.size()), IVR_OK);
        EXPECT_GT(max_abs(want), 0.0) << "a zero gradient would make this comparison vacuous";
        expect_close(doubles(groups[i]), want, 1e-5, 1e-5, name);
      }
    }
    EXPECT_EQ(ivr_result_release(r), IVR_OK);
  }
}

TEST_F(CApiSession, JacobianEqualsTheOneShotJacobian) {
  const std::string wrt = "background,voxels:" + std::to_string(kCentre) + ",tf";
  ivr_result* r = nullptr;
  ASSERT_EQ(ivr_jacobian(ctx_, scene_, wrt.c_str(), IVR_PRECISION_F32, 0, &r), IVR_OK)
      << ivr_last_error();
  int rank = 0;
  int64_t shape[5];
  ASSERT_EQ(ivr_result_array_shape(r, 0, nullptr, &rank, shape), IVR_OK);
  const std::vector<int64_t> want_shape(shape, shape + rank);
  EXPECT_EQ(want_shape, (std::vector<int64_t>{2, 16, 20, 4, 3 + 1 + 16}));
  std::vector<double> want(count_of(want_shape));
  ASSERT_EQ(ivr_result_array_data(r, 0, want.data(), want.size()), IVR_OK);
  EXPECT_EQ(ivr_result_release(r), IVR_OK);
  ivr_array* j = nullptr;
  ASSERT_EQ(ivr_session_jacobian(session_, wrt.c_str(), &j), IVR_OK) << ivr_last_error();
  const ArrayPtr held(j);
  EXPECT_EQ(shape_of(j), want_shape);
  ivr_dtype dtype = IVR_FLOAT64;
  ASSERT_EQ(ivr_array_info(j, nullptr, nullptr, &dtype), IVR_OK);
  EXPECT_EQ(dtype, IVR_FLOAT32);
  EXPECT_GT(max_abs(want), 0.0);
  expect_close(doubles(j), want, 1e-6, 1e-6, "jacobian");
}

TEST_F(CApiSession, LossEqualsTheHostImageLoss) {
  const ArrayPtr image = render_array(session_);
  const std::vector<float> rendered = floats(image.get());
  const std::vector<float> target = perturbed_target();
  const ArrayPtr t32 = make_array(ctx_, {2, 16, 20, 4}, target);
  // A float64 target of another shape with the same count: the loss is elementwise.
  const ArrayPtr t64 = make_array(ctx_, {int64_t(kPixels)}, IVR_FLOAT64,
                                  std::vector<double>(target.begin(), target.end()));
  for (const ivr_loss kind : {IVR_LOSS_MSE, IVR_LOSS_L1}) {
    double want = 0;
    ASSERT_EQ(ivr_image_loss(rendered.data(), target.data(), kPixels, kind, &want), IVR_OK);
    EXPECT_GT(want, 1e-5);
    for (const ivr_array* t : {t32.get(), t64.get()}) {
      ivr_array* value = nullptr;
      ASSERT_EQ(ivr_session_loss(session_, image.get(), t, kind, &value), IVR_OK)
          << ivr_last_error();
      const ArrayPtr held(value);
      EXPECT_EQ(shape_of(value), (std::vector<int64_t>{1}));
      // Device partial sums (rounded to the session's float32) against the host's float64 sum.
      EXPECT_NEAR(doubles(value).at(0), want, 2e-6 * want) << (kind == IVR_LOSS_L1 ? "l1" : "mse");
    }
  }
}

// Projections of the session's densities and of given arrays equal ivr_project / ivr_backproject,
// and N and Nᵀ are each other's transposes on device arrays.
TEST_F(CApiSession, ProjectionsEqualTheOneShotCallsAndPassTheDotProductTest) {
  const std::vector<int64_t> lines_shape = {2, 16, 20, 1};
  const size_t rays = 2 * 16 * 20;
  // The session's own densities.
  std::vector<float> want(rays);
  ASSERT_EQ(ivr_project(ctx_, scene_, IVR_PRECISION_F32, nullptr, 0, want.data(), rays), IVR_OK)
      << ivr_last_error();
  ivr_array* lines = nullptr;
  ASSERT_EQ(ivr_session_project(session_, nullptr, &lines), IVR_OK) << ivr_last_error();
  const ArrayPtr held_lines(lines);
  EXPECT_EQ(shape_of(lines), lines_shape);
  EXPECT_GT(max_abs(want), 0.1);
  expect_close(floats(lines), want, 1e-6, 1e-6, "project()");
  // Another volume from a device array. (x and y below hold float values, so that float32 and
  // float64 arrays hold the same x64 and y64 exactly.)
  const std::vector<double> u = uniform(kVoxels, 11, 0, 1);
  const std::vector<float> x(u.begin(), u.end());
  const std::vector<double> x64(x.begin(), x.end());
  const ArrayPtr x_array = make_array(ctx_, {16, 18, 20}, x);
  ASSERT_EQ(ivr_project(ctx_, scene_, IVR_PRECISION_F32, x.data(), x.size(), want.data(), rays),
            IVR_OK)
      << ivr_last_error();
  ASSERT_EQ(ivr_session_project(session_, x_array.get(), &lines), IVR_OK) << ivr_last_error();
  const ArrayPtr held_x_lines(lines);
  expect_close(floats(lines), want, 1e-6, 1e-6, "project(x)");
  // The transpose of given lines.
  const std::vector<double> w = uniform(rays, 12, -1, 1);
  const std::vector<float> y(w.begin(), w.end());
  const std::vector<double> y64(y.begin(), y.end());
  const ArrayPtr y_array = make_array(ctx_, lines_shape, y);
  std::vector<float> want_back(kVoxels);
  ASSERT_EQ(ivr_backproject(ctx_, scene_, IVR_PRECISION_F32, y.data(), y.size(), want_back.data(),
                            want_back.size()),
            IVR_OK)
      << ivr_last_error();
  ivr_array* back = nullptr;
  ASSERT_EQ(ivr_session_backproject(session_, y_array.get(), &back), IVR_OK) << ivr_last_error();
  const ArrayPtr held_back(back);
  EXPECT_EQ(shape_of(back), (std::vector<int64_t>(kShape, kShape + 3)));
  EXPECT_GT(max_abs(want_back), 0.01);
  // Scattered with atomics: the sums' order may differ.
  expect_close(floats(back), want_back, 1e-5, 1e-5, "backproject(y)");

  // ⟨N x, y⟩ = ⟨x, Nᵀ y⟩ on device arrays, (x, y) → (N x, Nᵀ y) with dot products on the host:
  // to float32 rounding here, to float64 rounding in a float64 session.
  const auto dot_test = [&](const std::vector<double>& nx, const std::vector<double>& nty,
                            double rel, const char* what) {
    ASSERT_EQ(nx.size(), rays);
    ASSERT_EQ(nty.size(), kVoxels);
    long double lhs = 0, rhs = 0, scale = 0;
    for (size_t i = 0; i < rays; ++i) lhs += (long double)nx[i] * y64[i];
    for (size_t i = 0; i < kVoxels; ++i) {
      rhs += (long double)x64[i] * nty[i];
      scale += std::abs((long double)x64[i] * nty[i]);
    }
    EXPECT_GT(double(scale), 1.0) << what;
    EXPECT_NEAR(double(lhs), double(rhs), rel * double(scale))
        << what << ": <N x, y> = " << double(lhs) << ", <x, N^T y> = " << double(rhs);
  };
  dot_test(doubles(held_x_lines.get()), doubles(back), 2e-6, "float32");

  ivr_session_options o;
  ASSERT_EQ(ivr_session_options_init(&o), IVR_OK);
  o.precision = IVR_PRECISION_F64;
  ivr_session* s64 = nullptr;
  const ivr_status made = ivr_session_create(ctx_, scene_, &o, &s64);
  if (made == IVR_ERROR_UNSUPPORTED) {
    EXPECT_TRUE(has(ivr_last_error(), "float64")) << ivr_last_error();
    GTEST_SKIP() << "no float64 on this device: " << ivr_last_error();
  }
  ASSERT_EQ(made, IVR_OK) << ivr_last_error();
  const ArrayPtr x_f64 = make_array(ctx_, {16, 18, 20}, IVR_FLOAT64, x64);
  const ArrayPtr y_f64 = make_array(ctx_, lines_shape, IVR_FLOAT64, y64);
  ivr_array *nx = nullptr, *nty = nullptr;
  ASSERT_EQ(ivr_session_project(s64, x_f64.get(), &nx), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_session_backproject(s64, y_f64.get(), &nty), IVR_OK) << ivr_last_error();
  const ArrayPtr held_nx(nx), held_nty(nty);
  ivr_dtype dtype = IVR_FLOAT32;
  ASSERT_EQ(ivr_array_info(nx, nullptr, nullptr, &dtype), IVR_OK);
  EXPECT_EQ(dtype, IVR_FLOAT64);
  dot_test(doubles(nx), doubles(nty), 1e-12, "float64");
  // The float64 projection equals the one-shot float64 one (which hands out floats).
  ASSERT_EQ(ivr_project(ctx_, scene_, IVR_PRECISION_F64, x.data(), x.size(), want.data(), rays),
            IVR_OK);
  ivr_array* nx32 = nullptr;
  const ArrayPtr x32_in_f64 = make_array(ctx_, {16, 18, 20}, x);
  ASSERT_EQ(ivr_session_project(s64, x32_in_f64.get(), &nx32), IVR_OK) << ivr_last_error();
  const ArrayPtr held_nx32(nx32);
  expect_close(doubles(nx32), want, 1e-7, 1e-7, "float64 project(x)");
  EXPECT_EQ(ivr_session_release(s64), IVR_OK);
}

// --- optimisation --------------------------------------------------------------------------------

// Adam steps on the densities of a small emission–absorption scene, from a perturbed volume
// towards the images of the true one, lower the loss; the volume view shows the stepped values.
TEST_F(CApiSession, DensityStepsLowerTheLoss) {
  const ArrayPtr target = render_array(session_);  // of the true volume
  ASSERT_EQ(ivr_session_set_target_array(session_, target.get()), IVR_OK) << ivr_last_error();
  std::vector<float> start(volume_);
  const std::vector<double> noise = uniform(start.size(), 21, 0.6, 1.3);
  for (size_t i = 0; i < start.size(); ++i) start[i] = float(start[i] * noise[i]);
  ASSERT_EQ(ivr_session_set_volume(session_, start.data(), IVR_FLOAT32, kShape), IVR_OK)
      << ivr_last_error();
  ivr_array* view = nullptr;
  ASSERT_EQ(ivr_session_volume(session_, &view), IVR_OK) << ivr_last_error();
  const ArrayPtr held_view(view);
  EXPECT_EQ(shape_of(view), (std::vector<int64_t>(kShape, kShape + 3)));
  EXPECT_EQ(floats(view), start);
  ivr_density_optimizer* adam = nullptr;
  ASSERT_EQ(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_ADAM, 0.01, &adam), IVR_OK)
      << ivr_last_error();
  std::vector<double> losses;
  for (int k = 0; k < 25; ++k) {
    ivr_array* loss = nullptr;
    ivr_array* grad = nullptr;
    ASSERT_EQ(ivr_session_gradient(session_, nullptr, "density", IVR_MODE_ADJOINT, IVR_LOSS_MSE, 0,
                                   &loss, &grad, 1, nullptr, nullptr),
              IVR_OK)
        << ivr_last_error();
    const ArrayPtr held_loss(loss), held_grad(grad);
    ASSERT_EQ(ivr_session_step(session_, adam, grad), IVR_OK) << ivr_last_error();
    losses.push_back(doubles(loss).at(0));
  }
  EXPECT_EQ(ivr_density_optimizer_release(adam), IVR_OK);
  EXPECT_GT(losses.front(), 1e-5);
  EXPECT_LT(losses.back(), 0.25 * losses.front())
      << "loss " << losses.front() << " -> " << losses.back();
  // The view taken before the steps shows the stepped densities: >= 0, moved, and what the
  // session renders.
  const std::vector<float> stepped = floats(view);
  EXPECT_GE(*std::min_element(stepped.begin(), stepped.end()), 0.f);
  EXPECT_NE(stepped, start);
  EXPECT_TRUE(session_render(session_) ==
              reference_render(SceneParts{}, stepped.data(), IVR_FLOAT32, kShape));
}

// ivr_session_step takes the density gradient whichever mode computed it.
TEST_F(CApiSession, StepTakesTheDensityGradientOfEitherMode) {
  const std::vector<float> target = perturbed_target();
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  ivr_density_optimizer* sgd = nullptr;
  ASSERT_EQ(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_SGD, 0.05, &sgd), IVR_OK)
      << ivr_last_error();
  for (const ivr_mode mode : {IVR_MODE_ADJOINT, IVR_MODE_FORWARD}) {
    ivr_array* loss = nullptr;
    ivr_array* grad = nullptr;
    ASSERT_EQ(ivr_session_gradient(session_, nullptr, "density", mode, IVR_LOSS_MSE, 0, &loss,
                                   &grad, 1, nullptr, nullptr),
              IVR_OK)
        << ivr_last_error();
    const ArrayPtr held_loss(loss), held_grad(grad);
    ivr_dtype dtype = IVR_UINT8;
    ASSERT_EQ(ivr_array_info(grad, nullptr, nullptr, &dtype), IVR_OK);
    EXPECT_EQ(ivr_session_step(session_, sgd, grad), IVR_OK)
        << (mode == IVR_MODE_FORWARD ? "forward" : "adjoint") << "-mode density gradient ("
        << (dtype == IVR_FLOAT64 ? "float64" : "float32") << "): " << ivr_last_error();
  }
  EXPECT_EQ(ivr_density_optimizer_release(sgd), IVR_OK);
  // The automatic mode picks forward for a volume this small (2 x 2 x 2) under the default cost
  // model: the simplest loop, gradient then step, must work there too.
  const std::vector<float> tiny = test_volume(2, 2, 2, 71);
  const int64_t tiny_shape[3] = {2, 2, 2};
  ivr_density_optimizer* adam = nullptr;
  ASSERT_EQ(ivr_session_set_volume(session_, tiny.data(), IVR_FLOAT32, tiny_shape), IVR_OK);
  ASSERT_EQ(ivr_session_set_target(session_, target.data(), target.size()), IVR_OK);
  ASSERT_EQ(ivr_density_optimizer_create(session_, IVR_OPTIMIZER_ADAM, 0.01, &adam), IVR_OK);
  ivr_array* loss = nullptr;
  ivr_array* grad = nullptr;
  ivr_mode ran = IVR_MODE_AUTO;
  ASSERT_EQ(ivr_session_gradient(session_, nullptr, "density", IVR_MODE_AUTO, IVR_LOSS_MSE, 0,
                                 &loss, &grad, 1, nullptr, &ran),
            IVR_OK)
      << ivr_last_error();
  const ArrayPtr held_loss(loss), held_grad(grad);
  EXPECT_EQ(ivr_session_step(session_, adam, grad), IVR_OK)
      << "automatic mode (ran " << (ran == IVR_MODE_FORWARD ? "forward" : "adjoint")
      << "): " << ivr_last_error();
  EXPECT_EQ(ivr_density_optimizer_release(adam), IVR_OK);
}

}  // namespace
}  // namespace ivr::test
