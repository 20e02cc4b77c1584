// c_api_tomo_test.cpp — the C API's tomography (ivr_project, ivr_backproject, ivr_tomo,
// ivr_lines_from_intensities, ivr_phantom) and its C++ wrappers: a matched pair by the
// dot-product test, results equal to the core's, a progress callback that stops the solver, and
// an error status with a message (and nothing written) for every bad argument.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "ivr/ivr.h"
#include "ivr/ivr.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// An anisotropic Shepp–Logan grid (X, Y, Z) = (8, 10, 12) seen by two parallel-beam views and a
// cone-beam one, 9 x 7 pixels each.
const char* const kScene = R"({
  "volume": {"synthetic": "shepp_logan", "dims": [8, 10, 12]}, "model": "absorption",
  "tf": {"type": "identity", "extinction_scale": 2, "color_scale": 1}, "background": 0.8,
  "cameras": [
    {"eye": [2, 0.1, 0.05], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
     "projection": "orthographic", "ortho_height": 1.3},
    {"eye": [0.2, 2, -0.3], "target": [0, 0, 0], "up": [0, 0, 1], "width": 9, "height": 7,
     "projection": "orthographic", "ortho_height": 1.3},
    {"eye": [0.3, -0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "width": 9, "height": 7,
     "fov_y": 45}]})";
constexpr std::size_t kVoxels = 8 * 10 * 12, kRays = 3 * 9 * 7;

std::vector<float> random_values(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> v(n);
  for (float& x : v) x = u(rng);
  return v;
}

double dot(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += double(a[i]) * b[i];
  return s;
}

class CApiTomo : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(ivr_context_create(nullptr, &ctx_), IVR_OK) << ivr_last_error();
    ASSERT_EQ(ivr_scene_from_json(ctx_, kScene, nullptr, &scene_), IVR_OK) << ivr_last_error();
  }
  void TearDown() override {
    if (scene_) EXPECT_EQ(ivr_scene_release(scene_), IVR_OK);
    if (ctx_) EXPECT_EQ(ivr_context_release(ctx_), IVR_OK);
  }
  std::vector<float> project(const std::vector<float>* volume, ivr_precision p) {
    std::vector<float> lines(kRays, -1.0f);
    EXPECT_EQ(ivr_project(ctx_, scene_, p, volume ? volume->data() : nullptr,
                          volume ? volume->size() : 0, lines.data(), lines.size()),
              IVR_OK)
        << ivr_last_error();
    return lines;
  }
  std::vector<float> backproject(const std::vector<float>& lines, ivr_precision p) {
    std::vector<float> volume(kVoxels, -1.0f);
    EXPECT_EQ(
        ivr_backproject(ctx_, scene_, p, lines.data(), lines.size(), volume.data(), volume.size()),
        IVR_OK)
        << ivr_last_error();
    return volume;
  }
  ivr_context* ctx_ = nullptr;
  ivr_scene* scene_ = nullptr;
};

// The status and a message naming the function.
void expect_error(ivr_status got, ivr_status want, const char* function,
                  const std::string& part = "") {
  EXPECT_EQ(got, want) << ivr_status_string(got) << ": " << ivr_last_error();
  const std::string message = ivr_last_error();
  EXPECT_NE(message.find(function), std::string::npos) << message;
  EXPECT_NE(message.find(part), std::string::npos) << message << " (expected '" << part << "')";
}

TEST_F(CApiTomo, ProjectorIsAMatchedPairThroughTheCApi) {
  const std::vector<float> x = random_values(kVoxels, 1), y = random_values(kRays, 2);
  for (const ivr_precision p : {IVR_PRECISION_F32, IVR_PRECISION_F64}) {
    if (p == IVR_PRECISION_F64 && !device().info().fp64) continue;
    const double nx_y = dot(project(&x, p), y), x_nty = dot(x, backproject(y, p));
    const double mismatch = std::abs(nx_y - x_nty) / std::max(std::abs(nx_y), std::abs(x_nty));
    EXPECT_LE(mismatch, p == IVR_PRECISION_F32 ? 1e-5 : 1e-6)
        << "<Nx, y> = " << nx_y << ", <x, N^T y> = " << x_nty;
  }
}

