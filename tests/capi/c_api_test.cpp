// c_api_test.cpp — the C API (ivr/ivr.h): results equal to the C++ core's, and every function's
// error paths (NULL handles and pointers, released handles, wrong dtypes, shapes and sizes,
// handles of another context) return their status with a message and never crash; separate
// contexts on separate threads.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "adjoint/adjoint_support.hpp"
#include "ivr/ivr.h"

namespace ivr::test {
namespace {

// The scene the C API and the Python binding's tests share (no volume: they pass one).
const std::string kSceneText = [] {
  std::ifstream in(std::string(IVR_TESTS_DIR) + "/data/binding_scene.json");
  return std::string(std::istreambuf_iterator<char>(in), {});
}();
const char* const kScene = kSceneText.c_str();

std::vector<float> test_volume() {
  std::vector<float> v(4 * 5 * 6);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(0.4 + 0.3 * std::sin(0.7 * double(i)));
  return v;
}

class CApi : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(ivr_context_create(nullptr, &ctx_), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_scene_from_json(ctx_, kScene, nullptr, &scene_), IVR_OK) << ivr_last_error();
    const int64_t shape[3] = {4, 5, 6};
    ASSERT_EQ(ivr_scene_set_volume(scene_, volume_.data(), IVR_FLOAT32, shape), IVR_OK)
        << ivr_last_error();
  }
  void TearDown() override {
    if (scene_) EXPECT_EQ(ivr_scene_release(scene_), IVR_OK);
    if (ctx_) EXPECT_EQ(ivr_context_release(ctx_), IVR_OK);
  }
  // The C++ scene the C calls should amount to.
  Scene cpp_scene() const {
    Scene s = parse_scene(std::string(kScene).insert(1, R"("volume": {"synthetic": "sphere",
        "dims": [2, 2, 2]}, )"),
                          ".");
    s.volume.nx = 6, s.volume.ny = 5, s.volume.nz = 4;
    s.volume.data = volume_;
    set_default_box(s);
    return s;
  }
  std::vector<float> volume_ = test_volume();
  ivr_context* ctx_ = nullptr;
  ivr_scene* scene_ = nullptr;
};

// The status, and a message naming the function, for this thread and the context.
void expect_error(ivr_status got, ivr_status want, const char* function,
                  ivr_context* ctx = nullptr) {
  EXPECT_EQ(got, want) << ivr_status_string(got) << ": " << ivr_last_error();
  EXPECT_NE(std::string(ivr_last_error()).find(function), std::string::npos) << ivr_last_error();
  if (ctx) EXPECT_EQ(std::string(ivr_context_last_error(ctx)), std::string(ivr_last_error()));
}

TEST_F(CApi, RenderEqualsTheCoreAndShapesAreReported) {
  int64_t shape[4];
  ASSERT_EQ(ivr_scene_image_shape(scene_, shape), IVR_OK);
  EXPECT_EQ(std::vector<int64_t>(shape, shape + 4), (std::vector<int64_t>{1, 5, 6, 4}));
  int64_t vshape[3];
  ASSERT_EQ(ivr_scene_volume_shape(scene_, vshape), IVR_OK);
  EXPECT_EQ(std::vector<int64_t>(vshape, vshape + 3), (std::vector<int64_t>{4, 5, 6}));
  std::vector<float> image(5 * 6 * 4);
  ASSERT_EQ(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, image.data(), image.size()), IVR_OK)
      << ivr_last_error();
  const Image want = render(device(), cpp_scene(), {Precision::f32});
  EXPECT_EQ(image, want.pixels);
  EXPECT_EQ(ivr_version(), IVR_VERSION);
  const char* name = nullptr;
  ASSERT_EQ(ivr_context_device_name(ctx_, &name), IVR_OK);
  EXPECT_EQ(std::string(name), device().info().name);
}

