// jacobian_test.cpp — forward-mode derivatives: every parameter group against central differences
// of the float64 loss, forward against adjoint on the parameters both compute, and the Jacobian
// contracted with d loss / d pixel against the gradient reduced on the device.
#include "ivr/jacobian.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "adjoint/adjoint_support.hpp"

namespace ivr::test {
namespace {

// two_view_scene with the second view aimed off-centre, orthographic where asked.
Scene tangent_scene(Model model, TfKind kind, bool ortho = false) {
  Scene s = two_view_scene(model, kind);
  s.cameras[1].target = {0.05, -0.03, 0.02};
  if (ortho) {
    s.cameras[1].projection = Projection::orthographic;
    s.cameras[1].ortho_height = 0.9;
  }
  return s;
}

// Forward-mode float64 gradient of the loss against central differences, parameter by parameter.
void expect_matches_differences(const Scene& s, const std::vector<Parameter>& params,
                                const std::string& what, double h = 1e-6) {
  const Image target = perturbed_target(s);
  JacobianOptions o;
  o.precision = Precision::f64;
  const Jacobian t = jacobian(device(), s, params, &target, o);
  ASSERT_EQ(t.gradient.size(), params.size());
  EXPECT_NEAR(t.loss, loss_of(s, target), 1e-12 * t.loss) << what;
  const double scale = std::max(max_abs(t.gradient), 1e-12);
  for (std::size_t i = 0; i < params.size(); ++i) {
    const double fd =
        central_difference(s, target, params[i].group == ParameterGroup::voxel ? 1.0 / 4096 : h,
                           [&](Scene& x, double hh) { return nudge(x, params[i], hh); });
    EXPECT_NEAR(t.gradient[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd))
        << what << " parameter " << i << " (row/view " << params[i].index << ", column "
        << params[i].column << ")";
  }
}

class TangentsTf : public ::testing::TestWithParam<std::tuple<TfKind, Model>> {};

TEST_P(TangentsTf, TfAndBackgroundMatchCentralDifferences) {
  const auto [kind, model] = GetParam();
  const Scene s = tangent_scene(model, kind);
  std::vector<Parameter> params = parameters_of(s, kind == TfKind::identity ? "scales" : "tf");
  if (kind == TfKind::piecewise_linear)
    for (const Parameter& p : parameters_of(s, "tf_points")) params.push_back(p);
  for (const Parameter& p : parameters_of(s, "background")) params.push_back(p);
  const char* kinds[] = {"identity", "piecewise_linear", "table", "gaussian"};
  expect_matches_differences(
      s, params,
      std::string(kinds[int(kind)]) + (model == Model::absorption ? " absorption" : " emission"));
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, TangentsTf,
    ::testing::Combine(::testing::Values(TfKind::identity, TfKind::piecewise_linear, TfKind::table,
                                         TfKind::gaussian),
                       ::testing::Values(Model::absorption, Model::emission_absorption)));

TEST(Jacobian, CameraMatchesCentralDifferences) {
  for (Model m : {Model::absorption, Model::emission_absorption}) {
    const Scene s = tangent_scene(m, TfKind::piecewise_linear, /*ortho=*/true);
    expect_matches_differences(s, parameters_of(s, "camera"), "camera");
  }
}

TEST(Jacobian, VoxelsMatchCentralDifferences) {
  const Scene s = tangent_scene(Model::emission_absorption, TfKind::gaussian);
  std::vector<Parameter> params;
  for (std::int64_t i : {0, 7, 31, 64, 119}) params.push_back({ParameterGroup::voxel, i, 0});
  expect_matches_differences(s, params, "voxels");
}

// The step enters the render only through the sample count n = ceil(length / step), which a small
// change does not move: the derivative is exactly 0, and so is the difference.
TEST(Jacobian, StepHasZeroDerivative) {
  const Scene s = tangent_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image target = perturbed_target(s);
  const Jacobian t = jacobian(device(), s, parameters_of(s, "step"), &target, {Precision::f64});
  ASSERT_EQ(t.gradient.size(), 1u);
  EXPECT_EQ(t.gradient[0], 0.0);
  const double fd = central_difference(s, target, 1e-7, [&](Scene& x, double h) {
    return nudge(x, {ParameterGroup::step, 0, 0}, h);
  });
  EXPECT_NEAR(fd, 0.0, 1e-9);
}

// Forward and adjoint compute the same derivatives of the same rendered loss: TF, background,
// voxels and cameras (a perspective and an orthographic view).
TEST(Jacobian, ForwardMatchesAdjoint) {
  for (Precision p : {Precision::f32, Precision::f64}) {
    const double tolerance = p == Precision::f32 ? 1e-5 : 1e-10;
    for (Model m : {Model::absorption, Model::emission_absorption}) {
      const Scene s = tangent_scene(m, TfKind::piecewise_linear, /*ortho=*/true);
      const Image target = perturbed_target(s);
      AdjointOptions go;
      go.precision = p;
      go.tf = go.background = go.camera = true;
      const AdjointGradient g = adjoint(device(), s, target, go);
      const std::vector<std::int64_t> voxels = {3, 17, 42, 88};
      std::vector<Parameter> params;
      for (const char* group : {"tf", "background", "camera"})
        for (const Parameter& q : parameters_of(s, group)) params.push_back(q);
      for (std::int64_t i : voxels) params.push_back({ParameterGroup::voxel, i, 0});
      JacobianOptions to;
      to.precision = p;
      const Jacobian t = jacobian(device(), s, params, &target, to);
      std::vector<double> adjoint(g.tf.begin(), g.tf.end());
      adjoint.insert(adjoint.end(), g.background.begin(), g.background.end());
      adjoint.insert(adjoint.end(), g.camera.begin(), g.camera.end());
      for (std::int64_t i : voxels) adjoint.push_back(g.density[std::size_t(i)]);
      ASSERT_EQ(adjoint.size(), t.gradient.size());
      EXPECT_NEAR(t.loss, g.loss, 1e-6 * g.loss);
      const double scale = max_abs(adjoint);
      for (std::size_t i = 0; i < adjoint.size(); ++i)  // AdjointGradient::density is stored as float32
        EXPECT_NEAR(t.gradient[i], adjoint[i],
                    tolerance * (scale + std::abs(adjoint[i])) +
                        (i >= adjoint.size() - voxels.size() ? 1.2e-7 * std::abs(adjoint[i]) : 0.0))
            << name(p) << (m == Model::absorption ? " absorption" : " emission") << " parameter "
            << i;
    }
  }
}

// The adjoint's camera gradient against central differences (float64), with early termination.
TEST(Jacobian, AdjointCameraMatchesCentralDifferences) {
  Scene s = tangent_scene(Model::emission_absorption, TfKind::table, /*ortho=*/true);
  const Image target = perturbed_target(s);
  AdjointOptions go;
  go.precision = Precision::f64;
  go.density = false;
  go.camera = true;
  const AdjointGradient g = adjoint(device(), s, target, go);
  ASSERT_EQ(g.camera.size(), 14u);
  const double scale = max_abs(g.camera);
  ASSERT_GT(scale, 0);
  const std::vector<Parameter> params = parameters_of(s, "camera");
  for (std::size_t i = 0; i < params.size(); ++i) {
    const double fd = central_difference(
        s, target, 1e-6, [&](Scene& x, double h) { return nudge(x, params[i], h); });
    EXPECT_NEAR(g.camera[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << "camera value " << i;
  }
}

// The Jacobian (views, H, W, C, P) contracted with d loss / d pixel is the reduced gradient, and
// passes of 32 lanes cover more parameters (here 2 views x 7 camera + 12 TF + 3 background + 20
// voxels = 49: two passes).
TEST(Jacobian, JacobianContractsToTheGradient) {
  const Scene s = tangent_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image target = perturbed_target(s);
  std::vector<Parameter> params = parameters_of(s, "camera");
  for (const char* g : {"tf", "background"})
    for (const Parameter& q : parameters_of(s, g)) params.push_back(q);
  for (std::int64_t i = 0; i < 20; ++i) params.push_back({ParameterGroup::voxel, i * 5, 0});
  JacobianOptions o;
  o.precision = Precision::f64;
  o.jacobian = true;
  const Jacobian t = jacobian(device(), s, params, &target, o);
  EXPECT_EQ(t.passes, 2);
  const std::size_t n = t.image.pixels.size(), P = params.size();
  ASSERT_EQ(t.jacobian.size(), n * P);
  std::vector<double> contracted(P, 0.0);
  for (std::size_t e = 0; e < n; ++e) {
    const double dl = 2.0 * (double(t.image.pixels[e]) - double(target.pixels[e])) / double(n);
    for (std::size_t q = 0; q < P; ++q) contracted[q] += dl * double(t.jacobian[e * P + q]);
  }
  const double scale = max_abs(t.gradient);
  for (std::size_t q = 0; q < P; ++q)
    EXPECT_NEAR(contracted[q], t.gradient[q], 1e-5 * scale) << "parameter " << q;
}

// Near-opaque media (sigma·step = 100, total optical depth 1e3) with early termination off:
// every forward derivative is finite and matches the adjoint's (float32).
TEST(Jacobian, FiniteAndConsistentInOpaqueMedia) {
  Scene s = tangent_scene(Model::emission_absorption, TfKind::piecewise_linear);
  for (TfPoint& p : s.tf.points) p.extinction *= 400;  // sigma up to 1600 per world unit
  s.integrator.step = 0.5;
  const Image target = perturbed_target(s);
  std::vector<Parameter> params;
  for (const char* group : {"tf", "background", "camera"})
    for (const Parameter& q : parameters_of(s, group)) params.push_back(q);
  const Jacobian t = jacobian(device(), s, params, &target, {});
  AdjointOptions go;
  go.density = false;
  go.tf = go.background = go.camera = true;
  const AdjointGradient g = adjoint(device(), s, target, go);
  std::vector<double> adjoint(g.tf.begin(), g.tf.end());
  adjoint.insert(adjoint.end(), g.background.begin(), g.background.end());
  adjoint.insert(adjoint.end(), g.camera.begin(), g.camera.end());
  ASSERT_EQ(adjoint.size(), t.gradient.size());
  const double scale = max_abs(adjoint);
  ASSERT_GT(scale, 0);
  for (std::size_t i = 0; i < adjoint.size(); ++i) {
    ASSERT_TRUE(std::isfinite(t.gradient[i])) << "parameter " << i;
    EXPECT_NEAR(t.gradient[i], adjoint[i], 1e-4 * scale) << "parameter " << i;
  }
}

TEST(Jacobian, BadParametersNameWhatAndWhere) {
  const Scene s = tangent_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const auto message = [&](std::vector<Parameter> p) {
    try {
      jacobian(device(), s, p, nullptr, {});
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({{ParameterGroup::tf, 3, 0}}).find("parameter 0: tf row 3"), std::string::npos);
  EXPECT_NE(message({{ParameterGroup::background, 0, 0}, {ParameterGroup::camera, 2, 0}})
                .find("parameter 1: camera view 2"),
            std::string::npos);
  EXPECT_NE(message({{ParameterGroup::voxel, 120, 0}}).find("voxel 120"), std::string::npos);
  EXPECT_THROW(parameters_of(s, "scales"), Error);
  EXPECT_THROW(parameters_of(s, "colour"), Error);
}

}  // namespace
}  // namespace ivr::test
