// c_api_session_support.hpp — scenes, array helpers and the fixture of the C API session tests.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "ivr/ivr.hpp"
#include "test_support.hpp"

// Not in an anonymous namespace: the tests of CApiSession in every file must share one fixture
// class (GoogleTest checks), so the helpers it uses are `inline` here too.
namespace ivr::test {

// --- scenes --------------------------------------------------------------------------------------

// A TF that is 0 below density 0.1 (so automatic empty-space skipping has bricks to skip), and a
// Gaussian one (no zero range: no skipping) for set_tf.
inline const char* const kTf =
    R"({"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0.1, 0.2, 0.3], "extinction": 0},
        {"density": 0.1, "color": [0.2, 0.3, 0.5], "extinction": 0},
        {"density": 0.5, "color": [1.0, 0.6, 0.2], "extinction": 10},
        {"density": 1.0, "color": [1.0, 1.0, 0.8], "extinction": 16}]})";
// Zero below 0.6: more bricks empty than under kTf (an occupancy grid left over from it would
// skip bricks that kTf needs).
inline const char* const kHighTf =
    R"({"type": "piecewise_linear", "points": [
        {"density": 0.6, "color": [0.8, 0.5, 0.3], "extinction": 0},
        {"density": 1.0, "color": [1.0, 0.9, 0.7], "extinction": 25}]})";
inline const char* const kGaussianTf =
    R"({"type": "gaussian", "gaussians": [
        {"mean": 0.5, "width": 0.15, "color": [0.9, 0.4, 0.1], "extinction": 12},
        {"mean": 0.8, "width": 0.1, "color": [0.2, 0.5, 1.0], "extinction": 20}]})";
// Two 20 x 16 views (not square, so that a swapped width and height shows).
inline const char* const kCameras =
    R"([{"eye": [0.3, 0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
         "width": 20, "height": 16},
        {"eye": [-1.8, 0.2, 0.6], "target": [0.05, 0, 0], "up": [0, 1, 0], "fov_y": 45,
         "width": 20, "height": 16}])";

// The parts of a scene's JSON that the setters change; the one-shot reference scene is built
// from them, so it is changed "the same way" independently of the session's code.
struct SceneParts {
  std::string model = "emission_absorption";
  std::string tf = kTf;
  std::string background = "[0.1, 0.2, 0.3]";
  std::string cameras = kCameras;
  std::string integrator = R"({"scheme": "midpoint", "step": 0.5})";
  std::string box;  // "": the default box, which follows the grid
  std::string json() const {
    return "{\"model\": \"" + model + "\", \"tf\": " + tf + ", \"background\": " + background +
           ", \"cameras\": " + cameras + ", \"integrator\": " + integrator +
           (box.empty() ? "" : ", \"box\": " + box) + "}";
  }
};

inline constexpr int64_t kShape[3] = {16, 18, 20};  // (nz, ny, nx): every axis a different length
inline constexpr size_t kVoxels = 16 * 18 * 20;
inline constexpr size_t kPixels = 2 * 16 * 20 * 4;  // (views, H, W, C) of kCameras
// Voxel (x, y, z) = (10, 9, 8), inside the ball where the density gradient is not 0.
inline constexpr size_t kCentre = (8 * 18 + 9) * 20 + 10;

// Densities (nz, ny, nx), x fastest, in [0, 1]: a soft ball off the centre with seeded noise
// inside it, 0 outside (the corners' bricks are empty).
inline std::vector<float> test_volume(int64_t nz, int64_t ny, int64_t nx, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<float> v(size_t(nz * ny * nx));
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x) {
        const double cx = (x + 0.5) / double(nx) - 0.55, cy = (y + 0.5) / double(ny) - 0.5,
                     cz = (z + 0.5) / double(nz) - 0.45;
        const double ball = std::max(0.0, 1.0 - 2.2 * std::sqrt(cx * cx + cy * cy + cz * cz));
        const double noise = double(rng()) / 4294967296.0;
        v[size_t((z * ny + y) * nx + x)] = float(ball * (0.8 + 0.2 * noise));
      }
  return v;
}

