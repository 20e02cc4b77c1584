// c_api_array_host_test.cpp — arrays over host memory without copies (ivr_array_wrap) and mapped
// into it (ivr_array_map): on PoCL, whose device memory is the host's, the kernels read the
// caller's memory itself and a map hands out the device array's own memory; the errors.
#include <gtest/gtest.h>

#include <cstring>

#include "capi/c_api_session_support.hpp"

namespace ivr::test {
namespace {

bool host_unified() {
  return device().info().host_unified_memory;
}

double session_loss(ivr_session* s, const ivr_array* image, const ivr_array* target,
                    ivr_loss kind) {
  ivr_array* out = nullptr;
  EXPECT_EQ(ivr_session_loss(s, image, target, kind, &out), IVR_OK) << ivr_last_error();
  const ArrayPtr held(out);
  return out ? doubles(out)[0] : NAN;
}

TEST_F(CApiSession, WrappedHostMemoryIsReadInPlace) {
  // In place only where the device's memory is the host's (PoCL's CPU device reports it; a
  // discrete GPU copies CL_MEM_USE_HOST_PTR memory, as OpenCL allows).
  if (!host_unified()) GTEST_SKIP() << "the device's memory is not the host's";
  const std::vector<int64_t> shape = image_shape(session_);
  const ArrayPtr image = render_array(session_);
  const std::vector<float> values = floats(image.get());
  std::vector<float> weights(values.size(), 1.f);
  ivr_array* w = nullptr;
  int borrowed = -1;
  ASSERT_EQ(ivr_array_wrap(ctx_, weights.data(), int(shape.size()), shape.data(), IVR_FLOAT32,
                           &borrowed, &w),
            IVR_OK)
      << ivr_last_error();
  const ArrayPtr wrapped(w);
  EXPECT_EQ(borrowed, 1);
  double sum = 0;
  for (float v : values) sum += v;
  EXPECT_NEAR(session_loss(session_, image.get(), w, IVR_LOSS_DOT), sum, 1e-4 * std::abs(sum));
  // The caller's memory changes; no upload: the next operation sees it.
  for (float& x : weights) x = 2.f;
  EXPECT_NEAR(session_loss(session_, image.get(), w, IVR_LOSS_DOT), 2 * sum, 2e-4 * std::abs(sum));
  // Mapped, it is the caller's memory itself.
  void* mapped = nullptr;
  ASSERT_EQ(ivr_array_map(w, &mapped), IVR_OK) << ivr_last_error();
  EXPECT_EQ(mapped, static_cast<void*>(weights.data()));
  EXPECT_EQ(ivr_array_unmap(w), IVR_OK);
}

TEST_F(CApiSession, MapsShowTheValuesWithoutACopyAndNest) {
  if (!host_unified()) GTEST_SKIP() << "the device's memory is not the host's";
  const ArrayPtr image = render_array(session_);
  const std::vector<float> want = floats(image.get());
  void* a = nullptr;
  void* b = nullptr;
  ASSERT_EQ(ivr_array_map(image.get(), &a), IVR_OK) << ivr_last_error();
  ASSERT_EQ(ivr_array_map(image.get(), &b), IVR_OK) << ivr_last_error();
  EXPECT_EQ(a, b);  // maps nest and share one pointer
  EXPECT_EQ(std::memcmp(a, want.data(), want.size() * sizeof(float)), 0);
  // No copy: the mapped memory is the buffer's, so a write shows in a download after the unmap.
  static_cast<float*>(a)[0] = 42.f;
  const float sentinel = 1.f;
  EXPECT_NE(ivr_array_upload(image.get(), &sentinel, IVR_FLOAT32, 1), IVR_OK);  // mapped: refused
  EXPECT_NE(std::string(ivr_last_error()).find("mapped"), std::string::npos) << ivr_last_error();
  EXPECT_EQ(ivr_array_unmap(image.get()), IVR_OK);
  EXPECT_EQ(ivr_array_unmap(image.get()), IVR_OK);
  EXPECT_EQ(floats(image.get())[0], 42.f);
  // One unmap too many.
  EXPECT_EQ(ivr_array_unmap(image.get()), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(ivr_last_error()).find("not mapped"), std::string::npos);
  // float64 arrays map as float64.
  const double three[3] = {1.5, -2.0, 4.25};
  const ArrayPtr d = make_array(ctx_, {3}, IVR_FLOAT64, {three[0], three[1], three[2]});
  void* dp = nullptr;
  ASSERT_EQ(ivr_array_map(d.get(), &dp), IVR_OK);
  EXPECT_EQ(std::memcmp(dp, three, sizeof three), 0);
  EXPECT_EQ(ivr_array_unmap(d.get()), IVR_OK);
}

// Released while mapped, or while a wrapped array's operation is queued: no leak, no error
// (LeakSanitizer and AddressSanitizer watch the sanitizer run).
TEST_F(CApiSession, ReleasesWhileMappedOrBorrowed) {
  const ArrayPtr image = render_array(session_);
  ivr_array* copy = nullptr;
  ASSERT_EQ(ivr_session_render(session_, &copy), IVR_OK);
  void* p = nullptr;
  ASSERT_EQ(ivr_array_map(copy, &p), IVR_OK);
  EXPECT_EQ(ivr_array_release(copy), IVR_OK);
  std::vector<float> weights(floats(image.get()).size(), 0.5f);
  const std::vector<int64_t> shape = image_shape(session_);
  ivr_array* w = nullptr;
  ASSERT_EQ(ivr_array_wrap(ctx_, weights.data(), 4, shape.data(), IVR_FLOAT32, nullptr, &w),
            IVR_OK);
  ivr_array* out = nullptr;
  ASSERT_EQ(ivr_session_loss(session_, image.get(), w, IVR_LOSS_DOT, &out), IVR_OK);
  EXPECT_EQ(ivr_array_release(w), IVR_OK);  // waits for the loss that reads `weights`
  const ArrayPtr held(out);
  double sum = 0;
  for (float v : floats(image.get())) sum += 0.5 * v;
  EXPECT_NEAR(doubles(out)[0], sum, 1e-4 * std::abs(sum));
}

TEST_F(CApiSession, WrapAndMapErrorsNameTheArgument) {
  float x[4] = {};
  const int64_t shape[1] = {4};
  ivr_array* a = nullptr;
  EXPECT_EQ(ivr_array_wrap(ctx_, nullptr, 1, shape, IVR_FLOAT32, nullptr, &a),
            IVR_ERROR_NULL_POINTER);
  EXPECT_NE(std::string(ivr_last_error()).find("data"), std::string::npos) << ivr_last_error();
  EXPECT_EQ(ivr_array_wrap(ctx_, x, 0, shape, IVR_FLOAT32, nullptr, &a), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(ivr_last_error()).find("rank 0"), std::string::npos);
  EXPECT_EQ(ivr_array_wrap(ctx_, x, 1, shape, IVR_UINT8, nullptr, &a), IVR_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(ivr_array_wrap(nullptr, x, 1, shape, IVR_FLOAT32, nullptr, &a),
            IVR_ERROR_NULL_POINTER);
  EXPECT_EQ(a, nullptr);
  EXPECT_EQ(ivr_array_map(nullptr, nullptr), IVR_ERROR_NULL_POINTER);
  const ArrayPtr b = make_array(ctx_, {2}, IVR_FLOAT32, {0.0, 0.0});
  EXPECT_EQ(ivr_array_map(b.get(), nullptr), IVR_ERROR_NULL_POINTER);
  EXPECT_NE(std::string(ivr_last_error()).find("data"), std::string::npos) << ivr_last_error();
  EXPECT_EQ(ivr_array_unmap(nullptr), IVR_ERROR_NULL_POINTER);
  ivr_array* released = nullptr;
  ASSERT_EQ(ivr_array_create(ctx_, 1, shape, IVR_FLOAT32, &released), IVR_OK);
  ASSERT_EQ(ivr_array_release(released), IVR_OK);
  void* p = nullptr;
  EXPECT_EQ(ivr_array_map(released, &p), IVR_ERROR_INVALID_HANDLE);
}

}  // namespace
}  // namespace ivr::test
