// c_api_volume_test.cpp — the C API's volume and transfer-function handles: made from memory and
// from docs/design.md's JSON objects, read back, set on scenes (the render equals the core's with the
// same volume and TF), and every error path (NULL, released, wrong kind, other context, bad JSON).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "ivr/ivr.h"
#include "test_support.hpp"

namespace ivr::test {
namespace {

const std::string kSceneText = [] {
  std::ifstream in(std::string(IVR_TESTS_DIR) + "/data/binding_scene.json");
  return std::string(std::istreambuf_iterator<char>(in), {});
}();

const char* const kTf =
    R"({"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0.2, 0.4, 1.0], "extinction": 0.5},
        {"density": 1.0, "color": [1.0, 0.5, 0.1], "extinction": 9.0}]})";

void expect_error(ivr_status got, ivr_status want, const std::string& words) {
  EXPECT_EQ(got, want) << ivr_status_string(got) << ": " << ivr_last_error();
  EXPECT_NE(std::string(ivr_last_error()).find(words), std::string::npos) << ivr_last_error();
}

class CApiVolume : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(ivr_context_create(nullptr, &ctx_), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_scene_from_json(ctx_, kSceneText.c_str(), nullptr, &scene_), IVR_OK)
        << ivr_last_error();
  }
  void TearDown() override {
    EXPECT_EQ(ivr_scene_release(scene_), IVR_OK);
    EXPECT_EQ(ivr_context_release(ctx_), IVR_OK);
  }
  std::vector<float> render() {
    int64_t shape[4];
    EXPECT_EQ(ivr_scene_image_shape(scene_, shape), IVR_OK);
    std::vector<float> image(size_t(shape[0] * shape[1] * shape[2] * shape[3]));
    EXPECT_EQ(ivr_render(ctx_, scene_, IVR_PRECISION_F32, 0, image.data(), image.size()), IVR_OK)
        << ivr_last_error();
    return image;
  }
  ivr_context* ctx_ = nullptr;
  ivr_scene* scene_ = nullptr;
};

TEST_F(CApiVolume, FromMemoryAndJsonReadBackAndRenderLikeTheCore) {
  // A uint16 volume from memory maps to [0, 1] and reads back as float32.
  std::vector<uint16_t> raw(3 * 4 * 5);
  for (size_t i = 0; i < raw.size(); ++i) raw[i] = uint16_t(i * 1000);
  const int64_t shape[3] = {3, 4, 5};
  ivr_volume* v = nullptr;
  ASSERT_EQ(ivr_volume_create(ctx_, raw.data(), IVR_UINT16, shape, &v), IVR_OK) << ivr_last_error();
  int64_t got[3];
  ASSERT_EQ(ivr_volume_shape(v, got), IVR_OK);
  EXPECT_EQ(std::vector<int64_t>(got, got + 3), (std::vector<int64_t>{3, 4, 5}));
  std::vector<float> back(raw.size());
  ASSERT_EQ(ivr_volume_data(v, back.data(), back.size()), IVR_OK);
  for (size_t i = 0; i < raw.size(); ++i) EXPECT_FLOAT_EQ(back[i], float(raw[i] / 65535.0));

  // Set on the scene with a TF handle: the render equals the core's with that volume and TF.
  ivr_transfer_function* tf = nullptr;
  ASSERT_EQ(ivr_tf_from_json(ctx_, kTf, &tf), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_scene_set_volume_handle(scene_, v), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_scene_set_tf(scene_, tf), IVR_OK) << ivr_last_error();
  EXPECT_EQ(ivr_volume_release(v), IVR_OK);  // the scene has its own copy
  EXPECT_EQ(ivr_tf_release(tf), IVR_OK);
  Scene s = parse_scene(std::string(kSceneText).insert(1, R"("volume": {"synthetic": "sphere",
      "dims": [2, 2, 2]}, )"),
                        ".");
  s.volume.nx = 5, s.volume.ny = 4, s.volume.nz = 3;
  s.volume.data = back;
  set_default_box(s);
  s.tf = parse_tf(kTf);
  EXPECT_EQ(render(), ivr::render(device(), s, {Precision::f32}).pixels);

  // A synthetic volume from its JSON object equals the core's.
  ASSERT_EQ(ivr_volume_from_json(ctx_, R"({"synthetic": "marschner_lobb", "dims": [6, 7, 8]})",
                                 nullptr, &v),
            IVR_OK)
      << ivr_last_error();
  ASSERT_EQ(ivr_volume_shape(v, got), IVR_OK);
  EXPECT_EQ(std::vector<int64_t>(got, got + 3), (std::vector<int64_t>{8, 7, 6}));
  back.assign(6 * 7 * 8, 0.f);
  ASSERT_EQ(ivr_volume_data(v, back.data(), back.size()), IVR_OK);
  EXPECT_EQ(back, synthetic_volume("marschner_lobb", 6, 7, 8).data);
  EXPECT_EQ(ivr_volume_release(v), IVR_OK);
}