TEST_F(CApi, GradientAndJacobianEqualTheCore) {
  const Scene s = cpp_scene();
  const Image target = perturbed_target(s);
  ivr_result* r = nullptr;
  ASSERT_EQ(
      ivr_gradient(ctx_, scene_, target.pixels.data(), target.pixels.size(), "tf,voxels:3,7-9",
                   IVR_MODE_FORWARD, IVR_LOSS_MSE, IVR_PRECISION_F64, 0, &r),
      IVR_OK)
      << ivr_last_error();
  GradientOptions o;
  o.mode = Mode::forward;
  o.precision = Precision::f64;
  const Gradient d = gradient(device(), s, target, {"tf", "voxels:3,7-9"}, o);
  double loss = 0, seconds = 0;
  ivr_mode mode = IVR_MODE_AUTO;
  ASSERT_EQ(ivr_result_info(r, &loss, &mode, &seconds), IVR_OK);
  EXPECT_DOUBLE_EQ(loss, d.loss);
  EXPECT_EQ(mode, IVR_MODE_FORWARD);
  size_t count = 0;
  ASSERT_EQ(ivr_result_array_count(r, &count), IVR_OK);
  ASSERT_EQ(count, 2u);
  for (size_t i = 0; i < count; ++i) {
    const char* name = nullptr;
    int rank = 0;
    int64_t shape[5];
    ASSERT_EQ(ivr_result_array_shape(r, i, &name, &rank, shape), IVR_OK);
    EXPECT_EQ(std::string(name), d.groups[i].name);
    EXPECT_EQ(std::size_t(rank), d.groups[i].shape.size());
    std::vector<double> values(d.groups[i].values.size());
    ASSERT_EQ(ivr_result_array_data(r, i, values.data(), values.size()), IVR_OK);
    EXPECT_EQ(values, d.groups[i].values);
    std::vector<double> small(values.size() - 1);
    expect_error(ivr_result_array_data(r, i, small.data(), small.size()),
                 IVR_ERROR_BUFFER_TOO_SMALL, "ivr_result_array_data", ctx_);
  }
  EXPECT_EQ(ivr_result_release(r), IVR_OK);

  ASSERT_EQ(ivr_jacobian(ctx_, scene_, "background", IVR_PRECISION_F32, 0, &r), IVR_OK)
      << ivr_last_error();
  int64_t shape[5];
  int rank = 0;
  ASSERT_EQ(ivr_result_array_shape(r, 0, nullptr, &rank, shape), IVR_OK);
  EXPECT_EQ(rank, 5);
  EXPECT_EQ(std::vector<int64_t>(shape, shape + 5), (std::vector<int64_t>{1, 5, 6, 4, 3}));
  EXPECT_EQ(ivr_result_release(r), IVR_OK);
}