TEST_F(CApiTomo, ProjectEqualsTheCoreWithTheScenesOwnOrAGivenVolume) {
  const Scene scene = parse_scene(kScene, ".");
  const Projector core(device(), scene, Precision::f32);
  const std::vector<double> want =
      core.project({scene.volume.data.begin(), scene.volume.data.end()});
  const std::vector<float> own = project(nullptr, IVR_PRECISION_F32);
  const std::vector<float> given = project(&scene.volume.data, IVR_PRECISION_F32);
  ASSERT_EQ(own.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(own[i], float(want[i])) << "ray " << i;
    EXPECT_EQ(given[i], own[i]) << "ray " << i;
  }
  EXPECT_GT(*std::max_element(own.begin(), own.end()), 0.1f);
}

// Counts the calls and stops after the third.
int stop_after_three(const ivr_tomo_iteration* it, void* user) {
  auto* calls = static_cast<std::vector<ivr_tomo_iteration>*>(user);
  calls->push_back(*it);
  return it->iteration < 3;
}

TEST_F(CApiTomo, TomoStopsWhenTheCallbackSaysSoAndReportsTheHistory) {
  const std::vector<float> lines = project(nullptr, IVR_PRECISION_F32);
  ivr_tomo_options o;
  ASSERT_EQ(ivr_tomo_options_init(&o), IVR_OK);
  EXPECT_EQ(o.solver, IVR_SOLVER_CGLS);
  EXPECT_EQ(o.iterations, 50);
  EXPECT_EQ(o.relaxation, 1.0);
  o.iterations = 20;
  std::vector<float> volume(kVoxels, NAN);
  std::vector<ivr_tomo_iteration> history(20), calls;
  ivr_tomo_summary summary{};
  ASSERT_EQ(ivr_tomo(ctx_, scene_, &o, lines.data(), lines.size(), volume.data(), volume.size(),
                     stop_after_three, &calls, history.data(), history.size(), &summary),
            IVR_OK)
      << ivr_last_error();
  ASSERT_EQ(calls.size(), 3u);
  EXPECT_EQ(summary.iterations, 3);
  EXPECT_STREQ(summary.stop_reason, "interrupted");
  EXPECT_EQ(summary.residual, calls.back().residual);
  EXPECT_GT(summary.seconds, 0);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(history[k].iteration, k + 1);
    EXPECT_EQ(history[k].residual, calls[k].residual);
    EXPECT_EQ(history[k].seconds, calls[k].seconds);
    if (k > 0) EXPECT_LT(history[k].residual, history[k - 1].residual);
  }
  for (float v : volume) ASSERT_TRUE(std::isfinite(v));

  // Without a callback, history or summary: every iteration runs, and the C++ wrapper agrees.
  std::vector<float> all(kVoxels);
  ASSERT_EQ(ivr_tomo(ctx_, scene_, &o, lines.data(), lines.size(), all.data(), all.size(), nullptr,
                     nullptr, nullptr, 0, nullptr),
            IVR_OK)
      << ivr_last_error();
  api::Context cpp;
  api::Scene s = cpp.scene_from_json(kScene);
  api::TomoOptions options;
  options.iterations = 20;
  const api::TomoResult r = cpp.tomo(s, lines, options);
  EXPECT_EQ(r.history.size(), 20u);
  EXPECT_EQ(r.stop_reason, "iterations");
  EXPECT_EQ(r.volume.shape, (std::vector<int64_t>{12, 10, 8}));
  // The back-projection's atomic adds may sum in another order: equal up to rounding.
  ASSERT_EQ(r.volume.values.size(), all.size());
  const float scale = *std::max_element(all.begin(), all.end());
  for (std::size_t i = 0; i < all.size(); ++i)
    ASSERT_NEAR(r.volume.values[i], all[i], 1e-4 * scale) << "voxel " << i;
  EXPECT_LT(r.residual, 0.1 * r.history.front().residual);
}

