// empty_space_test.cpp — empty-space skipping: the TF's zero ranges (closed forms), the brick
// grid covering every cell that can absorb, and renders with skipping equal to renders without
// (both models, every TF kind with a zero range, f32 and f64, rays along brick faces, cameras
// inside the volume, the real neghip volume) with fewer samples taken.
#include "empty_space/empty_space.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "empty_space/empty_space_support.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

TEST(EmptySpace, TransferFunctionZeroRangesInClosedForm) {
  const TransferFunction pl = ramp_with_plateau();
  EXPECT_FALSE(tf_may_absorb(pl, 0.0, 0.19));
  EXPECT_FALSE(tf_may_absorb(pl, 0.0, 0.0));
  EXPECT_TRUE(tf_may_absorb(pl, 0.1, 0.21));  // reaches the ramp
  EXPECT_TRUE(tf_may_absorb(pl, 0.7, 0.9));   // constant beyond the last point
  EXPECT_TRUE(tf_has_empty_range(pl));

  TransferFunction id;  // σ = 3·d
  id.extinction_scale = 3;
  EXPECT_FALSE(tf_may_absorb(id, 0, 0));
  EXPECT_TRUE(tf_may_absorb(id, 0, 1e-3));
  EXPECT_TRUE(tf_has_empty_range(id));

  TransferFunction table;  // entries at 0, 0.25, 0.5, 0.75, 1: σ = 0, 0, 0, 5, 5
  table.kind = TfKind::table;
  table.entries = {{1, 1, 1, 0}, {1, 1, 1, 0}, {1, 1, 1, 0}, {1, 1, 1, 5}, {1, 1, 1, 5}};
  EXPECT_FALSE(tf_may_absorb(table, 0.0, 0.2));
  EXPECT_TRUE(tf_may_absorb(table, 0.4, 0.6));  // the segment 0.5 .. 0.75 rises
  EXPECT_TRUE(tf_has_empty_range(table));

  TransferFunction gauss;
  gauss.kind = TfKind::gaussian;
  gauss.gaussians = {{0.5, 0.1, {1, 1, 1}, 4.0}};
  EXPECT_TRUE(tf_may_absorb(gauss, 0, 0));  // never exactly 0
  EXPECT_FALSE(tf_has_empty_range(gauss));
}

// σ > 0 throughout a range: the shortcut that spares the grid when no brick can be empty. The
// calibration TF (σ = 0 at density 0 only, rising to 2 at 0.35, then 10, 30).
TEST(EmptySpace, AbsorbsThroughoutIsExactForPiecewiseLinear) {
  const TransferFunction tf = calibration_scene(4, 4).tf;
  EXPECT_TRUE(tf_absorbs_throughout(tf, 0.01, 1.0));
  EXPECT_TRUE(tf_absorbs_throughout(tf, 0.5, 5.0));     // constant 30 beyond the last point
  EXPECT_FALSE(tf_absorbs_throughout(tf, 0.0, 1.0));    // σ(0) = 0
  EXPECT_FALSE(tf_absorbs_throughout(tf, -1.0, 0.2));   // constant 0 below the first point
  EXPECT_FALSE(tf_absorbs_throughout(tf, 1e-12, 0.5));  // within the rounding margin of 0
  // A zero inside the range (a point with σ = 0 between positive ones) is found.
  const TransferFunction plateau = ramp_with_plateau();
  EXPECT_TRUE(tf_absorbs_throughout(plateau, 0.25, 2.0));
  EXPECT_FALSE(tf_absorbs_throughout(plateau, 0.1, 2.0));  // σ = 0 up to 0.2
  for (double lo : {0.0, 0.1, 0.3})
    for (double hi : {0.35, 0.6, 2.0}) {
      bool positive = true;  // sampled densely: the closed form's independent check
      for (int i = 0; i <= 1000; ++i)
        positive &= tf_may_absorb(plateau, lo + (hi - lo) * i / 1000, lo + (hi - lo) * i / 1000);
      if (tf_absorbs_throughout(plateau, lo, hi)) EXPECT_TRUE(positive) << lo << " " << hi;
    }
  TransferFunction gauss;
  gauss.kind = TfKind::gaussian;
  gauss.gaussians = {{0.5, 0.1, {1, 1, 1}, 4.0}};
  EXPECT_FALSE(tf_absorbs_throughout(gauss, 0.4, 0.6));  // unsure: the grid decides
}

