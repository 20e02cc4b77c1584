// planner_test.cpp — the forward/adjoint choice: the default model, calibration files that say
// otherwise, pass counts, bad files; and `ivr gradient --mode auto` following the choice.
#include "ivr/planner.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "adjoint/adjoint_support.hpp"
#include "ivr/gradient.hpp"

namespace ivr::test {
namespace {

Scene planner_scene(int n) {
  Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  s.volume = synthetic_volume("sphere", n, n, n);
  set_default_box(s);
  return s;
}

TEST(Planner, DefaultModelPicksForwardForFewTfParametersAndAdjointForVolumes) {
  const CostModel model;
  const Scene s = planner_scene(64);
  for (std::size_t p = 1; p <= 8; ++p)
    EXPECT_EQ(plan_gradient(model, s, p, true, true).mode, Mode::forward) << p << " parameters";
  const Plan volume = plan_gradient(model, s, s.volume.voxel_count(), true, true);
  EXPECT_EQ(volume.mode, Mode::adjoint);
  EXPECT_GT(volume.forward_seconds, 1000 * volume.adjoint_seconds);
  EXPECT_EQ(volume.model, "default");
}

// The built-in CPU model (forward mode in packets): forward for up to 32 TF parameters (one pass of
// 32 lanes), the adjoint for a volume; other devices keep CostModel's defaults.
TEST(Planner, CpuDefaultPicksForwardUpToThirtyTwoLanes) {
  DeviceInfo cpu = device().info(), gpu = device().info();
  cpu.type = "cpu";
  gpu.type = "gpu";
  const CostModel model = default_cost_model(cpu);
  EXPECT_EQ(model.source, "default");
  EXPECT_LT(model.forward_base + 32 * model.forward_per_lane, model.adjoint);
  const Scene s = planner_scene(64);
  for (std::size_t p : {1, 8, 16, 20, 32})
    EXPECT_EQ(plan_gradient(model, s, p, true, true).mode, Mode::forward) << p << " parameters";
  EXPECT_EQ(plan_gradient(model, s, s.volume.voxel_count(), true, true).mode, Mode::adjoint);
  // Camera and voxel lanes march one ray per work-item: the adjoint (packets, private sums) is
  // faster from one parameter on (ivr calibrate: one voxel lane 1.3–1.4 times its time).
  for (std::size_t p : {1, 2, 4, 16, 32})
    EXPECT_EQ(plan_gradient(model, s, p, true, true, Mode::automatic, 0, true).mode, Mode::adjoint)
        << p << " voxel parameters";
  const CostModel other = default_cost_model(gpu);
  EXPECT_EQ(other.adjoint, CostModel{}.adjoint);
  EXPECT_EQ(other.forward_per_lane, CostModel{}.forward_per_lane);
  EXPECT_EQ(other.forward_ray_per_lane, other.forward_per_lane);
}

TEST(Planner, PassesAndLanes) {
  const CostModel model;
  std::size_t passes = 0, lanes = 0;
  forward_cost(model, 1, &passes, &lanes);
  EXPECT_EQ(passes, 1u);
  EXPECT_EQ(lanes, 1u);
  forward_cost(model, 5, &passes, &lanes);
  EXPECT_EQ(lanes, 8u);
  const double cost = forward_cost(model, 49, &passes, &lanes);  // 32 + 17 (padded to 32)
  EXPECT_EQ(passes, 2u);
  EXPECT_EQ(lanes, 32u);
  EXPECT_DOUBLE_EQ(cost, 2 * (model.forward_base + 32 * model.forward_per_lane));
}

TEST(Planner, RequestedModesAndWhatEachCanCompute) {
  const CostModel model;
  const Scene s = planner_scene(8);
  EXPECT_EQ(plan_gradient(model, s, 1, true, true, Mode::adjoint).mode, Mode::adjoint);
  EXPECT_EQ(plan_gradient(model, s, 512, true, true, Mode::forward).mode, Mode::forward);
  // camera / tf_points: forward only, so auto takes forward whatever the count
  EXPECT_EQ(plan_gradient(model, s, 5000, true, false).mode, Mode::forward);
  EXPECT_THROW(plan_gradient(model, s, 14, true, false, Mode::adjoint), Error);
}

// A calibration file that says forward lanes are dear (or the adjoint is) changes the choice.
TEST(Planner, FollowsACalibrationFile) {
  const std::string dir = temp_dir("planner");
  const std::string path = dir + "/cost.json";
  const DeviceInfo& info = device().info();
  ScopedEnv env("IVR_COST_MODEL", path);
  EXPECT_EQ(cost_model_path(info), path);
  EXPECT_EQ(load_cost_model(info).source, "default");  // no file yet
  const Scene s = planner_scene(16);

  CostModel dear;
  dear.forward_base = 5;
  dear.forward_per_lane = 2;
  dear.forward_ray_base = 7;
  dear.forward_ray_per_lane = 3;
  save_cost_model(path, dear, info);
  const CostModel read = load_cost_model(info);
  EXPECT_EQ(read.source, path);
  EXPECT_DOUBLE_EQ(read.forward_per_lane, 2);
  EXPECT_DOUBLE_EQ(read.forward_ray_base, 7);
  EXPECT_DOUBLE_EQ(read.forward_ray_per_lane, 3);
  EXPECT_EQ(plan_gradient(read, s, 1, true, true).mode, Mode::adjoint);

  CostModel cheap;
  cheap.adjoint = 1000;
  save_cost_model(path, cheap, info);
  EXPECT_EQ(plan_gradient(load_cost_model(info), s, 64, true, true).mode, Mode::forward);

  // gradient() reads it: 3 TF parameters go adjoint under the dear model.
  save_cost_model(path, dear, info);
  const Image target = perturbed_target(s);
  const Gradient d = gradient(device(), s, target, {"background"});
  EXPECT_EQ(d.plan.mode, Mode::adjoint);
  EXPECT_EQ(d.plan.model, path);
  EXPECT_FALSE(d.atomics.empty());
}

TEST(Planner, BadCalibrationFilesNameTheFileAndField) {
  const std::string dir = temp_dir("planner_bad");
  const std::string path = write_file(dir + "/cost.json", R"({"forward_base": 1, "adjoint": 3,
      "seconds_per_sample": 1e-8})");
  try {
    read_cost_model(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("forward_per_lane"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  write_file(path, "{not json");
  EXPECT_THROW(read_cost_model(path), Error);
  write_file(path, R"({"forward_base": 1, "forward_per_lane": -2, "adjoint": 3,
      "seconds_per_sample": 1e-8})");
  EXPECT_THROW(read_cost_model(path), Error);
  // A file from before the per-ray lanes: they take the other lanes' figures; a bad one is named.
  write_file(path, R"({"forward_base": 1, "forward_per_lane": 0.5, "adjoint": 3,
      "seconds_per_sample": 1e-8})");
  const CostModel old = read_cost_model(path);
  EXPECT_EQ(old.forward_ray_base, 1);
  EXPECT_EQ(old.forward_ray_per_lane, 0.5);
  write_file(path, R"({"forward_base": 1, "forward_per_lane": 0.5, "forward_ray_base": "x",
      "adjoint": 3, "seconds_per_sample": 1e-8})");
  try {
    read_cost_model(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("forward_ray_base"), std::string::npos) << e.what();
  }
}

// Both modes through gradient(): the same numbers for the groups both compute.
TEST(Differentiate, ForwardAndAdjointAgreeByGroup) {
  const Scene s = two_view_scene(Model::emission_absorption, TfKind::gaussian);
  const Image target = perturbed_target(s);
  const std::vector<std::string> groups = {"tf", "background", "voxels:3,17,40-42", "step",
                                           "camera"};
  GradientOptions o;
  o.precision = Precision::f64;
  o.mode = Mode::forward;
  const Gradient f = gradient(device(), s, target, groups, o);
  o.mode = Mode::adjoint;
  const Gradient a = gradient(device(), s, target, groups, o);
  EXPECT_EQ(f.plan.mode, Mode::forward);
  EXPECT_EQ(a.plan.mode, Mode::adjoint);
  ASSERT_EQ(f.groups.size(), 5u);
  ASSERT_EQ(a.groups.size(), 5u);
  EXPECT_EQ(f.parameters, 12u + 3 + 5 + 1 + 14);
  for (std::size_t g = 0; g < 5; ++g) {
    EXPECT_EQ(f.groups[g].name, a.groups[g].name);
    EXPECT_EQ(f.groups[g].shape, a.groups[g].shape);
    ASSERT_EQ(f.groups[g].values.size(), a.groups[g].values.size());
    const double scale = max_abs(a.groups[g].values);
    for (std::size_t i = 0; i < f.groups[g].values.size(); ++i)  // density: float32 storage
      EXPECT_NEAR(f.groups[g].values[i], a.groups[g].values[i],
                  1e-10 * scale + 1.2e-7 * std::abs(a.groups[g].values[i]))
          << f.groups[g].name << " " << i;
  }
  EXPECT_EQ(f.groups[2].name, "voxels");
  EXPECT_EQ(f.groups[3].values, std::vector<double>{0.0});
  EXPECT_EQ(a.groups[3].values, std::vector<double>{0.0});
}

TEST(Differentiate, GroupListsAndTheirErrors) {
  EXPECT_EQ(parse_groups("tf,voxels:3,17,40-45,background"),
            (std::vector<std::string>{"tf", "voxels:3,17,40-45", "background"}));
  EXPECT_EQ(parse_groups("tf,tf"), std::vector<std::string>{"tf"});
  EXPECT_THROW(parse_groups("tf,,background"), Error);
  EXPECT_THROW(parse_groups("voxels:x"), Error);
  EXPECT_THROW(parse_groups("voxels:1,voxels:2"), Error);
  const Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image target = perturbed_target(s);
  GradientOptions o;
  o.mode = Mode::adjoint;
  EXPECT_THROW(gradient(device(), s, target, {"tf_points"}, o), Error);
  const auto message = [&](const std::string& g) {
    try {
      gradient(device(), s, target, {g});
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("voxels:5-2").find("empty"), std::string::npos);
  EXPECT_NE(message("voxels:500").find("outside the volume's 120 voxels"), std::string::npos);
  EXPECT_NE(message("opacity").find("unknown parameter group 'opacity'"), std::string::npos);
  EXPECT_NE(message("scales").find("identity"), std::string::npos);
}

}  // namespace
}  // namespace ivr::test
