// integrator_gradients_test.cpp — every integrator's gradients are those of its own forward pass:
// adjoint and forward mode against central differences of the float64 loss, and against each
// other, for density, TF (and control-point densities), background and camera. The default suite
// runs one case per integrator code path; `Extended*` (CTest label extended) runs the whole
// scheme × model × TF matrix.
#include <gtest/gtest.h>

#include <cmath>

#include "adjoint/adjoint_support.hpp"
#include "ivr/jacobian.hpp"

namespace ivr::test {
namespace {

struct Case {
  Scheme scheme;
  Model model;
  TfKind kind;
};

std::string describe(const Case& c) {
  const char* kinds[] = {"identity", "piecewise_linear", "table", "gaussian"};
  return std::string(scheme_name(c.scheme)) +
         (c.model == Model::absorption ? "_absorption_" : "_emission_") + kinds[int(c.kind)];
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  return describe(info.param);
}

// two_view_scene, the second view aimed off-centre and orthographic, with the case's integrator.
Scene case_scene(const Case& c) {
  Scene s = two_view_scene(c.model, c.kind);
  s.cameras[1].target = {0.05, -0.03, 0.02};
  s.cameras[1].projection = Projection::orthographic;
  s.cameras[1].ortho_height = 0.9;
  s.integrator.scheme = c.scheme;
  return s;
}

// The case's differentiable parameters, in the adjoint's layout: TF, background, camera, voxels.
std::vector<Parameter> case_parameters(const Scene& s, const std::vector<std::int64_t>& voxels) {
  std::vector<Parameter> params;
  for (const char* group : {"tf", "background", "camera"})
    for (const Parameter& q : parameters_of(s, group)) params.push_back(q);
  for (std::int64_t i : voxels) params.push_back({ParameterGroup::voxel, i, 0});
  return params;
}

void check_case(const Case& c) {
  SCOPED_TRACE(describe(c));
  const Scene s = case_scene(c);
  const Image target = perturbed_target(s);
  const std::vector<std::int64_t> voxels = {3, 17, 42, 64, 88};
  const std::vector<Parameter> params = case_parameters(s, voxels);

  AdjointOptions go;
  go.precision = Precision::f64;
  go.tf = go.background = go.camera = true;
  const AdjointGradient g = adjoint(device(), s, target, go);
  ASSERT_TRUE(all_finite(g));
  std::vector<double> adjoint(g.tf.begin(), g.tf.end());
  adjoint.insert(adjoint.end(), g.background.begin(), g.background.end());
  adjoint.insert(adjoint.end(), g.camera.begin(), g.camera.end());
  for (std::int64_t i : voxels) adjoint.push_back(g.density[std::size_t(i)]);
  ASSERT_EQ(adjoint.size(), params.size());

  JacobianOptions to;
  to.precision = Precision::f64;
  const Jacobian t = jacobian(device(), s, params, &target, to);
  ASSERT_EQ(t.gradient.size(), params.size());
  EXPECT_NEAR(t.loss, g.loss, 1e-9 * g.loss);

  const double scale = std::max(max_abs(adjoint), 1e-12);
  for (std::size_t i = 0; i < params.size(); ++i) {
    const bool voxel = params[i].group == ParameterGroup::voxel;
    const double fd =
        central_difference(s, target, voxel ? 1.0 / 4096 : 1e-6,
                           [&](Scene& x, double h) { return nudge(x, params[i], h); });
    const std::string what = "parameter " + std::to_string(i) + " (group " +
                             std::to_string(int(params[i].group)) + ", index " +
                             std::to_string(params[i].index) + ", column " +
                             std::to_string(params[i].column) + ")";
    EXPECT_NEAR(adjoint[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << "adjoint " << what;
    EXPECT_NEAR(t.gradient[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << "forward " << what;
    // Both modes in float64 on the same march; AdjointGradient::density is stored as float32.
    EXPECT_NEAR(t.gradient[i], adjoint[i],
                1e-9 * (scale + std::abs(adjoint[i])) + (voxel ? 1.2e-7 * std::abs(adjoint[i]) : 0))
        << "forward vs adjoint " << what;
  }

  // Control-point densities (forward mode only) against central differences.
  if (c.kind == TfKind::piecewise_linear) {
    const std::vector<Parameter> points = parameters_of(s, "tf_points");
    const Jacobian tp = jacobian(device(), s, points, &target, to);
    const double pscale = std::max(max_abs(tp.gradient), 1e-12);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const double fd = central_difference(
          s, target, 1e-6, [&](Scene& x, double h) { return nudge(x, points[i], h); });
      EXPECT_NEAR(tp.gradient[i], fd, 1e-6 * pscale + 1e-6 * std::abs(fd)) << "point " << i;
    }
  }
}

class IntegratorGradients : public ::testing::TestWithParam<Case> {};
TEST_P(IntegratorGradients, AdjointForwardAndDifferencesAgree) {
  check_case(GetParam());
}

// One case per code path: trapezoid (both models), preintegrated (cut at knots; identity without
// knots; table knots), exact (piecewise-linear knots; identity).
INSTANTIATE_TEST_SUITE_P(
    Schemes, IntegratorGradients,
    ::testing::Values(Case{Scheme::trapezoid, Model::emission_absorption, TfKind::piecewise_linear},
                      Case{Scheme::trapezoid, Model::absorption, TfKind::gaussian},
                      Case{Scheme::preintegrated, Model::emission_absorption,
                           TfKind::piecewise_linear},
                      Case{Scheme::preintegrated, Model::emission_absorption, TfKind::identity},
                      Case{Scheme::preintegrated, Model::absorption, TfKind::table},
                      Case{Scheme::exact, Model::absorption, TfKind::piecewise_linear},
                      Case{Scheme::exact, Model::absorption, TfKind::identity}),
    case_name);

// The whole matrix (label extended): every scheme × model × TF kind it supports.
std::vector<Case> every_case() {
  std::vector<Case> out;
  for (Scheme scheme : {Scheme::trapezoid, Scheme::preintegrated, Scheme::exact})
    for (Model model : {Model::absorption, Model::emission_absorption})
      for (TfKind kind :
           {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian}) {
        if (scheme == Scheme::exact && model != Model::absorption) continue;
        if (scheme != Scheme::trapezoid && kind == TfKind::gaussian) continue;
        out.push_back({scheme, model, kind});
      }
  return out;
}

class ExtendedIntegratorGradients : public ::testing::TestWithParam<Case> {};
TEST_P(ExtendedIntegratorGradients, AdjointForwardAndDifferencesAgree) {
  check_case(GetParam());
}
INSTANTIATE_TEST_SUITE_P(Extended, ExtendedIntegratorGradients, ::testing::ValuesIn(every_case()),
                         case_name);

}  // namespace
}  // namespace ivr::test
