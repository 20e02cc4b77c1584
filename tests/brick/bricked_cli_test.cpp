// bricked_cli_test.cpp — the out-of-core render from the command line: --volume-brick and
// IVR_DEVICE_MEMORY_LIMIT choose bricks, --json reports them, the image is the in-core one, and a
// command that runs in core only fails clearly under a cap it cannot keep.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstring>

#include "io/npy.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

std::vector<float> floats_of(const std::string& path) {
  const volfile::TypedArray a = volfile::read_npy(path);
  std::vector<float> v((a.bytes.size() - a.offset) / sizeof(float));
  std::memcpy(v.data(), a.bytes.data() + a.offset, v.size() * sizeof(float));
  return v;
}

std::vector<double> doubles_of(const std::string& path) {
  const volfile::TypedArray a = volfile::read_npy(path);
  if (a.type == volfile::ScalarType::float32) {
    const std::vector<float> f = floats_of(path);
    return {f.begin(), f.end()};
  }
  std::vector<double> v((a.bytes.size() - a.offset) / sizeof(double));
  std::memcpy(v.data(), a.bytes.data() + a.offset, v.size() * sizeof(double));
  return v;
}

TEST(BrickedCli, JsonReportsBricksAndTheImageIsTheInCoreOne) {
  const std::string dir = temp_dir("bricked_cli");
  const std::string scene = write_file(dir + "/scene.json", R"({
    "volume": {"synthetic": "sphere", "dims": [48, 48, 48]}, "model": "emission_absorption",
    "tf": {"type": "piecewise_linear", "points": [
      {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0},
      {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
    "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 24, "height": 24},
                {"eye": [-1.4, 0.3, -1.0], "width": 24, "height": 24}],
    "integrator": {"scheme": "trapezoid", "step": 0.5}})");
  CliResult r = run_cli("render '" + scene + "' -o '" + dir + "/a.npy' --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["bricks"], 1) << r.out;
  r = run_cli("render '" + scene + "' -o '" + dir + "/b.npy' --json --volume-brick 16");
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["bricks"], 27) << r.out;  // 47 cells per axis in runs of 16
  EXPECT_EQ(j["brick_edge"], 16);
  // The volume alone is 432 KiB: under a 300 KiB cap the render splits it by itself.
  r = run_cli("render '" + scene + "' -o '" + dir + "/c.npy' --json", "IVR_DEVICE_MEMORY_LIMIT=300K");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_GT(nlohmann::json::parse(r.out)["bricks"].get<int>(), 1) << r.out;
  const std::vector<float> a = floats_of(dir + "/a.npy");
  for (const char* other : {"/b.npy", "/c.npy"}) {
    const std::vector<float> b = floats_of(dir + other);
    ASSERT_EQ(a.size(), b.size());
    float worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
    EXPECT_LE(worst, 1e-5f) << other;
  }
  // The density and TF gradients under the cap run in bricks (the adjoint's sweeps), the camera's
  // too (forward lanes, as many a pass as fit beside the bricks) and equals the in-core one.
  r = run_cli("gradient '" + scene + "' --target '" + dir + "/a.npy' --wrt density --scheme midpoint -o '" +
                  dir + "/g' --json",
              "IVR_DEVICE_MEMORY_LIMIT=600K");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_GT(nlohmann::json::parse(r.out)["bricks"].get<int>(), 1) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir + "/g_density.npy"));
  r = run_cli("gradient '" + scene + "' --target '" + dir + "/a.npy' --wrt tf --scheme midpoint -o '" +
                  dir + "/t' --json",
              "IVR_DEVICE_MEMORY_LIMIT=600K");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_GT(nlohmann::json::parse(r.out)["bricks"].get<int>(), 1) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir + "/t_tf.npy"));
  r = run_cli("gradient '" + scene + "' --target '" + dir +
                  "/a.npy' --wrt camera --scheme midpoint --precision f64 -o '" + dir +
                  "/h' --json",
              "IVR_DEVICE_MEMORY_LIMIT=900K");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_GT(nlohmann::json::parse(r.out)["bricks"].get<int>(), 1) << r.out;
  r = run_cli("gradient '" + scene + "' --target '" + dir +
              "/a.npy' --wrt camera --scheme midpoint --precision f64 -o '" + dir + "/hc' --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["bricks"].get<int>(), 1) << r.out;
  {
    const std::vector<double> want = doubles_of(dir + "/hc_camera.npy"),
                              got = doubles_of(dir + "/h_camera.npy");
    ASSERT_EQ(want.size(), got.size());
    double scale = 0, worst = 0;
    for (std::size_t i = 0; i < want.size(); ++i) {
      scale = std::max(scale, std::abs(want[i]));
      worst = std::max(worst, std::abs(want[i] - got[i]));
    }
    EXPECT_GT(scale, 0.0);
    EXPECT_LE(worst, 1e-10 * scale);
  }
  r = run_cli("render '" + scene + "' -o '" + dir + "/d.npy' --volume-brick 0");
  EXPECT_NE(r.status, 0);
  r = run_cli("render '" + scene + "' -o '" + dir + "/e.npy'", "IVR_DEVICE_MEMORY_LIMIT=much");
  EXPECT_NE(r.status, 0);
  EXPECT_TRUE(has(r.err, "IVR_DEVICE_MEMORY_LIMIT: 'much'")) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/e.npy"));
}

}  // namespace
}  // namespace ivr::test
