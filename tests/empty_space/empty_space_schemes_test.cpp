// empty_space_schemes_test.cpp — empty-space skipping under every integrator and in forward mode:
// renders, adjoint gradients and forward-mode gradients with skipping equal those without, also at
// coarse steps across a sharp face just past an empty brick (where a skip that lands one sample
// or one piece off shows), and forward mode skips only where every lane stays exact.
#include <gtest/gtest.h>

#include <cmath>

#include "adjoint/adjoint_support.hpp"
#include "empty_space/empty_space_support.hpp"

namespace ivr::test {
namespace {

Scene scheme_ball(Scheme scheme, int n = 32) {
  Scene s = ball_scene(scheme == Scheme::exact ? Model::absorption : Model::emission_absorption,
                       TfKind::piecewise_linear, n);
  s.integrator.scheme = scheme;
  return s;
}

class SkipScheme : public ::testing::TestWithParam<Scheme> {};

TEST_P(SkipScheme, RendersEqualTheRendersWithoutSkipping) {
  Scene s = scheme_ball(GetParam());
  s.cameras = hard_cameras();
  for (Camera& c : s.cameras) c.width = c.height = 24;
  expect_same_render(s, Precision::f32);
  if (device().info().fp64) expect_same_render(s, Precision::f64);
}

TEST_P(SkipScheme, CoarseStepsAcrossASharpFace) {
  Scene s = scheme_ball(GetParam());
  s.tf.points = {
      {0.0, {0.1, 0.2, 0.3}, 0.0}, {0.01, {0.9, 0.5, 0.1}, 0.0}, {0.6, {1.0, 0.9, 0.8}, 30.0}};
  set_sharp_face(s, 0.6, 0.3);
  s.cameras = {ortho({2, 0, 0}, {0, 1, 0}, 16, 16, 1.2), ortho({-2, 0, 0}, {0, 1, 0}, 16, 16, 1.2),
               hard_cameras()[0]};
  s.cameras[2].width = s.cameras[2].height = 16;
  s.integrator.min_transmittance = 0;
  for (int brick : {4, 8})
    for (double step : {2.5, 1.3}) {
      s.integrator.step = step;
      SCOPED_TRACE("brick " + std::to_string(brick) + " step " + std::to_string(step));
      expect_same_render(s, Precision::f32, brick, /*saves=*/false);
      AdjointOptions o;
      o.camera = true;
      o.brick_size = brick;
      expect_same_gradient(s, o, 1e-5);
    }
}

TEST_P(SkipScheme, GradientsEqualTheGradientsWithoutSkipping) {
  Scene s = scheme_ball(GetParam(), 24);
  s.cameras = hard_cameras();
  for (Camera& c : s.cameras) c.width = c.height = 12;
  AdjointOptions o;
  o.background = o.camera = true;
  expect_same_gradient(s, o, 1e-5);
}

INSTANTIATE_TEST_SUITE_P(Schemes, SkipScheme,
                         ::testing::Values(Scheme::trapezoid, Scheme::preintegrated, Scheme::exact),
                         [](const ::testing::TestParamInfo<Scheme>& info) {
                           return std::string(scheme_name(info.param));
                         });

// Forward mode skips with camera, voxel and background lanes under a TF whose zero range has
// σ' = 0, and gives what it gives without skipping; with TF lanes it does not skip.
TEST(EmptySpace, ForwardModeSkipsWhereExact) {
  for (Scheme scheme :
       {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact}) {
    SCOPED_TRACE(scheme_name(scheme));
    Scene s = scheme_ball(scheme, 24);
    s.cameras = {hard_cameras()[0], hard_cameras()[2]};
    for (Camera& c : s.cameras) c.width = c.height = 12;
    const Image target = [&] {
      Scene t = s;
      for (float& d : t.volume.data) d *= 0.93f;
      return render(device(), t, {Precision::f32, 0, EmptySpace::off});
    }();
    std::vector<Parameter> params = parameters_of(s, "camera");
    for (const Parameter& p : parameters_of(s, "background")) params.push_back(p);
    for (std::int64_t i : {5000, 6000, 7000}) params.push_back({ParameterGroup::voxel, i, 0});
    JacobianOptions on, off;
    on.empty_space = EmptySpace::on;
    off.empty_space = EmptySpace::off;
    const Jacobian a = jacobian(device(), s, params, &target, on);
    const Jacobian b = jacobian(device(), s, params, &target, off);
    ASSERT_TRUE(a.skipped_empty);
    ASSERT_FALSE(b.skipped_empty);
    const double scale = max_abs(b.gradient);
    ASSERT_GT(scale, 0);
    for (std::size_t i = 0; i < params.size(); ++i)
      EXPECT_NEAR(a.gradient[i], b.gradient[i], 1e-5 * (scale + std::abs(b.gradient[i])))
          << "parameter " << i;
    EXPECT_FALSE(jacobian(device(), s, parameters_of(s, "tf"), &target, on).skipped_empty);
  }
}


// The benchmark suite's smooth blob under the exact scheme in float32: there rounding counts
// slivers of pieces on a brick's face as the empty brick's, whose exit then lies at the piece's
// start; the walk must still move on (it once restarted at the same piece for ever).
TEST(EmptySpace, ExactSkipMovesOnPastSliversOnBrickFaces) {
  Scene s = scheme_ball(Scheme::exact, 64);
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        auto c = [](int i) { return 2.0 * (i + 0.5) / 64 - 1.0; };
        s.volume.data[(std::size_t(z) * 64 + y) * 64 + x] =
            float(0.8 * std::exp(-3.0 * (c(x) * c(x) + 1.5 * c(y) * c(y) + 0.7 * c(z) * c(z))));
      }
  s.tf.points = {{0.0, {0, 0, 0}, 0}, {0.1, {0, 0, 0}, 0}, {0.4, {0, 0, 0}, 3}, {1.0, {0, 0, 0}, 8}};
  Camera a, b;
  a.eye = {1.2, 0.7, 1.5};
  b.eye = {-1.6, 0.3, -0.4};
  a.width = a.height = b.width = b.height = 24;
  s.cameras = {a, b};
  s.integrator.min_transmittance = 0;
  expect_same_render(s, Precision::f32);
}

}  // namespace
}  // namespace ivr::test
