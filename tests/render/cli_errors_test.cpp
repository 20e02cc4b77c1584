// cli_errors_test.cpp — every bad input of `ivr render` ends in one clear line on stderr, a
// non-zero status and no output file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

class CliErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    const std::vector<float> ones(4 * 4 * 4, 0.5f);
    save_npy(dir_ + "/vol.npy", {4, 4, 4}, ones.data());
    scene_ = json::parse(R"({
      "volume": {"file": "vol.npy"}, "model": "emission_absorption",
      "tf": {"type": "identity", "extinction_scale": 2, "color_scale": 1},
      "cameras": [{"eye": [0, 0, 2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
                   "width": 8, "height": 8}],
      "integrator": {"scheme": "midpoint", "step": 0.5}})");
  }

  // Runs `ivr render` on `text` and checks the failure contract; returns stderr.
  std::string expect_failure(const std::string& text, const std::string& extra = "",
                             const std::string& env = "") {
    const std::string scene = write_file(dir_ + "/scene.json", text);
    const std::string out = dir_ + "/out.npy";
    const CliResult r = run_cli("render " + scene + " -o " + out + " " + extra, env);
    EXPECT_NE(r.status, 0) << r.out;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(out)) << "output written despite the error";
    for (const auto& entry : fs::directory_iterator(dir_))  // no temporary left behind either
      EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
    return r.err;
  }
  std::string expect_failure(const json& j, const std::string& extra = "") {
    return expect_failure(j.dump(), extra);
  }

  static bool one_line(const std::string& err) { return err.find('\n') == err.size() - 1; }

  std::string dir_;
  json scene_;
};

TEST_F(CliErrors, ValidSceneRenders) {
  const std::string scene = write_file(dir_ + "/scene.json", scene_.dump());
  const CliResult r = run_cli("render " + scene + " -o " + dir_ + "/ok.npy --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  for (const char* key : {"device", "kernel_seconds", "samples", "samples_per_second"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_GT(j["samples"].get<double>(), 0);
  EXPECT_TRUE(fs::exists(dir_ + "/ok.npy"));
}

TEST_F(CliErrors, MissingSceneFile) {
  const CliResult r = run_cli("render " + dir_ + "/nope.json -o " + dir_ + "/out.npy");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("nope.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no such file"), std::string::npos) << r.err;
  EXPECT_TRUE(one_line(r.err)) << r.err;
}

TEST_F(CliErrors, SceneIsADirectory) {
  const CliResult r = run_cli("render " + dir_ + " -o " + dir_ + "/out.npy");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("is a directory"), std::string::npos) << r.err;
}

TEST_F(CliErrors, MissingVolumeFile) {
  scene_["volume"]["file"] = "missing.npy";
  const std::string err = expect_failure(scene_);
  EXPECT_NE(err.find("missing.npy"), std::string::npos) << err;
  EXPECT_TRUE(one_line(err)) << err;
}

TEST_F(CliErrors, MalformedJson) {
  const std::string err = expect_failure(std::string("{\"volume\": {\"file\": \"vol.npy\"},, }"));
  EXPECT_NE(err.find("malformed JSON"), std::string::npos) << err;
  EXPECT_NE(err.find("line 1"), std::string::npos) << err;
  EXPECT_TRUE(one_line(err)) << err;
}

// A number beyond the double range is malformed JSON too, not an uncaught exception (found by
// fuzzing; nlohmann reports it as out_of_range, not parse_error).
TEST_F(CliErrors, NumberBeyondTheDoubleRangeIsMalformedJson) {
  const std::string err = expect_failure(
      std::string(R"({"volume": {"file": "vol.npy"}, "integrator": {"step": 1e999}})"));
  EXPECT_NE(err.find("malformed JSON"), std::string::npos) << err;
  EXPECT_NE(err.find("1e999"), std::string::npos) << err;
  EXPECT_TRUE(one_line(err)) << err;
}

TEST_F(CliErrors, UnknownValuesAndKeys) {
  json j = scene_;
  j["tf"]["type"] = "rainbow";
  EXPECT_NE(expect_failure(j).find("unknown transfer function type 'rainbow'"), std::string::npos);
  j = scene_;
  j["model"] = "scattering";
  EXPECT_NE(expect_failure(j).find("unknown optical model 'scattering'"), std::string::npos);
  j = scene_;
  j["cameras"][0]["projection"] = "fisheye";
  EXPECT_NE(expect_failure(j).find("cameras[0].projection: unknown projection 'fisheye'"),
            std::string::npos);
  j = scene_;
  j["camera"] = j["cameras"];
  EXPECT_NE(expect_failure(j).find("camera: unknown key"), std::string::npos);
  j = scene_;
  j["integrator"]["scheme"] = "rk4";
  EXPECT_NE(expect_failure(j).find("unknown scheme 'rk4'"), std::string::npos);
  j = scene_;
  j["cameras"][0]["fov_y"] = "wide";
  EXPECT_NE(expect_failure(j).find("cameras[0].fov_y: expected a number"), std::string::npos);
}

