// cli_jacobian_test.cpp — `ivr jacobian` (its array against ivr::tangents, its errors) and
// `ivr calibrate` (a model the planner reads back).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "adjoint/adjoint_support.hpp"
#include "ivr/calibrate.hpp"
#include "ivr/jacobian.hpp"
#include "reference/reference.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

class CliJacobian : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::vector<float> v(5 * 4 * 3);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(0.4 + 0.3 * std::sin(0.9 * double(i)));
    save_npy(dir_ + "/vol.npy", {5, 4, 3}, v.data());
    scene_path_ = write_file(dir_ + "/scene.json", R"({
      "volume": {"file": "vol.npy"}, "model": "emission_absorption",
      "tf": {"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0.1, 0.2, 0.3], "extinction": 0.5},
        {"density": 0.5, "color": [1.0, 0.6, 0.2], "extinction": 6.0}]},
      "background": [0.1, 0.2, 0.3],
      "cameras": [{"eye": [0.3, 0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
                   "width": 6, "height": 5}],
      "integrator": {"scheme": "midpoint", "step": 0.5, "min_transmittance": 0}})");
  }
  std::string dir_, scene_path_;
};

TEST_F(CliJacobian, WritesTheForwardModeJacobian) {
  const std::string out = dir_ + "/J.npy";
  const CliResult r =
      run_cli("jacobian " + scene_path_ + " --wrt camera,tf,voxels:7,20-21 -o " + out + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["mode"], "forward");
  EXPECT_EQ(j["parameters"].get<int>(), 7 + 8 + 3);
  EXPECT_EQ(j["groups"][1]["group"], "tf");
  EXPECT_EQ(j["groups"][1]["first"].get<int>(), 7);
  EXPECT_EQ(j["groups"][2]["group"], "voxels");
  const NpyArray a = load_npy(out);
  ASSERT_EQ(a.shape, (std::vector<std::size_t>{1, 5, 6, 4, 18}));

  const Scene scene = load_scene(scene_path_);
  std::vector<Parameter> params = parameters_of(scene, "camera");
  for (const char* g : {"tf", "voxels:7,20-21"})
    for (const Parameter& p : parameters_of(scene, g)) params.push_back(p);
  JacobianOptions o;
  o.jacobian = true;
  const Jacobian t = jacobian(device(), scene, params, nullptr, o);
  ASSERT_EQ(a.data.size(), t.jacobian.size());
  double scale = 0;
  for (float x : t.jacobian) scale = std::max(scale, double(std::abs(x)));
  ASSERT_GT(scale, 0);
  for (std::size_t i = 0; i < a.data.size(); ++i)
    ASSERT_NEAR(a.data[i], t.jacobian[i], 1e-6 * scale) << "element " << i;
}

TEST_F(CliJacobian, BadInputWritesNothing) {
  const std::string out = dir_ + "/J.npy";
  for (const std::string& args :
       {std::string("--wrt opacity -o ") + out, "--wrt voxels:999 -o " + out,
        "--wrt tf --precision f16 -o " + out, "--wrt tf -o " + dir_ + "/missing/J.npy",
        "--wrt tf --step -1 -o " + out}) {
    const CliResult r = run_cli("jacobian " + scene_path_ + " " + args);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << args;
  }
}

// With --precision f64 the image and the Jacobian reach their files unrounded: the image equals
// the midpoint rule's own discretisation evaluated in double precision (reference/) to
// 1e-12, which float32 storage (~3e-8 here) could not, and the Jacobian with respect to the
// background holds its closed form, d pixel_c / d background_c = T = 1 - alpha, from the files.
TEST_F(CliJacobian, Float64FilesKeepTheImageAndTheJacobianUnrounded) {
  const std::string image_path = dir_ + "/image.npy", jacobian_path = dir_ + "/J.npy";
  CliResult r = run_cli("render " + scene_path_ + " --precision f64 -o " + image_path);
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_cli("jacobian " + scene_path_ + " --wrt background --precision f64 -o " + jacobian_path);
  ASSERT_EQ(r.status, 0) << r.err;
  const NpyArray image = load_npy(image_path), jacobian = load_npy(jacobian_path);
  EXPECT_EQ(image.dtype, "float64");
  EXPECT_EQ(jacobian.dtype, "float64");
  ASSERT_EQ(image.shape, (std::vector<std::size_t>{1, 5, 6, 4}));
  ASSERT_EQ(jacobian.shape, (std::vector<std::size_t>{1, 5, 6, 4, 3}));

  const Scene scene = load_scene(scene_path_);
  const std::vector<double> want =
      reference::render_midpoint(scene, 0.5 * reference::min_voxel_edge(scene));
  ASSERT_EQ(want.size(), image.data.size());
  double worst = 0;
  std::size_t unrounded = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    worst = std::max(worst, std::abs(image.data[i] - want[i]));
    unrounded += double(float(image.data[i])) != image.data[i];
  }
  std::printf("[ measured ] f64 image file vs double midpoint reference: max|diff| %.3g\n", worst);
  EXPECT_LE(worst, 1e-12);
  EXPECT_GT(unrounded, want.size() / 2);

  for (std::size_t p = 0; p < 5 * 6; ++p) {
    const double transmittance = 1 - image.data[p * 4 + 3];
    for (std::size_t c = 0; c < 4; ++c)
      for (std::size_t k = 0; k < 3; ++k) {
        const double got = jacobian.data[(p * 4 + c) * 3 + k];
        EXPECT_NEAR(got, c == k ? transmittance : 0.0, 1e-14) << "pixel " << p << " c " << c
                                                              << " background " << k;
      }
  }

  // float32 stays the default.
  r = run_cli("render " + scene_path_ + " -o " + image_path);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(load_npy(image_path).dtype, "float32");
}

TEST_F(CliJacobian, CalibrateWritesAModelThePlannerReads) {
  const std::string out = dir_ + "/cost.json";
  const CliResult r = run_cli("calibrate --volume 8 --image 8 --repeats 1 -o " + out + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["path"], out);
  EXPECT_EQ(j["lanes"].size(), 6u);
  const CostModel m = read_cost_model(out);
  EXPECT_GT(m.forward_base, 0);
  EXPECT_GT(m.forward_per_lane, 0);
  EXPECT_GT(m.adjoint, 0);
  EXPECT_DOUBLE_EQ(m.adjoint, j["adjoint"].get<double>());
  const CliResult bad = run_cli("calibrate --volume 2 -o " + out);
  EXPECT_NE(bad.status, 0);
  EXPECT_TRUE(has(bad.err, "at least 4")) << bad.err;
}

}  // namespace
}  // namespace ivr::test