TEST_F(CApiTomo, CppWrappersShapesPhantomIntensitiesAndCallbackExceptions) {
  api::Context cpp;
  api::Scene s = cpp.scene_from_json(kScene);
  const api::Array<float> p = cpp.project(s);
  EXPECT_EQ(p.shape, (std::vector<int64_t>{3, 7, 9, 1}));
  const api::Array<float> b = cpp.backproject(s, p.values);
  EXPECT_EQ(b.shape, (std::vector<int64_t>{12, 10, 8}));

  // I = I_in exp(-a p) back to p (background 0.8, extinction_scale 2).
  std::vector<float> intensities(p.size());
  for (std::size_t i = 0; i < p.size(); ++i)
    intensities[i] = float(0.8 * std::exp(-2.0 * p.values[i]));
  const api::Array<float> back = api::lines_from_intensities(s, intensities);
  EXPECT_EQ(back.shape, p.shape);
  for (std::size_t i = 0; i < p.size(); ++i) EXPECT_NEAR(back.values[i], p.values[i], 1e-5);

  const api::Array<float> phantom = api::phantom("shepp-logan", 6);
  EXPECT_EQ(phantom.shape, (std::vector<int64_t>{6, 6, 6}));
  EXPECT_EQ(phantom.values, ivr::phantom("shepp-logan", 6).data);
  EXPECT_EQ(api::phantom("ellipsoids", 5, 7).values, ivr::phantom("ellipsoids", 5, 7).data);
  EXPECT_EQ(api::phantom("shepp-logan", 6, 1, 3).values, ivr::phantom("shepp-logan", 6, 1, 3).data);

  int calls = 0;
  try {
    cpp.tomo(s, p.values, {}, [&](const ivr_tomo_iteration& it) -> bool {
      ++calls;
      if (it.iteration == 2) throw std::runtime_error("stop here");
      return true;
    });
    ADD_FAILURE() << "the callback's exception was not rethrown";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "stop here");
  }
  EXPECT_EQ(calls, 2);
}