// `n` seeded values uniform in [lo, hi).
inline std::vector<double> uniform(size_t n, unsigned seed, double lo, double hi) {
  std::mt19937_64 rng(seed);
  std::vector<double> v(n);
  for (double& x : v) x = lo + (hi - lo) * (double(rng() >> 11) / 9007199254740992.0);
  return v;
}

// --- handles and arrays --------------------------------------------------------------------------

struct ArrayRelease {
  void operator()(ivr_array* a) const {
    EXPECT_EQ(ivr_array_release(a), IVR_OK) << ivr_last_error();
  }
};
using ArrayPtr = std::unique_ptr<ivr_array, ArrayRelease>;

inline std::vector<int64_t> shape_of(const ivr_array* a) {
  int rank = 0;
  int64_t shape[8];
  EXPECT_EQ(ivr_array_info(a, &rank, shape, nullptr), IVR_OK) << ivr_last_error();
  return std::vector<int64_t>(shape, shape + std::max(rank, 0));
}

inline size_t count_of(const std::vector<int64_t>& shape) {
  size_t n = 1;
  for (int64_t d : shape) n *= size_t(d);
  return n;
}

inline std::vector<float> floats(const ivr_array* a) {
  std::vector<float> v(count_of(shape_of(a)));
  EXPECT_EQ(ivr_array_download(a, v.data(), IVR_FLOAT32, v.size()), IVR_OK) << ivr_last_error();
  return v;
}

inline std::vector<double> doubles(const ivr_array* a) {
  std::vector<double> v(count_of(shape_of(a)));
  EXPECT_EQ(ivr_array_download(a, v.data(), IVR_FLOAT64, v.size()), IVR_OK) << ivr_last_error();
  return v;
}

// A new array of the context holding `values` (uploaded as float64: exact for float32 arrays
// of float values too).
inline ArrayPtr make_array(ivr_context* ctx, const std::vector<int64_t>& shape, ivr_dtype dtype,
                           const std::vector<double>& values) {
  ivr_array* a = nullptr;
  EXPECT_EQ(ivr_array_create(ctx, int(shape.size()), shape.data(), dtype, &a), IVR_OK)
      << ivr_last_error();
  if (a)
    EXPECT_EQ(ivr_array_upload(a, values.data(), IVR_FLOAT64, values.size()), IVR_OK)
        << ivr_last_error();
  return ArrayPtr(a);
}
inline ArrayPtr make_array(ivr_context* ctx, const std::vector<int64_t>& shape,
                           const std::vector<float>& values) {
  return make_array(ctx, shape, IVR_FLOAT32, std::vector<double>(values.begin(), values.end()));
}

inline ArrayPtr render_array(ivr_session* s) {
  ivr_array* a = nullptr;
  EXPECT_EQ(ivr_session_render(s, &a), IVR_OK) << ivr_last_error();
  return ArrayPtr(a);
}

inline std::vector<float> session_render(ivr_session* s) {
  const ArrayPtr a = render_array(s);
  return a ? floats(a.get()) : std::vector<float>{};
}

inline std::vector<int64_t> image_shape(ivr_session* s) {
  int64_t shape[4] = {};
  EXPECT_EQ(ivr_session_image_shape(s, shape), IVR_OK) << ivr_last_error();
  return std::vector<int64_t>(shape, shape + 4);
}

inline std::vector<int64_t> volume_shape(ivr_session* s) {
  int64_t shape[3] = {};
  EXPECT_EQ(ivr_session_volume_shape(s, shape), IVR_OK) << ivr_last_error();
  return std::vector<int64_t>(shape, shape + 3);
}