TEST_F(CliErrors, RawSizeMismatch) {
  std::ofstream(dir_ + "/vol.raw", std::ios::binary) << std::string(1000, '\1');
  scene_["volume"] = {{"file", "vol.raw"}, {"dims", {10, 10, 11}}, {"type", "uint8"}};
  const std::string err = expect_failure(scene_);
  EXPECT_NE(err.find("1000"), std::string::npos) << err;
  EXPECT_NE(err.find("1100"), std::string::npos) << err;
}

TEST_F(CliErrors, NonFiniteAndNegativeDensities) {
  for (float bad :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -0.25f}) {
    std::vector<float> v(4 * 4 * 4, 0.5f);
    v[(2 * 4 + 1) * 4 + 3] = bad;  // (x, y, z) = (3, 1, 2)
    save_npy(dir_ + "/bad.npy", {4, 4, 4}, v.data());
    scene_["volume"]["file"] = "bad.npy";
    const std::string err = expect_failure(scene_);
    EXPECT_NE(err.find("(3, 1, 2)"), std::string::npos) << err;
    EXPECT_TRUE(one_line(err)) << err;
  }
}

TEST_F(CliErrors, ImageSizes) {
  for (auto [w, h] : {std::pair{0, 0}, std::pair{100000, 100000}, std::pair{-3, 8}}) {
    json j = scene_;
    j["cameras"][0]["width"] = w;
    j["cameras"][0]["height"] = h;
    EXPECT_NE(expect_failure(j).find("image size"), std::string::npos) << w << "x" << h;
  }
  json j = scene_;
  j["cameras"].push_back(j["cameras"][0]);
  j["cameras"][1]["width"] = 16;
  EXPECT_NE(expect_failure(j).find("share width and height"), std::string::npos);
}

TEST_F(CliErrors, Steps) {
  for (double step : {0.0, -1.0}) {
    json j = scene_;
    j["integrator"]["step"] = step;
    EXPECT_NE(expect_failure(j).find("integrator.step: must be > 0"), std::string::npos) << step;
  }
  EXPECT_NE(expect_failure(scene_, "--step -0.5").find("--step must be > 0"), std::string::npos);
  EXPECT_NE(expect_failure(scene_, "--step 0").find("--step must be > 0"), std::string::npos);
  EXPECT_NE(expect_failure(scene_, "--step 1e-12").find("samples per ray"), std::string::npos);
}

TEST_F(CliErrors, DegenerateCameras) {
  json j = scene_;
  j["cameras"][0]["eye"] = {0, 0, 0};
  EXPECT_NE(expect_failure(j).find("eye equals target"), std::string::npos);
  j = scene_;
  j["cameras"][0]["up"] = {0, 0, 3};
  EXPECT_NE(expect_failure(j).find("up is parallel"), std::string::npos);
  for (double fov : {0.0, -10.0, 180.0, 200.0}) {
    j = scene_;
    j["cameras"][0]["fov_y"] = fov;
    EXPECT_NE(expect_failure(j).find("fov_y must be in (0, 180)"), std::string::npos) << fov;
  }
  j = scene_;
  j["cameras"][0]["projection"] = "orthographic";
  j["cameras"][0]["ortho_height"] = 0;
  EXPECT_NE(expect_failure(j).find("ortho_height must be > 0"), std::string::npos);
}

TEST_F(CliErrors, BadTransferFunctions) {
  json j = scene_;
  j["tf"] = json::parse(R"({"type": "piecewise_linear", "points": [
      {"density": 0.5, "color": [1,1,1], "extinction": 1}, {"density": 0.1, "color": [1,1,1], "extinction": 1}]})");
  EXPECT_NE(expect_failure(j).find("sorted by density"), std::string::npos);
  j["tf"] = json::parse(
      R"({"type": "gaussian", "gaussians": [{"mean": 0.5, "width": 0, "color": [1,1,1], "extinction": 1}]})");
  EXPECT_NE(expect_failure(j).find("width must be > 0"), std::string::npos);
  j["tf"] = json::parse(R"({"type": "table", "range": [1, 0], "entries": [[1,1,1,1]]})");
  EXPECT_NE(expect_failure(j).find("lo < hi"), std::string::npos);
  j["tf"] = json::parse(R"({"type": "identity", "extinction_scale": -1})");
  EXPECT_NE(expect_failure(j).find("extinction must be finite and >= 0"), std::string::npos);
}