TEST_F(CApi, NullPointersAndHandles) {
  float image[120];
  int64_t shape[4];
  ivr_result* r = nullptr;
  expect_error(ivr_context_create(nullptr, nullptr), IVR_ERROR_NULL_POINTER, "ivr_context_create");
  expect_error(ivr_context_retain(nullptr), IVR_ERROR_NULL_POINTER, "ivr_context_retain");
  expect_error(ivr_context_release(nullptr), IVR_ERROR_NULL_POINTER, "ivr_context_release");
  expect_error(ivr_scene_from_json(nullptr, kScene, nullptr, &scene_), IVR_ERROR_NULL_POINTER,
               "ivr_scene_from_json");
  ivr_scene* other = nullptr;
  expect_error(ivr_scene_from_json(ctx_, nullptr, nullptr, &other), IVR_ERROR_NULL_POINTER,
               "ivr_scene_from_json", ctx_);
  expect_error(ivr_scene_load(ctx_, nullptr, &other), IVR_ERROR_NULL_POINTER, "ivr_scene_load",
               ctx_);
  expect_error(ivr_scene_image_shape(nullptr, shape), IVR_ERROR_NULL_POINTER,
               "ivr_scene_image_shape");
  expect_error(ivr_scene_image_shape(scene_, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_scene_image_shape", ctx_);
  expect_error(ivr_scene_set_volume(scene_, nullptr, IVR_FLOAT32, shape), IVR_ERROR_NULL_POINTER,
               "ivr_scene_set_volume", ctx_);
  expect_error(ivr_render(ctx_, nullptr, IVR_PRECISION_F32, 0, image, 120), IVR_ERROR_NULL_POINTER,
               "ivr_render", ctx_);
  expect_error(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, nullptr, 120), IVR_ERROR_NULL_POINTER,
               "ivr_render", ctx_);
  expect_error(ivr_gradient(ctx_, scene_, nullptr, 120, "tf", IVR_MODE_AUTO, IVR_LOSS_MSE,
                            IVR_PRECISION_F32, 0, &r),
               IVR_ERROR_NULL_POINTER, "ivr_gradient", ctx_);
  expect_error(ivr_gradient(ctx_, scene_, image, 120, nullptr, IVR_MODE_AUTO, IVR_LOSS_MSE,
                            IVR_PRECISION_F32, 0, &r),
               IVR_ERROR_NULL_POINTER, "ivr_gradient", ctx_);
  expect_error(ivr_jacobian(ctx_, scene_, "tf", IVR_PRECISION_F32, 0, nullptr),
               IVR_ERROR_NULL_POINTER, "ivr_jacobian", ctx_);
  expect_error(ivr_result_info(nullptr, nullptr, nullptr, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_result_info");
  expect_error(ivr_result_array_count(nullptr, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_result_array_count");
  expect_error(ivr_devices_json(nullptr, 10, nullptr), IVR_ERROR_NULL_POINTER, "ivr_devices_json");
  EXPECT_NE(std::string(ivr_context_last_error(nullptr)).find("not a live"), std::string::npos);
}

TEST_F(CApi, ReleasedHandlesAndForeignPointers) {
  ivr_scene* s = nullptr;
  ASSERT_EQ(ivr_scene_from_json(ctx_, kScene, nullptr, &s), IVR_OK);
  ASSERT_EQ(ivr_scene_retain(s), IVR_OK);
  ASSERT_EQ(ivr_scene_release(s), IVR_OK);  // one reference left
  int64_t shape[4];
  EXPECT_EQ(ivr_scene_image_shape(s, shape), IVR_OK);
  ASSERT_EQ(ivr_scene_release(s), IVR_OK);  // gone
  expect_error(ivr_scene_image_shape(s, shape), IVR_ERROR_INVALID_HANDLE, "ivr_scene_image_shape");
  expect_error(ivr_scene_release(s), IVR_ERROR_INVALID_HANDLE, "ivr_scene_release");
  // A pointer of another type, or none at all.
  expect_error(ivr_scene_image_shape(reinterpret_cast<ivr_scene*>(ctx_), shape),
               IVR_ERROR_INVALID_HANDLE, "ivr_scene_image_shape");
  int not_a_handle = 0;
  expect_error(ivr_context_retain(reinterpret_cast<ivr_context*>(&not_a_handle)),
               IVR_ERROR_INVALID_HANDLE, "ivr_context_retain");
  // A scene keeps its context alive.
  ivr_context* c = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &c), IVR_OK);
  ASSERT_EQ(ivr_scene_from_json(c, kScene, nullptr, &s), IVR_OK);
  ASSERT_EQ(ivr_context_release(c), IVR_OK);
  EXPECT_EQ(ivr_scene_image_shape(s, shape), IVR_OK);
  ASSERT_EQ(ivr_scene_release(s), IVR_OK);
  expect_error(ivr_context_retain(c), IVR_ERROR_INVALID_HANDLE, "ivr_context_retain");
}

TEST_F(CApi, WrongDtypesShapesSizesAndContexts) {
  const int64_t bad_shape[3] = {4, 0, 6};
  expect_error(ivr_scene_set_volume(scene_, volume_.data(), IVR_FLOAT32, bad_shape),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_scene_set_volume", ctx_);
  const int64_t shape[3] = {4, 5, 6};
  expect_error(ivr_scene_set_volume(scene_, volume_.data(), static_cast<ivr_dtype>(9), shape),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_scene_set_volume", ctx_);
  std::vector<float> image(119);
  expect_error(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, image.data(), image.size()),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_render", ctx_);
  image.resize(120);
  expect_error(ivr_render(ctx_, scene_, static_cast<ivr_precision>(5), 0, image.data(), 120),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_render", ctx_);
  ivr_result* r = nullptr;
  expect_error(ivr_gradient(ctx_, scene_, image.data(), 100, "tf", IVR_MODE_AUTO, IVR_LOSS_MSE,
                            IVR_PRECISION_F32, 0, &r),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_gradient", ctx_);
  expect_error(ivr_gradient(ctx_, scene_, image.data(), 120, "opacity", IVR_MODE_AUTO, IVR_LOSS_MSE,
                            IVR_PRECISION_F32, 0, &r),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_gradient", ctx_);
  EXPECT_NE(std::string(ivr_last_error()).find("unknown parameter group 'opacity'"),
            std::string::npos);
  expect_error(ivr_gradient(ctx_, scene_, image.data(), 120, "tf", static_cast<ivr_mode>(7),
                            IVR_LOSS_MSE, IVR_PRECISION_F32, 0, &r),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_gradient", ctx_);
  EXPECT_EQ(r, nullptr);
  // A scene of another context.
  ivr_context* other = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &other), IVR_OK);
  expect_error(ivr_render(other, scene_, IVR_PRECISION_F32, 0, image.data(), 120),
               IVR_ERROR_WRONG_CONTEXT, "ivr_render", other);
  EXPECT_EQ(ivr_context_release(other), IVR_OK);
  // A scene without a volume, and bad JSON.
  ivr_scene* empty = nullptr;
  ASSERT_EQ(ivr_scene_from_json(ctx_, kScene, nullptr, &empty), IVR_OK);
  expect_error(ivr_render(ctx_, empty, IVR_PRECISION_F32, 0, image.data(), 120),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_render", ctx_);
  EXPECT_NE(std::string(ivr_last_error()).find("no volume"), std::string::npos);
  EXPECT_EQ(ivr_scene_release(empty), IVR_OK);
  expect_error(ivr_scene_from_json(ctx_, "{\"cameras\": 3", nullptr, &empty), IVR_ERROR_IO,
               "ivr_scene_from_json", ctx_);
  expect_error(ivr_scene_load(ctx_, "/nonexistent/scene.json", &empty), IVR_ERROR_IO,
               "ivr_scene_load", ctx_);
  expect_error(ivr_context_create("no-such-device-xyz", &other), IVR_ERROR_NO_DEVICE,
               "ivr_context_create");
  EXPECT_STREQ(ivr_status_string(IVR_ERROR_WRONG_CONTEXT), "IVR_ERROR_WRONG_CONTEXT");
  EXPECT_STREQ(ivr_status_string(static_cast<ivr_status>(-5)), "IVR_ERROR_UNKNOWN_STATUS");
}

TEST_F(CApi, ImageLossAndTheRemainingErrorPaths) {
  const float a[4] = {0.f, 1.f, 2.f, -1.f}, b[4] = {1.f, 1.f, 0.f, 1.f};
  double value = -1;
  ASSERT_EQ(ivr_image_loss(a, b, 4, IVR_LOSS_MSE, &value), IVR_OK) << ivr_last_error();
  EXPECT_DOUBLE_EQ(value, (1.0 + 0.0 + 4.0 + 4.0) / 4.0);
  ASSERT_EQ(ivr_image_loss(a, b, 4, IVR_LOSS_L1, &value), IVR_OK) << ivr_last_error();
  EXPECT_DOUBLE_EQ(value, (1.0 + 0.0 + 2.0 + 2.0) / 4.0);
  expect_error(ivr_image_loss(nullptr, b, 4, IVR_LOSS_MSE, &value), IVR_ERROR_NULL_POINTER,
               "ivr_image_loss");
  expect_error(ivr_image_loss(a, b, 4, IVR_LOSS_MSE, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_image_loss");
  expect_error(ivr_image_loss(a, b, 4, static_cast<ivr_loss>(3), &value),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_image_loss");
  expect_error(ivr_image_loss(a, b, 0, IVR_LOSS_MSE, &value), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_image_loss");

  int64_t shape[5];
  expect_error(ivr_scene_volume_shape(scene_, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_scene_volume_shape", ctx_);
  const char* name = nullptr;
  expect_error(ivr_context_device_name(ctx_, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_context_device_name", ctx_);
  ivr_result* r = nullptr;
  expect_error(ivr_jacobian(ctx_, scene_, "tf,nonsense", IVR_PRECISION_F32, 0, &r),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_jacobian", ctx_);
  ASSERT_EQ(ivr_jacobian(ctx_, scene_, "background", IVR_PRECISION_F32, 0, &r), IVR_OK);
  int rank = 0;
  expect_error(ivr_result_array_shape(r, 1, &name, &rank, shape), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_result_array_shape", ctx_);
  expect_error(ivr_result_array_shape(r, 0, &name, &rank, nullptr), IVR_ERROR_NULL_POINTER,
               "ivr_result_array_shape", ctx_);
  double values[360];
  expect_error(ivr_result_array_data(r, 0, nullptr, 360), IVR_ERROR_NULL_POINTER,
               "ivr_result_array_data", ctx_);
  expect_error(ivr_result_array_data(r, 3, values, 360), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_result_array_data", ctx_);
  expect_error(ivr_result_retain(reinterpret_cast<ivr_result*>(scene_)), IVR_ERROR_INVALID_HANDLE,
               "ivr_result_retain");
  EXPECT_EQ(ivr_result_release(r), IVR_OK);
  expect_error(ivr_result_release(r), IVR_ERROR_INVALID_HANDLE, "ivr_result_release");
}

TEST_F(CApi, DevicesJson) {
  size_t needed = 0;
  ASSERT_EQ(ivr_devices_json(nullptr, 0, &needed), IVR_OK);
  ASSERT_GT(needed, 10u);
  std::vector<char> text(needed);
  ASSERT_EQ(ivr_devices_json(text.data(), text.size(), nullptr), IVR_OK);
  EXPECT_EQ(std::string(text.data()).rfind("{\"devices\":[", 0), 0u);
  expect_error(ivr_devices_json(text.data(), needed - 1, nullptr), IVR_ERROR_BUFFER_TOO_SMALL,
               "ivr_devices_json");
}

// Separate contexts on separate threads render concurrently, each getting the same image, and
// each thread's errors stay its own.
TEST_F(CApi, SeparateContextsOnSeparateThreads) {
  std::vector<float> want(120);
  ASSERT_EQ(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, want.data(), 120), IVR_OK);
  std::vector<std::vector<float>> got(4, std::vector<float>(120));
  std::vector<ivr_status> status(4, IVR_ERROR_INTERNAL);
  std::vector<std::string> errors(4);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      ivr_context* c = nullptr;
      ivr_scene* s = nullptr;
      if ((status[t] = ivr_context_create(nullptr, &c)) != IVR_OK) return;
      status[t] = ivr_scene_from_json(c, kScene, nullptr, &s);
      const int64_t shape[3] = {4, 5, 6};
      for (int k = 0; k < 3 && status[t] == IVR_OK; ++k) {
        status[t] = ivr_scene_set_volume(s, volume_.data(), IVR_FLOAT32, shape);
        if (status[t] == IVR_OK)
          status[t] = ivr_render(c, s, IVR_PRECISION_F32, 0, got[t].data(), 120);
      }
      ivr_render(c, s, IVR_PRECISION_F32, 0, got[t].data(), 7);  // this thread's own error
      errors[t] = ivr_last_error();
      ivr_scene_release(s);
      ivr_context_release(c);
    });
  for (std::thread& th : threads) th.join();
  for (int t = 0; t < 4; ++t) {
    EXPECT_EQ(status[t], IVR_OK) << "thread " << t;
    EXPECT_EQ(got[t], want) << "thread " << t;
    EXPECT_NE(errors[t].find("holds 7 floats"), std::string::npos) << errors[t];
  }
}


// The step a render uses: the scene's own, or the one its tolerance chooses (as the core's).
TEST_F(CApi, SceneStepIsTheOneRendersUse) {
  double step = 0, error = -1;
  ASSERT_EQ(ivr_scene_step(ctx_, scene_, IVR_PRECISION_F32, &step, &error), IVR_OK)
      << ivr_last_error();
  EXPECT_EQ(step, cpp_scene().integrator.step);
  EXPECT_EQ(error, 0.0);
  std::string text = kSceneText;
  const std::string integrator = R"("integrator": {"scheme": "midpoint", "step": 0.5})";
  ASSERT_NE(text.find(integrator), std::string::npos);
  text.replace(text.find(integrator), integrator.size(),
               R"("integrator": {"scheme": "trapezoid", "tolerance": 0.002})");
  ivr_scene* tolerant = nullptr;
  ASSERT_EQ(ivr_scene_from_json(ctx_, text.c_str(), nullptr, &tolerant), IVR_OK) << ivr_last_error();
  const int64_t shape[3] = {4, 5, 6};
  ASSERT_EQ(ivr_scene_set_volume(tolerant, volume_.data(), IVR_FLOAT32, shape), IVR_OK);
  ASSERT_EQ(ivr_scene_step(ctx_, tolerant, IVR_PRECISION_F32, &step, nullptr), IVR_OK)
      << ivr_last_error();
  Scene core = cpp_scene();
  core.integrator.scheme = Scheme::trapezoid;
  EXPECT_EQ(step, choose_step(device(), core, 0.002).step);
  expect_error(ivr_scene_step(ctx_, tolerant, IVR_PRECISION_F32, nullptr, nullptr),
               IVR_ERROR_NULL_POINTER, "ivr_scene_step", ctx_);
  expect_error(ivr_scene_step(ctx_, nullptr, IVR_PRECISION_F32, &step, nullptr),
               IVR_ERROR_NULL_POINTER, "ivr_scene_step", ctx_);
  EXPECT_EQ(ivr_scene_release(tolerant), IVR_OK);
}

}  // namespace
}  // namespace ivr::test
