// cli_gradient_test.cpp — `ivr gradient`: the files it writes, their shapes and values against
// ivr::gradient(), and one clear error with nothing written for every bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

class CliGrad : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    // (Z, Y, X) = (6, 5, 4): every axis differs, so a transposed gradient cannot pass.
    std::vector<float> v(6 * 5 * 4);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(0.4 + 0.3 * std::sin(0.7 * double(i)));
    save_npy(dir_ + "/vol.npy", {6, 5, 4}, v.data());
    scene_ = json::parse(R"({
      "volume": {"file": "vol.npy"}, "model": "emission_absorption",
      "tf": {"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0.1, 0.2, 0.3], "extinction": 0.5},
        {"density": 0.3, "color": [1.0, 0.6, 0.2], "extinction": 4.0},
        {"density": 0.8, "color": [0.3, 0.9, 0.7], "extinction": 9.0}]},
      "background": [0.1, 0.2, 0.3],
      "cameras": [{"eye": [0.3, 0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
                   "width": 8, "height": 7}],
      "integrator": {"scheme": "midpoint", "step": 0.5}})");
    write_scene();
    target_ = write_target({1, 7, 8, 4}, 0.25f);
  }

  void write_scene() { scene_path_ = write_file(dir_ + "/scene.json", scene_.dump()); }

  // A constant target of the given shape (optionally with one bad value at `bad_at`).
  std::string write_target(const std::vector<std::size_t>& shape, float value,
                           std::size_t bad_at = 0, float bad = 0) {
    std::size_t n = 1;
    for (std::size_t s : shape) n *= s;
    std::vector<float> t(n, value);
    if (bad_at > 0) t[bad_at] = bad;
    const std::string path = dir_ + "/target.npy";
    save_npy(path, shape, t.data());
    return path;
  }

  CliResult grad(const std::string& extra) {
    return run_cli("gradient " + scene_path_ + " --target " + target_ + " -o " + prefix() + " " +
                   extra);
  }
  std::string prefix() const { return dir_ + "/g"; }

  // Names in the folder that belong to the outputs or to their temporaries.
  std::vector<std::string> written() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string n = e.path().filename().string();
      if (n.rfind("g_", 0) == 0 || n.rfind(".g_", 0) == 0 || n.find(".tmp") != std::string::npos)
        names.push_back(n);
    }
    std::sort(names.begin(), names.end());
    return names;
  }

  // Runs `ivr gradient` with `extra` and checks the failure contract; returns stderr.
  std::string expect_failure(const std::string& extra) {
    const CliResult r = grad(extra);
    EXPECT_NE(r.status, 0) << r.out;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    EXPECT_TRUE(written().empty()) << "written despite the error: " << written().front();
    return r.err;
  }

  std::string dir_, scene_path_, target_;
  json scene_;
};

TEST_F(CliGrad, WritesEveryAskedGroupWithItsShape) {
  const CliResult r = grad("--wrt density,tf,background --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  for (const char* key : {"loss", "mode", "parameters", "seconds", "device_bytes", "device",
                          "precision", "plan", "atomics", "outputs"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["mode"], "adjoint");
  EXPECT_EQ(j["precision"], "f32");
  EXPECT_EQ(j["parameters"].get<int>(), 6 * 5 * 4 + 3 * 4 + 3);
  EXPECT_GT(j["loss"].get<double>(), 0);
  EXPECT_GT(j["seconds"].get<double>(), 0);
  EXPECT_GT(j["device_bytes"].get<double>(), 0);
  for (const char* key : {"forward_seconds", "adjoint_seconds", "forward_passes", "cost_model"})
    EXPECT_TRUE(j["plan"].contains(key)) << key;
  EXPECT_GT(j["plan"]["forward_seconds"].get<double>(), j["plan"]["adjoint_seconds"].get<double>());
  EXPECT_EQ(j["outputs"].size(), 3u);
  EXPECT_EQ(written(), (std::vector<std::string>{"g_background.npy", "g_density.npy", "g_tf.npy"}));

  const NpyArray density = load_npy(prefix() + "_density.npy");
  EXPECT_EQ(density.shape, (std::vector<std::size_t>{6, 5, 4}));
  const NpyArray tf = load_npy(prefix() + "_tf.npy");
  EXPECT_EQ(tf.shape, (std::vector<std::size_t>{3, 4}));
  const NpyArray background = load_npy(prefix() + "_background.npy");
  EXPECT_EQ(background.shape, (std::vector<std::size_t>{3}));
  for (const NpyArray* a : {&density, &tf, &background}) {
    EXPECT_TRUE(
        std::all_of(a->data.begin(), a->data.end(), [](double x) { return std::isfinite(x); }));
    EXPECT_TRUE(std::any_of(a->data.begin(), a->data.end(), [](double x) { return x != 0; }));
  }
}