// The situation is made by the test: a preloaded clGetPlatformIDs that finds no platform
// (tests/no_platform_shim.c), whichever ICD loader comes first on this machine. Under ASan the
// preload comes before the sanitizer runtime, which is then told not to mind.
TEST_F(CliErrors, NoPlatform) {
  const std::string err =
      expect_failure(scene_.dump(), "", std::string("ASAN_OPTIONS=verify_asan_link_order=0 ") +
                                            "LD_PRELOAD=" + IVR_NO_PLATFORM_SHIM);
  EXPECT_NE(err.find("no OpenCL platform"), std::string::npos) << err;
  EXPECT_TRUE(one_line(err)) << err;
}

TEST_F(CliErrors, NoMatchingDevice) {
  std::string err = expect_failure(scene_.dump(), "--device no-such-device-xyz");
  EXPECT_NE(err.find("no OpenCL device matches device selector 'no-such-device-xyz'"),
            std::string::npos)
      << err;
  err = expect_failure(scene_.dump(), "", "IVR_DEVICE=99");
  EXPECT_NE(err.find("IVR_DEVICE '99'"), std::string::npos) << err;
  err = expect_failure(scene_.dump(), "--device 99999999999999999999");
  EXPECT_NE(err.find("no OpenCL device matches"), std::string::npos) << err;
}

TEST_F(CliErrors, KernelBuildFailureCarriesTheLog) {
  // A kernel folder whose render.cl does not compile.
  const std::string kdir = temp_dir("broken_kernels");
  for (const auto& f : fs::directory_iterator(IVR_KERNELS_DIR))
    fs::copy_file(f.path(), kdir + "/" + f.path().filename().string());
  write_file(kdir + "/render.cl",
             "#include \"config.cl\"\n__kernel void render(__global float* x) { x[0] = "
             "undeclared_thing; }\n");
  const std::string scene = write_file(dir_ + "/scene.json", scene_.dump());
  const CliResult r = run_cli("render " + scene + " -o " + dir_ + "/out.npy",
                              "IVR_KERNEL_DIR=" + kdir + " IVR_KERNEL_CACHE=0");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("building kernel render.cl"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("undeclared_thing"), std::string::npos)
      << "the build log is missing: " << r.err;
  EXPECT_FALSE(fs::exists(dir_ + "/out.npy"));
}

TEST_F(CliErrors, DeviceAllocationFailure) {
  // Views of 16384² RGBA float32 (4 GiB each), one more than the device's largest allocation
  // holds (at least 5: an H200 holds 8 in one allocation).
  json j = scene_;
  j["cameras"][0]["width"] = 16384;
  j["cameras"][0]["height"] = 16384;
  const std::uint64_t view_bytes = std::uint64_t(16384) * 16384 * 4 * sizeof(float);
  const std::uint64_t views = std::max<std::uint64_t>(5, device().info().max_allocation / view_bytes + 1);
  for (std::uint64_t i = 1; i < views; ++i) j["cameras"].push_back(j["cameras"][0]);
  const std::string err = expect_failure(j);
  EXPECT_NE(err.find("the image needs"), std::string::npos) << err;
  EXPECT_NE(err.find("largest allocation"), std::string::npos) << err;
}

TEST_F(CliErrors, BadOutputName) {
  const std::string scene = write_file(dir_ + "/scene.json", scene_.dump());
  CliResult r = run_cli("render " + scene + " -o " + dir_ + "/out.bmpx");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("needs the extension"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ + "/out.bmpx"));
  r = run_cli("render " + scene + " -o " + dir_ + "/no/such/folder/out.npy");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
}

TEST_F(CliErrors, Float64WhereUnsupportedIsClear) {
  // PoCL has fp64; the option itself must at least be validated.
  const std::string scene = write_file(dir_ + "/scene.json", scene_.dump());
  const CliResult r = run_cli("render " + scene + " -o " + dir_ + "/out.npy --precision f16");
  EXPECT_NE(r.status, 0);
  EXPECT_FALSE(fs::exists(dir_ + "/out.npy"));
}

}  // namespace
}  // namespace ivr::test