// Every cell whose own corners can absorb lies in an occupied brick (checked cell by cell, from
// the corners' range, independently of the grid's brick-wise construction).
TEST(EmptySpace, GridCoversEveryCellThatCanAbsorb) {
  Volume v = synthetic_volume("marschner_lobb", 37, 20, 29);
  for (int z = 0; z < v.nz; ++z)  // an empty slab, so that the grid has empty bricks to get wrong
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < 17; ++x) v.data[(std::size_t(z) * v.ny + y) * v.nx + x] = 0;
  const TransferFunction tf = ramp_with_plateau();
  for (int size : {4, 8}) {
    const EmptySpaceGrid g = build_brick_grid(v, tf, size);
    EXPECT_EQ(g.nx, (37 - 1) / size + 1);
    EXPECT_EQ(g.ny, (20 - 1) / size + 1);
    EXPECT_EQ(g.nz, (29 - 1) / size + 1);
    int absorbing = 0;
    for (int z = 0; z < v.nz; ++z)
      for (int y = 0; y < v.ny; ++y)
        for (int x = 0; x < v.nx; ++x) {
          float lo = 1e9f, hi = -1e9f;
          for (int k = 0; k < 8; ++k) {
            const float d =
                v.at(std::min(x + (k & 1), v.nx - 1), std::min(y + (k >> 1 & 1), v.ny - 1),
                     std::min(z + (k >> 2), v.nz - 1));
            lo = std::min(lo, d), hi = std::max(hi, d);
          }
          if (!tf_may_absorb(tf, lo, hi)) continue;
          ++absorbing;
          const std::size_t b = (std::size_t(z / size) * g.ny + y / size) * g.nx + x / size;
          ASSERT_TRUE(g.occupied[b]) << "cell " << x << "," << y << "," << z << " size " << size;
        }
    EXPECT_GT(absorbing, 0);
    EXPECT_GT(g.empty_fraction, 0.0);
  }
}

class EmptySpaceRender : public ::testing::TestWithParam<std::tuple<Model, TfKind>> {};

TEST_P(EmptySpaceRender, EqualsTheRenderWithoutSkipping) {
  Scene s = ball_scene(std::get<0>(GetParam()), std::get<1>(GetParam()));
  s.cameras = hard_cameras();
  expect_same_render(s, Precision::f32);
  if (device().info().fp64) expect_same_render(s, Precision::f64);
}

INSTANTIATE_TEST_SUITE_P(
    ModelsAndTfs, EmptySpaceRender,
    ::testing::Combine(::testing::Values(Model::absorption, Model::emission_absorption),
                       ::testing::Values(TfKind::identity, TfKind::piecewise_linear,
                                         TfKind::table)));

TEST(EmptySpace, NoEarlyTerminationAndTinySteps) {
  Scene s = ball_scene(Model::emission_absorption, TfKind::piecewise_linear);
  s.cameras = hard_cameras();
  s.integrator.min_transmittance = 0;
  s.integrator.step = 0.05;
  expect_same_render(s, Precision::f32);
}

// A sharp face just past an empty brick (voxels x <= 9 zero, dense from x = 10), crossed at
// coarse steps of up to 2.5 voxels: a skip that overshoots by a single sample shows.
TEST(EmptySpace, CoarseStepsAcrossASharpFace) {
  Scene s = ball_scene(Model::emission_absorption, TfKind::identity, 32);
  set_sharp_face(s, 0.6, 0.3);
  s.cameras = {ortho({2, 0, 0}, {0, 1, 0}, 24, 24, 1.2), ortho({-2, 0, 0}, {0, 1, 0}, 24, 24, 1.2),
               hard_cameras()[0]};
  s.cameras[2].width = s.cameras[2].height = 24;
  s.integrator.min_transmittance = 0;
  for (int brick : {4, 8})
    for (double step : {2.5, 1.3, 0.7}) {
      s.integrator.step = step;
      SCOPED_TRACE("brick " + std::to_string(brick) + " step " + std::to_string(step));
      expect_same_render(s, Precision::f32, brick);
    }
}

