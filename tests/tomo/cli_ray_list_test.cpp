// cli_ray_list_test.cpp — the command line over a scene whose geometry is a ray list ("rays":
// {"file": …}): `ivr render` writes (rays, C), `ivr project` / `ivr tomo` / `ivr backproject`
// take and give (rays, 1), `ivr gradient` takes a (rays, C) target; a bad ray is one error naming
// it, and nothing is written.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ivr::test {
namespace {

class CliRayList : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    // Sightlines from the centre to 3000 random points of the box (6 columns: start, end).
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-0.5, 0.5);
    std::vector<double> points;
    for (int i = 0; i < kRays; ++i) points.insert(points.end(), {0, 0, 0, u(rng), u(rng), u(rng)});
    save_npy(dir_ + "/rays.npy", {std::size_t(kRays), 6}, points.data());
    const Volume truth = synthetic_volume("sphere", 8, 8, 8);
    save_npy(dir_ + "/truth.npy", {8, 8, 8}, truth.data.data());
    scene_ = write_scene("scene.json", "truth.npy", "rays.npy");
  }

  std::string write_scene(const std::string& name, const std::string& volume,
                          const std::string& rays) {
    const json j = {{"volume", {{"file", volume}}},
                    {"box", {{"min", {-0.5, -0.5, -0.5}}, {"max", {0.5, 0.5, 0.5}}}},
                    {"model", "absorption"},
                    {"rays", {{"file", rays}}}};
    return write_file(dir_ + "/" + name, j.dump());
  }

  static constexpr int kRays = 3000;
  std::string dir_, scene_;
};

TEST_F(CliRayList, RenderProjectTomoAndGradient) {
  CliResult r = run_cli("render " + scene_ + " -o " + dir_ + "/I.npy --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["rays"], kRays);
  const NpyArray image = load_npy(dir_ + "/I.npy");
  EXPECT_EQ(image.shape, (std::vector<std::size_t>{kRays, 1}));

  r = run_cli("project " + scene_ + " -o " + dir_ + "/P.npy --precision f64");
  ASSERT_EQ(r.status, 0) << r.err;
  const NpyArray p = load_npy(dir_ + "/P.npy");
  ASSERT_EQ(p.shape, (std::vector<std::size_t>{kRays, 1}));
  // The render's transmittance is exp(−∫) of the same rays (midpoint against exact pieces).
  for (int i = 0; i < kRays; ++i) ASSERT_NEAR(image.data[i], std::exp(-p.data[i]), 2e-3) << i;

  r = run_cli("backproject " + scene_ + " --images " + dir_ + "/P.npy -o " + dir_ + "/B.npy");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(load_npy(dir_ + "/B.npy").shape, (std::vector<std::size_t>{8, 8, 8}));

  r = run_cli("tomo " + scene_ + " --projections " + dir_ + "/P.npy -o " + dir_ +
              "/X.npy --iterations 100 --precision f64 --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const NpyArray x = load_npy(dir_ + "/X.npy"), truth = load_npy(dir_ + "/truth.npy");
  double err = 0, norm = 0;
  for (std::size_t i = 0; i < x.data.size(); ++i)
    err += std::pow(x.data[i] - truth.data[i], 2), norm += std::pow(truth.data[i], 2);
  EXPECT_LT(std::sqrt(err / norm), 0.05);

  r = run_cli("gradient " + scene_ + " --target " + dir_ + "/I.npy -o " + dir_ + "/G --wrt density --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NEAR(double(json::parse(r.out)["loss"]), 0.0, 1e-12);
}

TEST_F(CliRayList, BadInputsNameTheRayAndWriteNothing) {
  std::vector<double> rows = {0, 0, 0, 1, 0, 0, 0, 0.2, 0, 0, 0, 0, 0, 0, 0, 1};  // ray 1: d = 0
  save_npy(dir_ + "/bad.npy", {2, 8}, rows.data());
  const std::string bad = write_scene("bad.json", "truth.npy", "bad.npy");
  CliResult r = run_cli("render " + bad + " -o " + dir_ + "/out.npy");
  EXPECT_NE(r.status, 0);
  EXPECT_TRUE(has(r.err, "rays[1].direction: is zero")) << r.err;
  EXPECT_FALSE(fs::exists(dir_ + "/out.npy"));
  // Pictures of a ray list: refused before any work.
  r = run_cli("render " + scene_ + " -o " + dir_ + "/out.png");
  EXPECT_NE(r.status, 0);
  EXPECT_TRUE(has(r.err, "write .npy (rays, C)")) << r.err;
  EXPECT_FALSE(fs::exists(dir_ + "/out.png"));
  // Projections of the wrong length.
  std::vector<double> short_lines(kRays - 1, 0.0);
  save_npy(dir_ + "/short.npy", {std::size_t(kRays - 1), 1}, short_lines.data());
  r = run_cli("tomo " + scene_ + " --projections " + dir_ + "/short.npy -o " + dir_ + "/X.npy");
  EXPECT_NE(r.status, 0);
  EXPECT_TRUE(has(r.err, "ray list of 3000 rays")) << r.err;
  EXPECT_FALSE(fs::exists(dir_ + "/X.npy"));
}

}  // namespace
}  // namespace ivr::test