TEST_F(CliGrad, WritesOnlyTheAskedGroups) {
  CliResult r = grad("--wrt tf");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(written(), (std::vector<std::string>{"g_tf.npy"}));
  // Without --json: one human line, naming the loss and the output.
  EXPECT_EQ(r.out.find('\n'), r.out.size() - 1) << r.out;
  EXPECT_TRUE(has(r.out, "mse loss")) << r.out;
  EXPECT_TRUE(has(r.out, prefix() + "_tf.npy")) << r.out;
  fs::remove(prefix() + "_tf.npy");
  r = grad("--wrt background,background --loss l1 --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["parameters"].get<int>(), 3);
  EXPECT_EQ(written(), (std::vector<std::string>{"g_background.npy"}));
}

TEST_F(CliGrad, DensityFileEqualsTheLibraryGradient) {
  const CliResult r = grad("--wrt density --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const NpyArray file = load_npy(prefix() + "_density.npy");

  const Scene scene = load_scene(scene_path_);
  Image target;
  target.views = 1;
  target.height = 7;
  target.width = 8;
  target.channels = 4;
  target.pixels.assign(7 * 8 * 4, 0.25f);
  const AdjointGradient g = adjoint(device(), scene, target, {});
  ASSERT_EQ(file.data.size(), g.density.size());
  double largest = 0;
  for (float x : g.density) largest = std::max(largest, double(std::abs(x)));
  ASSERT_GT(largest, 0);
  for (std::size_t i = 0; i < g.density.size(); ++i)  // the atomic sums may differ in order
    EXPECT_NEAR(file.data[i], g.density[i], 1e-5 * largest) << "voxel " << i;
  EXPECT_NEAR(json::parse(r.out)["loss"].get<double>(), g.loss, 1e-6 * g.loss);
}

// --precision f64 writes float64 files, unrounded: values float32 cannot hold, within float32
// accuracy of the default's float32 file.
TEST_F(CliGrad, Float64PrecisionWritesFloat64Files) {
  ASSERT_EQ(grad("--wrt density,tf --mode adjoint --precision f64").status, 0);
  const NpyArray d64 = load_npy(prefix() + "_density.npy"), t64 = load_npy(prefix() + "_tf.npy");
  EXPECT_EQ(d64.dtype, "float64");
  EXPECT_EQ(t64.dtype, "float64");
  std::size_t unrounded = 0;
  for (double x : d64.data) unrounded += double(float(x)) != x;
  EXPECT_GT(unrounded, d64.data.size() / 2);
  ASSERT_EQ(grad("--wrt density --mode adjoint").status, 0);
  const NpyArray d32 = load_npy(prefix() + "_density.npy");
  EXPECT_EQ(d32.dtype, "float32");
  ASSERT_EQ(d32.data.size(), d64.data.size());
  double largest = 0;
  for (double x : d64.data) largest = std::max(largest, std::abs(x));
  for (std::size_t i = 0; i < d64.data.size(); ++i)
    EXPECT_NEAR(d32.data[i], d64.data[i], 1e-4 * largest) << "voxel " << i;
}

TEST_F(CliGrad, AcceptsTargetsWithoutTheUnitAxes) {
  target_ = write_target({7, 8, 4}, 0.25f);  // one view: (H, W, C)
  CliResult r = grad("--wrt density --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const double loss = json::parse(r.out)["loss"].get<double>();
  target_ = write_target({1, 7, 8, 4}, 0.25f);
  r = grad("--wrt density --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_DOUBLE_EQ(json::parse(r.out)["loss"].get<double>(), loss);

  scene_["model"] = "absorption";  // one channel: (H, W), and (views, H, W) with two views
  scene_["tf"] = json::parse(R"({"type": "identity", "extinction_scale": 3})");
  scene_.erase("background");
  write_scene();
  target_ = write_target({7, 8}, 0.5f);
  r = grad("--wrt density,tf,background --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(load_npy(prefix() + "_tf.npy").shape, (std::vector<std::size_t>{1, 2}));
  EXPECT_EQ(load_npy(prefix() + "_background.npy").shape, (std::vector<std::size_t>{1}));
  scene_["cameras"].push_back(scene_["cameras"][0]);
  scene_["cameras"][1]["eye"] = {0, 2, 0.5};
  write_scene();
  target_ = write_target({2, 7, 8}, 0.5f);
  r = grad("--wrt density --precision f64 --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["precision"], "f64");
}

TEST_F(CliGrad, TargetShapeDiffersFromTheRender) {
  target_ = write_target({1, 7, 8, 3}, 0.25f);
  std::string err = expect_failure("--wrt density");
  EXPECT_TRUE(has(err, "(1, 7, 8, 3)") && has(err, "(1, 7, 8, 4)")) << err;
  target_ = write_target({8, 7, 4}, 0.25f);  // H and W swapped
  err = expect_failure("--wrt density");
  EXPECT_TRUE(has(err, "(8, 7, 4)") && has(err, "(1, 7, 8, 4)")) << err;
  target_ = write_target({7, 8}, 0.25f);  // (H, W) only for one channel
  err = expect_failure("--wrt density");
  EXPECT_TRUE(has(err, "(7, 8)") && has(err, "(1, 7, 8, 4)")) << err;
}

TEST_F(CliGrad, NonFiniteTargetNamesTheIndex) {
  const std::size_t at = ((0 * 7 + 2) * 8 + 5) * 4 + 1;  // (0, 2, 5, 1)
  for (float bad :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    target_ = write_target({1, 7, 8, 4}, 0.25f, at, bad);
    const std::string err = expect_failure("--wrt density");
    EXPECT_TRUE(has(err, "(0, 2, 5, 1)")) << err;
    EXPECT_TRUE(has(err, "non-finite")) << err;
  }
}

TEST_F(CliGrad, UnknownGroupsAndBadVoxelLists) {
  std::string err = expect_failure("--wrt density,opacity");
  EXPECT_TRUE(has(err, "unknown parameter group 'opacity'")) << err;
  EXPECT_TRUE(has(err, "density, tf, tf_points, scales, background, camera, step")) << err;
  err = expect_failure("--wrt density,,tf");
  EXPECT_TRUE(has(err, "empty group")) << err;
  EXPECT_TRUE(has(expect_failure("--wrt voxels:7-3"), "empty")) << err;
  EXPECT_TRUE(has(expect_failure("--wrt voxels:1,120"), "outside the volume's 120 voxels"));
  EXPECT_TRUE(has(expect_failure("--wrt voxels:a"), "indices and ranges"));
  EXPECT_TRUE(has(expect_failure("--wrt scales"), "identity"));
  // A group only forward mode computes, asked of the adjoint.
  EXPECT_TRUE(
      has(expect_failure("--wrt tf_points --mode adjoint"),
          "mode adjoint cannot compute group 'tf_points'"));
  EXPECT_TRUE(has(expect_failure("--wrt density --mode sideways"), "unknown mode 'sideways'"));
}

// Forward and adjoint write the same files (within float32 rounding); groups only forward mode
// computes go forward under auto, with their shapes.
TEST_F(CliGrad, ForwardAndAdjointModes) {
  CliResult r = grad("--wrt tf,voxels:3,10-12 --mode forward --json");
  ASSERT_EQ(r.status, 0) << r.err;
  json j = json::parse(r.out);
  EXPECT_EQ(j["mode"], "forward");
  EXPECT_EQ(j["parameters"].get<int>(), 12 + 4);
  const NpyArray tf_forward = load_npy(prefix() + "_tf.npy");
  const NpyArray voxels_forward = load_npy(prefix() + "_voxels.npy");
  EXPECT_EQ(voxels_forward.shape, (std::vector<std::size_t>{4}));
  r = grad("--wrt tf,voxels:3,10-12 --mode adjoint --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["mode"], "adjoint");
  for (const char* group : {"tf", "voxels"}) {
    const NpyArray forward = group == std::string("tf") ? tf_forward : voxels_forward;
    const NpyArray adjoint = load_npy(prefix() + "_" + group + ".npy");
    ASSERT_EQ(forward.shape, adjoint.shape);
    double scale = 0;
    for (double x : adjoint.data) scale = std::max(scale, std::abs(x));
    for (std::size_t i = 0; i < adjoint.data.size(); ++i)
      EXPECT_NEAR(forward.data[i], adjoint.data[i], 1e-5 * scale) << group << " " << i;
  }
  r = grad("--wrt camera,step,tf_points --json");  // tf_points: forward only
  ASSERT_EQ(r.status, 0) << r.err;
  j = json::parse(r.out);
  EXPECT_EQ(j["mode"], "forward");
  EXPECT_TRUE(j["plan"]["adjoint_seconds"].is_null());
  EXPECT_EQ(load_npy(prefix() + "_camera.npy").shape, (std::vector<std::size_t>{1, 7}));
  EXPECT_EQ(load_npy(prefix() + "_step.npy").data, std::vector<double>{0.0});
  EXPECT_EQ(load_npy(prefix() + "_tf_points.npy").shape, (std::vector<std::size_t>{3}));
  // The camera in both modes: the same file within float32 rounding.
  const NpyArray camera_forward = load_npy(prefix() + "_camera.npy");
  r = grad("--wrt camera --mode adjoint --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["mode"], "adjoint");
  const NpyArray camera_adjoint = load_npy(prefix() + "_camera.npy");
  ASSERT_EQ(camera_adjoint.shape, camera_forward.shape);
  double scale = 0;
  for (double x : camera_adjoint.data) scale = std::max(scale, std::abs(x));
  ASSERT_GT(scale, 0);
  for (std::size_t i = 0; i < 7; ++i)
    EXPECT_NEAR(camera_forward.data[i], camera_adjoint.data[i], 1e-4 * scale) << "camera " << i;
}

TEST_F(CliGrad, BadOptions) {
  EXPECT_TRUE(has(expect_failure("--wrt density --loss foo"), "unknown loss 'foo'"));
  EXPECT_TRUE(has(expect_failure("--wrt density --precision f16"), "unknown precision 'f16'"));
  EXPECT_TRUE(has(expect_failure("--wrt density --step 0"), "--step must be > 0"));
  EXPECT_TRUE(has(expect_failure(""), "--wrt is required"));  // a CLI11 parse error, one line
  EXPECT_TRUE(
      has(expect_failure("--wrt density --device no-such-device-xyz"), "no OpenCL device matches"));
}

TEST_F(CliGrad, MissingTargetFile) {
  target_ = dir_ + "/nope.npy";
  const std::string err = expect_failure("--wrt density");
  EXPECT_TRUE(has(err, "nope.npy")) << err;
}

TEST_F(CliGrad, BadOutputFolder) {
  const CliResult r = run_cli("gradient " + scene_path_ + " --target " + target_ + " -o " + dir_ +
                              "/no/such/folder/g --wrt density");
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
  EXPECT_TRUE(has(r.err, "does not exist")) << r.err;
  EXPECT_TRUE(written().empty());
  EXPECT_FALSE(fs::exists(dir_ + "/no"));
}

// --scheme and --tolerance reach the gradient: its file equals the library's for that
// integrator, the JSON names the scheme and the step used, and the checks come first.
TEST_F(CliGrad, SchemeAndToleranceOptions) {
  const CliResult r = grad("--wrt density --scheme preintegrated --tolerance 0.003 --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json out = json::parse(r.out);
  EXPECT_EQ(out["scheme"], "preintegrated");
  Scene scene = load_scene(scene_path_);
  scene.integrator.scheme = Scheme::preintegrated;
  scene.integrator.tolerance = 0.003;
  EXPECT_DOUBLE_EQ(out["step"].get<double>(), choose_step(device(), scene, 0.003).step);
  Image target;
  target.views = 1, target.height = 7, target.width = 8, target.channels = 4;
  target.pixels.assign(7 * 8 * 4, 0.25f);
  const AdjointGradient g = adjoint(device(), scene, target, {});
  const NpyArray file = load_npy(prefix() + "_density.npy");
  ASSERT_EQ(file.data.size(), g.density.size());
  double largest = 0;
  for (float x : g.density) largest = std::max(largest, double(std::abs(x)));
  for (std::size_t i = 0; i < g.density.size(); ++i)
    EXPECT_NEAR(file.data[i], g.density[i], 1e-5 * largest) << "voxel " << i;
  // The exact scheme needs the absorption model: a clear error, nothing written.
  fs::remove(prefix() + "_density.npy");
  const CliResult bad = grad("--wrt density --scheme exact");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("'exact' integrates the absorption model only"), std::string::npos)
      << bad.err;
  EXPECT_FALSE(fs::exists(prefix() + "_density.npy"));
  EXPECT_EQ(grad("--wrt density --tolerance -2").status, 1);
}

}  // namespace
}  // namespace ivr::test