// The renderer's grid, with brick ranges taken by the device's kernel or on the host, empties as
// many bricks as build_brick_grid; and the renders agree.
TEST(EmptySpace, DeviceGridMatchesTheHostGrid) {
  Scene s = ball_scene(Model::absorption, TfKind::piecewise_linear, 41);
  s.cameras = {hard_cameras()[0]};
  for (const char* where : {"device", "host"})
    for (int size : {4, 8})
      for (Precision p : {Precision::f32, Precision::f64}) {
        if (p == Precision::f64 && !device().info().fp64) continue;
        RenderOptions o;
        o.precision = p;
        o.brick_size = size;
        o.empty_space = EmptySpace::on;
        RenderStats stats;
        const ScopedEnv env("IVR_GRID", where);
        render(device(), s, o, &stats);
        EXPECT_EQ(stats.empty_fraction, build_brick_grid(s.volume, s.tf, size).empty_fraction)
            << where << " size " << size << " " << name(p);
        EXPECT_GT(stats.empty_fraction, 0.2);
      }
}

TEST(EmptySpace, BadGridSetting) {
  Scene s = ball_scene(Model::absorption, TfKind::piecewise_linear, 16);
  s.cameras = {hard_cameras()[0]};
  const ScopedEnv env("IVR_GRID", "gpu");
  RenderOptions o;
  o.empty_space = EmptySpace::on;
  try {
    render(device(), s, o);
    ADD_FAILURE() << "IVR_GRID=gpu accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("IVR_GRID must be host or device"), std::string::npos)
        << e.what();
  }
}

TEST(EmptySpace, AutomaticChoice) {
  Scene s = ball_scene(Model::emission_absorption, TfKind::piecewise_linear);
  s.cameras = {hard_cameras()[0]};
  RenderStats stats;
  render(device(), s, {}, &stats);
  EXPECT_TRUE(stats.skipped_empty) << stats.variant;
  EXPECT_NE(stats.variant.find("empty_space=on"), std::string::npos);
  s.tf.kind = TfKind::gaussian;  // σ > 0 everywhere: no grid, no skip
  s.tf.gaussians = {{0.5, 0.2, {1, 1, 1}, 10}};
  stats = {};
  render(device(), s, {}, &stats);
  EXPECT_FALSE(stats.skipped_empty);
  EXPECT_EQ(stats.grid_seconds, 0.0);
  std::fill(s.volume.data.begin(), s.volume.data.end(), 0.5f);  // nothing empty
  s.tf = ramp_with_plateau();
  stats = {};
  render(device(), s, {}, &stats);
  EXPECT_FALSE(stats.skipped_empty);
  EXPECT_EQ(stats.empty_fraction, 0.0);
}

TEST(EmptySpace, CommandLine) {
  const std::string dir = temp_dir("empty_space_cli");
  Scene s = ball_scene(Model::emission_absorption, TfKind::piecewise_linear, 32);
  save_npy(dir + "/ball.npy", {32, 32, 32}, s.volume.data.data());
  const std::string scene = write_file(dir + "/scene.json", R"({"volume": {"file": "ball.npy"},
      "model": "emission_absorption", "tf": {"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
        {"density": 0.2, "color": [0.5, 0.5, 1], "extinction": 0},
        {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 30}]},
      "cameras": [{"eye": [1.1, 0.7, 1.6], "width": 24, "height": 24}]})");
  std::vector<double> images[2];
  int k = 0;
  for (const char* mode : {"on", "off"}) {
    const CliResult r = run_cli("render " + scene + " -o " + dir + "/" + mode +
                                ".npy --json --empty-space " + mode);
    ASSERT_EQ(r.status, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["empty_space"]["skipped"].get<bool>(), std::string(mode) == "on") << r.out;
    images[k++] = load_npy(dir + "/" + mode + ".npy").data;
  }
  ASSERT_EQ(images[0].size(), images[1].size());
  for (std::size_t i = 0; i < images[0].size(); ++i)
    EXPECT_NEAR(images[0][i], images[1][i], 2e-6 * (1 + std::abs(images[1][i]))) << i;
  const CliResult bad = run_cli("render " + scene + " -o " + dir + "/x.npy --empty-space maybe");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("--empty-space"), std::string::npos) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.npy"));
}