// The one-shot render (float32, the scene's step) of a scene.
inline std::vector<float> one_shot_render(ivr_context* ctx, const ivr_scene* scene) {
  int64_t shape[4] = {};
  EXPECT_EQ(ivr_scene_image_shape(scene, shape), IVR_OK) << ivr_last_error();
  std::vector<float> image(count_of(std::vector<int64_t>(shape, shape + 4)));
  EXPECT_EQ(ivr_render(ctx, scene, IVR_PRECISION_F32, 0, image.data(), image.size()), IVR_OK)
      << ivr_last_error();
  return image;
}

// --- comparisons ---------------------------------------------------------------------------------

// |got - want| <= abs_of_max * max|want| + rel * |want| element by element; NaN/Inf fail.
template <class A, class B>
void expect_close(const std::vector<A>& got, const std::vector<B>& want, double rel,
                  double abs_of_max, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  double scale = 0;
  for (B w : want) scale = std::max(scale, std::abs(double(w)));
  int reported = 0;
  for (size_t i = 0; i < got.size(); ++i) {
    const double g = double(got[i]), w = double(want[i]);
    const double tol = abs_of_max * scale + rel * std::abs(w);
    if (!std::isfinite(g) || !(std::abs(g - w) <= tol)) {
      ADD_FAILURE() << what << "[" << i << "]: " << g << " vs " << w << " (tolerance " << tol
                    << ", max |want| " << scale << ")";
      if (++reported == 5) return;
    }
  }
}

template <class T>
double max_abs(const std::vector<T>& v) {
  double m = 0;
  for (T x : v) m = std::max(m, std::abs(double(x)));
  return m;
}

// --- the fixture: a context, the one-shot scene and a session made from it -----------------------

class CApiSession : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(ivr_context_create(nullptr, &ctx_), IVR_OK) << ivr_last_error();
    ASSERT_NO_FATAL_FAILURE(make_scene(SceneParts{}, volume_.data(), IVR_FLOAT32, kShape, &scene_));
    ASSERT_EQ(ivr_session_create(ctx_, scene_, nullptr, &session_), IVR_OK) << ivr_last_error();
  }
  void TearDown() override {
    if (session_) EXPECT_EQ(ivr_session_release(session_), IVR_OK) << ivr_last_error();
    if (scene_) EXPECT_EQ(ivr_scene_release(scene_), IVR_OK) << ivr_last_error();
    if (ctx_) EXPECT_EQ(ivr_context_release(ctx_), IVR_OK) << ivr_last_error();
  }
  // A scene of ctx_ from `parts` with the densities `data` (dtype, shape (nz, ny, nx)).
  void make_scene(const SceneParts& parts, const void* data, ivr_dtype dtype,
                  const int64_t shape[3], ivr_scene** out) {
    ASSERT_EQ(ivr_scene_from_json(ctx_, parts.json().c_str(), nullptr, out), IVR_OK)
        << ivr_last_error() << "\n"
        << parts.json();
    ASSERT_EQ(ivr_scene_set_volume(*out, data, dtype, shape), IVR_OK) << ivr_last_error();
  }
  // The one-shot render of that scene.
  std::vector<float> reference_render(const SceneParts& parts, const void* data, ivr_dtype dtype,
                                      const int64_t shape[3]) {
    ivr_scene* s = nullptr;
    make_scene(parts, data, dtype, shape, &s);
    if (!s) return {};
    std::vector<float> image = one_shot_render(ctx_, s);
    EXPECT_EQ(ivr_scene_release(s), IVR_OK);
    return image;
  }
  // A target near the render: 0.9 × the image + seeded noise.
  std::vector<float> perturbed_target() {
    const std::vector<float> image = one_shot_render(ctx_, scene_);
    const std::vector<double> noise = uniform(image.size(), 7, -0.03, 0.03);
    std::vector<float> t(image.size());
    for (size_t i = 0; i < t.size(); ++i) t[i] = float(0.9 * image[i] + noise[i]);
    return t;
  }

  std::vector<float> volume_ = test_volume(kShape[0], kShape[1], kShape[2], 1);
  ivr_context* ctx_ = nullptr;
  ivr_scene* scene_ = nullptr;
  ivr_session* session_ = nullptr;
};

}  // namespace ivr::test