TEST_F(CApiTomo, ErrorsHaveAStatusAndAMessage) {
  std::vector<float> lines = project(nullptr, IVR_PRECISION_F32), volume(kVoxels, 7.0f);
  const std::vector<float> small(kVoxels - 1);
  const ivr_precision f32 = IVR_PRECISION_F32;
  // NULL pointers and handles.
  expect_error(ivr_project(nullptr, scene_, f32, nullptr, 0, lines.data(), lines.size()),
               IVR_ERROR_NULL_POINTER, "ivr_project", "context");
  expect_error(ivr_project(ctx_, nullptr, f32, nullptr, 0, lines.data(), lines.size()),
               IVR_ERROR_NULL_POINTER, "ivr_project", "scene");
  expect_error(ivr_project(ctx_, scene_, f32, nullptr, 0, nullptr, lines.size()),
               IVR_ERROR_NULL_POINTER, "ivr_project", "lines");
  expect_error(ivr_backproject(ctx_, scene_, f32, nullptr, kRays, volume.data(), kVoxels),
               IVR_ERROR_NULL_POINTER, "ivr_backproject", "lines");
  expect_error(ivr_tomo(ctx_, scene_, nullptr, lines.data(), kRays, nullptr, kVoxels, nullptr,
                        nullptr, nullptr, 0, nullptr),
               IVR_ERROR_NULL_POINTER, "ivr_tomo", "volume");
  expect_error(ivr_tomo_options_init(nullptr), IVR_ERROR_NULL_POINTER, "ivr_tomo_options_init");
  // Wrong sizes: inputs exactly, outputs at least.
  expect_error(ivr_project(ctx_, scene_, f32, small.data(), small.size(), lines.data(), kRays),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_project", "959 floats; the scene's grid has 960");
  expect_error(ivr_project(ctx_, scene_, f32, nullptr, 0, lines.data(), kRays - 1),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_project", "the scene has 189 rays");
  expect_error(ivr_backproject(ctx_, scene_, f32, lines.data(), kRays + 1, volume.data(), kVoxels),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_backproject", "190 floats");
  expect_error(ivr_backproject(ctx_, scene_, f32, lines.data(), kRays, volume.data(), 3),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_backproject", "960 voxels");
  expect_error(ivr_tomo(ctx_, scene_, nullptr, lines.data(), kRays - 9, volume.data(), kVoxels,
                        nullptr, nullptr, nullptr, 0, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_tomo", "180 floats; the scene has 189 rays");
  ivr_tomo_iteration history[4];
  expect_error(ivr_tomo(ctx_, scene_, nullptr, lines.data(), kRays, volume.data(), kVoxels, nullptr,
                        nullptr, history, 4, nullptr),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_tomo", "up to 50 iterations");
  // Bad values and options.
  lines[100] = NAN;
  expect_error(ivr_backproject(ctx_, scene_, f32, lines.data(), kRays, volume.data(), kVoxels),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_backproject", "lines[100] is not finite");
  expect_error(ivr_tomo(ctx_, scene_, nullptr, lines.data(), kRays, volume.data(), kVoxels, nullptr,
                        nullptr, nullptr, 0, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_tomo", "lines[100]");
  lines[100] = 0;
  ivr_tomo_options o;
  ivr_tomo_options_init(&o);
  o.tv = -1;
  expect_error(ivr_tomo(ctx_, scene_, &o, lines.data(), kRays, volume.data(), kVoxels, nullptr,
                        nullptr, nullptr, 0, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_tomo", "tv must be >= 0");
  ivr_tomo_options_init(&o);
  o.solver = ivr_solver(7);
  expect_error(ivr_tomo(ctx_, scene_, &o, lines.data(), kRays, volume.data(), kVoxels, nullptr,
                        nullptr, nullptr, 0, nullptr),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_tomo", "options.solver 7 is unknown (IVR_SOLVER_CGLS,");
  expect_error(ivr_project(ctx_, scene_, ivr_precision(3), nullptr, 0, lines.data(), kRays),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_project", "unknown precision 3");
  for (float v : volume) ASSERT_EQ(v, 7.0f) << "an output was written despite the error";

  // Intensities and phantoms.
  std::vector<float> intensities(kRays, 0.5f), out(kRays);
  intensities[9 * 7 + 9 * 2 + 4] = 0;  // view 1, y 2, x 4
  expect_error(ivr_lines_from_intensities(scene_, intensities.data(), kRays, 0, out.data(), kRays),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_lines_from_intensities", "view 1, y 2, x 4");
  EXPECT_EQ(ivr_lines_from_intensities(scene_, intensities.data(), kRays, 0.01, out.data(), kRays),
            IVR_OK)
      << ivr_last_error();
  expect_error(ivr_lines_from_intensities(scene_, intensities.data(), 5, 0, out.data(), kRays),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_lines_from_intensities", "5 floats");
  std::vector<float> cube(64);
  expect_error(ivr_phantom("shepp-logan", 5, 1, 1, cube.data(), cube.size()),
               IVR_ERROR_BUFFER_TOO_SMALL, "ivr_phantom", "125 voxels");
  expect_error(ivr_phantom("cube", 4, 1, 1, cube.data(), cube.size()), IVR_ERROR_INVALID_ARGUMENT,
               "ivr_phantom", "shepp-logan");
  expect_error(ivr_phantom(nullptr, 4, 1, 1, cube.data(), cube.size()), IVR_ERROR_NULL_POINTER,
               "ivr_phantom", "name");
  expect_error(ivr_phantom("shepp-logan", 0, 1, 1, cube.data(), cube.size()),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_phantom", "1 .. 1024");
  expect_error(ivr_phantom("shepp-logan", 4, 1, 0, cube.data(), cube.size()),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_phantom", "supersample");

  // A scene without a volume has no grid.
  ivr_scene* bare = nullptr;
  ASSERT_EQ(ivr_scene_from_json(ctx_, R"({"model": "absorption", "cameras": [{"eye": [0, 0, 2],
      "target": [0, 0, 0], "up": [0, 1, 0], "width": 4, "height": 4}]})",
                                nullptr, &bare),
            IVR_OK)
      << ivr_last_error();
  expect_error(ivr_backproject(ctx_, bare, f32, lines.data(), 16, volume.data(), kVoxels),
               IVR_ERROR_INVALID_ARGUMENT, "ivr_backproject", "no volume");
  EXPECT_EQ(ivr_scene_release(bare), IVR_OK);
}

}  // namespace
}  // namespace ivr::test