TEST(EmptySpace, RealNeghipVolume) {
  const std::string path = std::string(IVR_SHARED_DATA_DIR) + "/neghip_64x64x64_uint8.raw";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path;
  Scene s = parse_scene(R"({"volume": {"file": ")" + path +
                            R"(", "dims": [64, 64, 64], "type": "uint8"},
      "model": "emission_absorption",
      "tf": {"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
        {"density": 0.15, "color": [0.2, 0.4, 1], "extinction": 0},
        {"density": 0.5, "color": [1, 0.6, 0.2], "extinction": 60}]},
      "cameras": [{"eye": [0, 0, 2]}]})",
                        ".");
  s.cameras = hard_cameras();
  expect_same_render(s, Precision::f32);
}

TEST(EmptySpace, GradientsEqualTheGradientsWithoutSkipping) {
  for (Model model : {Model::absorption, Model::emission_absorption}) {
    Scene s = ball_scene(model, TfKind::piecewise_linear, 32);
    s.cameras = hard_cameras();
    for (Camera& c : s.cameras) c.width = c.height = 20;
    AdjointOptions o;
    o.background = o.camera = true;
    SCOPED_TRACE(model == Model::absorption ? "absorption" : "emission_absorption");
    expect_same_gradient(s, o, 1e-5);
    if (device().info().fp64) {
      o.precision = Precision::f64;
      expect_same_gradient(s, o, 1e-11);
    }
  }
  // Coarse steps across a sharp face just past an empty brick, under a TF whose zero range is
  // narrow (so that a sample dropped past the brick would show).
  Scene s = ball_scene(Model::emission_absorption, TfKind::piecewise_linear, 32);
  s.tf.points = {
      {0.0, {0.1, 0.2, 0.3}, 0.0}, {0.01, {0.9, 0.5, 0.1}, 0.0}, {0.6, {1.0, 0.9, 0.8}, 30.0}};
  set_sharp_face(s, 0.8, 0.15);
  s.cameras = {ortho({-2, 0, 0}, {0, 1, 0}, 16, 16, 1.2), hard_cameras()[0]};
  s.cameras[1].eye = {-1.6, 0.2, 0.3};
  s.cameras[1].width = s.cameras[1].height = 16;
  s.integrator.min_transmittance = 0;
  for (int brick : {4, 8})
    for (double step : {2.5, 1.3, 0.7}) {
      s.integrator.step = step;
      SCOPED_TRACE("brick " + std::to_string(brick) + " step " + std::to_string(step));
      AdjointOptions o;
      o.camera = true;
      o.brick_size = brick;
      expect_same_gradient(s, o, 1e-5);
    }
}

TEST(EmptySpace, GradientsSkipOnlyWhereExact) {
  Scene s = ball_scene(Model::emission_absorption, TfKind::piecewise_linear, 24);
  s.cameras = {hard_cameras()[0]};
  s.cameras[0].width = s.cameras[0].height = 12;
  const Image target = render(device(), s, {});
  auto skipped = [&](const Scene& scene, bool density, bool tf, bool background) {
    AdjointOptions o;
    o.density = density, o.tf = tf, o.background = background;
    o.empty_space = EmptySpace::on;
    return adjoint(device(), scene, target, o).skipped_empty;
  };
  EXPECT_TRUE(skipped(s, true, false, false));
  EXPECT_FALSE(skipped(s, true, true, false));  // ∂σ/∂extinction ≠ 0 where σ = 0
  EXPECT_FALSE(skipped(s, false, true, false));
  s.tf = TransferFunction{};  // identity: σ' = its scale, also where σ = 0
  s.tf.extinction_scale = 30;
  EXPECT_FALSE(skipped(s, true, false, false));
  EXPECT_TRUE(skipped(s, false, false, true));  // the background needs σ = 0 only
}

}  // namespace
}  // namespace ivr::test
