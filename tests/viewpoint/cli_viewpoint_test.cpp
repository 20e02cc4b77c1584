// cli_viewpoint_test.cpp — `ivr viewpoint`: the camera it writes loads as a scene camera whose
// image has the reported entropy (>= the start's), the JSON and progress reports, bad inputs.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>

#include "reconstruct/reconstruct_support.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

// A 16³ phantom under the emission–absorption TF, seen by 4 cameras of 32² about z.
class CliViewpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    const Volume v = phantom("shepp-logan", 16, 1, 2);
    save_npy(dir_ + "/volume.npy", {16, 16, 16}, v.data.data());
    write_file(dir_ + "/scene.json", scene_text("[" + orbit(4, "[0, 0, 1]", 15, 32) + "]"));
  }

  static std::string scene_text(const std::string& cameras) {
    return R"({"volume": {"file": "volume.npy"}, "model": "emission_absorption", "tf": )" +
           std::string(kPhantomTf) + R"(, "background": [0, 0, 0], "cameras": )" + cameras +
           R"(, "integrator": {"scheme": "midpoint", "step": 0.5}})";
  }

  std::string dir_;
};

TEST_F(CliViewpoint, WritesACameraWhoseEntropyIsAtLeastTheStart) {
  const std::string cam = dir_ + "/camera.json", png = dir_ + "/best.png";
  const CliResult r = run_cli("viewpoint " + dir_ + "/scene.json -o " + cam +
                              " --view 1 --iterations 4 --render " + png + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);
  const double start = j["entropy_start"].get<double>(), best = j["entropy"].get<double>();
  EXPECT_GE(best, start);
  EXPECT_GT(start, 0);
  EXPECT_LE(best, 1);
  ASSERT_EQ(j["history"].size(), 5u);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(j["history"][k][0], k);
  EXPECT_DOUBLE_EQ(j["history"][0][1].get<double>(), start);
  EXPECT_NEAR(j["history"][0][2].get<double>(), 15 + 90, 1e-9);  // view 1 of the orbit
  EXPECT_EQ(json::parse(file_text(cam)), j["camera"]);
  EXPECT_EQ(file_text(png).rfind("\x89PNG", 0), 0u);

  // The written camera loads as a scene's camera and its image has the reported entropy.
  const Scene scene = parse_scene(scene_text("[" + file_text(cam) + "]"), dir_, "camera.json");
  ASSERT_EQ(scene.cameras.size(), 1u);
  EXPECT_EQ(scene.cameras[0].width, 32);
  EXPECT_EQ(scene.cameras[0].target, glm::dvec3(0.0));
  EXPECT_NEAR(glm::length(scene.cameras[0].eye), 2.2, 1e-9);  // on the start's orbit
  EXPECT_NEAR(image_entropy(render(device(), scene)), best, 1e-4);

  // One progress line per iteration (and the start) on stderr.
  const std::regex line(
      R"(iteration (\d)/4 entropy 0\.\d{6} azimuth -?\d+\.\d\d elevation -?\d+\.\d\d)");
  std::istringstream err(r.err);
  int lines = 0;
  for (std::string s; std::getline(err, s); ++lines) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(s, m, line)) << s;
    EXPECT_EQ(std::stoi(m[1]), lines);
  }
  EXPECT_EQ(lines, 5);

  const CliResult h = run_cli("viewpoint " + dir_ + "/scene.json -o " + cam +
                              " --iterations 2 --optimizer lbfgs --lr 0.1");
  ASSERT_EQ(h.status, 0) << h.err;
  EXPECT_TRUE(has(h.out, "at the start, best")) << h.out;
  EXPECT_TRUE(has(h.out, "-> " + cam)) << h.out;
}

TEST_F(CliViewpoint, EveryBadInputIsOneLineAndWritesNothing) {
  const std::string base = "viewpoint " + dir_ + "/scene.json -o " + dir_ + "/camera.json";
  const auto expect_failure = [&](const std::string& args) {
    const CliResult r = run_cli(args);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.out;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(r.err.rfind("ivr: error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.insert(e.path().filename().string());
    EXPECT_EQ(names, (std::set<std::string>{"scene.json", "volume.npy"})) << args;
    return r.err;
  };
  EXPECT_TRUE(has(expect_failure(base + " --view 4"),
                  "--view 4 does not exist: the scene has 4 camera(s), 0 .. 3"));
  EXPECT_TRUE(has(expect_failure(base + " --view -1"), "--view -1"));
  EXPECT_TRUE(has(expect_failure(base + " --optimizer newton"), "unknown optimizer 'newton'"));
  EXPECT_TRUE(has(expect_failure(base + " --lr -1"), "--lr must be > 0"));
  EXPECT_TRUE(has(expect_failure(base + " --iterations -2"), "--iterations must be >= 0"));
  EXPECT_TRUE(has(expect_failure(base + " --render " + dir_ + "/best.bmp"), "best.bmp"));
  EXPECT_TRUE(has(expect_failure("viewpoint " + dir_ + "/scene.json -o " + dir_ + "/camera.txt"),
                  "needs the extension .json"));
}

}  // namespace
}  // namespace ivr::test