TEST_F(CApiVolume, FromAFileRelativeToBaseDir) {
  const std::string dir = ivr::test::temp_dir("c_api_volume_relative");  // this process's own
  std::vector<float> data(2 * 3 * 4);
  for (size_t i = 0; i < data.size(); ++i) data[i] = float(i) / 24.f;
  save_npy(dir + "/c_api_volume.npy", {2, 3, 4}, data.data());
  ivr_volume* v = nullptr;
  ASSERT_EQ(ivr_volume_from_json(ctx_, R"({"file": "c_api_volume.npy"})", dir.c_str(), &v), IVR_OK)
      << ivr_last_error();
  std::vector<float> back(24);
  ASSERT_EQ(ivr_volume_data(v, back.data(), back.size()), IVR_OK);
  EXPECT_EQ(back, data);
  EXPECT_EQ(ivr_volume_release(v), IVR_OK);
  expect_error(ivr_volume_from_json(ctx_, R"({"file": "missing.npy"})", dir.c_str(), &v),
               IVR_ERROR_IO, "missing.npy");
  EXPECT_EQ(v, nullptr);
}

TEST_F(CApiVolume, ErrorPaths) {
  const float data[8] = {};
  const int64_t shape[3] = {2, 2, 2}, bad[3] = {2, -1, 2};
  ivr_volume* v = nullptr;
  ivr_transfer_function* tf = nullptr;
  expect_error(ivr_volume_create(nullptr, data, IVR_FLOAT32, shape, &v), IVR_ERROR_NULL_POINTER,
               "ivr_volume_create: context is NULL");
  expect_error(ivr_volume_create(ctx_, nullptr, IVR_FLOAT32, shape, &v), IVR_ERROR_NULL_POINTER,
               "data is NULL");
  expect_error(ivr_volume_create(ctx_, data, IVR_FLOAT32, bad, &v), IVR_ERROR_INVALID_ARGUMENT,
               "shape[1] = -1");
  expect_error(ivr_volume_create(ctx_, data, static_cast<ivr_dtype>(17), shape, &v),
               IVR_ERROR_INVALID_ARGUMENT, "unknown dtype 17");
  expect_error(ivr_volume_create(ctx_, data, IVR_FLOAT32, shape, nullptr), IVR_ERROR_NULL_POINTER,
               "volume is NULL");
  expect_error(ivr_volume_from_json(ctx_, R"({"synthetic": "cube"})", nullptr, &v),
               IVR_ERROR_INVALID_ARGUMENT, "cube");
  expect_error(ivr_volume_from_json(ctx_, "{", nullptr, &v), IVR_ERROR_IO, "malformed JSON");
  expect_error(ivr_tf_from_json(ctx_, R"({"type": "piecewise_linear", "points": []})", &tf),
               IVR_ERROR_INVALID_ARGUMENT, "tf.points");
  expect_error(ivr_tf_from_json(ctx_, R"({"type": "spline"})", &tf), IVR_ERROR_INVALID_ARGUMENT,
               "spline");
  expect_error(ivr_tf_from_json(ctx_, nullptr, &tf), IVR_ERROR_NULL_POINTER, "json is NULL");
  EXPECT_EQ(v, nullptr);
  EXPECT_EQ(tf, nullptr);

  ASSERT_EQ(ivr_volume_create(ctx_, data, IVR_FLOAT32, shape, &v), IVR_OK);
  std::vector<float> small(7);
  expect_error(ivr_volume_data(v, small.data(), small.size()), IVR_ERROR_BUFFER_TOO_SMALL,
               "the volume has 8");
  expect_error(ivr_volume_shape(v, nullptr), IVR_ERROR_NULL_POINTER, "shape is NULL");
  expect_error(ivr_scene_set_volume_handle(scene_, nullptr), IVR_ERROR_NULL_POINTER,
               "volume is NULL");
  expect_error(ivr_scene_set_tf(scene_, reinterpret_cast<const ivr_transfer_function*>(v)),
               IVR_ERROR_INVALID_HANDLE, "not a live ivr_transfer_function");
  // Handles of another context.
  ivr_context* other = nullptr;
  ASSERT_EQ(ivr_context_create(nullptr, &other), IVR_OK);
  ASSERT_EQ(ivr_tf_from_json(other, kTf, &tf), IVR_OK);
  expect_error(ivr_scene_set_tf(scene_, tf), IVR_ERROR_WRONG_CONTEXT, "another context");
  ivr_volume* foreign = nullptr;
  ASSERT_EQ(ivr_volume_create(other, data, IVR_FLOAT32, shape, &foreign), IVR_OK);
  expect_error(ivr_scene_set_volume_handle(scene_, foreign), IVR_ERROR_WRONG_CONTEXT,
               "another context");
  EXPECT_EQ(ivr_context_release(other), IVR_OK);  // the handles keep it alive
  EXPECT_EQ(ivr_volume_release(foreign), IVR_OK);
  EXPECT_EQ(ivr_tf_release(tf), IVR_OK);
  // Released handles.
  EXPECT_EQ(ivr_volume_retain(v), IVR_OK);
  EXPECT_EQ(ivr_volume_release(v), IVR_OK);
  EXPECT_EQ(ivr_volume_release(v), IVR_OK);
  int64_t out[3];
  expect_error(ivr_volume_shape(v, out), IVR_ERROR_INVALID_HANDLE, "not a live ivr_volume");
  expect_error(ivr_volume_release(v), IVR_ERROR_INVALID_HANDLE, "ivr_volume_release");
  expect_error(ivr_tf_retain(tf), IVR_ERROR_INVALID_HANDLE, "ivr_tf_retain");
  expect_error(ivr_scene_set_volume_handle(scene_, v), IVR_ERROR_INVALID_HANDLE,
               "ivr_scene_set_volume_handle");
}

}  // namespace
}  // namespace ivr::test
