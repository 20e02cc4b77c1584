// jacobian_packet_test.cpp — forward mode in packets (jacobian.cl with 16 or 8 rays per work-item
// in vector lanes, TF and background lanes, on CPU devices) against one ray per work-item
// ($IVR_PACKET=0): the image and the Jacobian bit for bit, the loss and its gradient to their
// summation order (a packet sums its rays before the work-group does), for every TF kind, both
// models, every integrator (midpoint, trapezoid, preintegrated, exact), float32 and float64, with
// and without empty-space skipping.
#include <gtest/gtest.h>

#include <cmath>

#include "adjoint/adjoint_support.hpp"
#include "ivr/jacobian.hpp"

namespace ivr::test {
namespace {

struct Forward {
  Jacobian j;
  std::string variant;
};

Forward forward_with(const Scene& scene, const std::vector<Parameter>& params, const Image& target,
                     bool packet, Precision precision, EmptySpace skip) {
  const ScopedEnv env("IVR_PACKET", packet ? "1" : "0");
  JacobianOptions o;
  o.precision = precision;
  o.jacobian = true;
  o.empty_space = skip;
  o.brick_size = 4;
  Forward f;
  f.j = jacobian(device(), scene, params, &target, o);
  f.variant = f.j.variant;
  return f;
}

template <class T>
double worst_difference(const std::vector<T>& a, const std::vector<T>& b) {
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(double(a[i]))) return INFINITY;
    worst = std::max(worst, std::abs(double(a[i]) - double(b[i])));
  }
  return worst;
}

void expect_same(const Scene& scene, const std::string& what, Precision precision,
                 EmptySpace skip) {
  std::vector<Parameter> params =
      parameters_of(scene, scene.tf.kind == TfKind::identity ? "scales" : "tf");
  if (scene.tf.kind == TfKind::piecewise_linear)
    for (const Parameter& p : parameters_of(scene, "tf_points")) params.push_back(p);
  for (const Parameter& p : parameters_of(scene, "background")) params.push_back(p);
  const Image target = perturbed_target(scene);
  const Forward a = forward_with(scene, params, target, true, precision, skip),
                b = forward_with(scene, params, target, false, precision, skip);
  if (device().info().type == "cpu") {
    EXPECT_NE(a.variant.find("packet"), std::string::npos) << what << ": " << a.variant;
  }
  EXPECT_EQ(b.variant.find("packet"), std::string::npos) << what << ": " << b.variant;
  ASSERT_EQ(a.j.jacobian.size(), b.j.jacobian.size()) << what;
  EXPECT_EQ(worst_difference(a.j.image.pixels, b.j.image.pixels), 0.0) << what << ": image";
  EXPECT_EQ(worst_difference(a.j.jacobian, b.j.jacobian), 0.0) << what << ": Jacobian";
  if (precision == Precision::f64) {
    EXPECT_EQ(worst_difference(a.j.jacobian_f64, b.j.jacobian_f64), 0.0) << what;
  }
  // Sums in another order: to float32 rounding of the largest term, relative.
  const double eps = precision == Precision::f64 ? 1e-12 : 1e-5;
  EXPECT_NEAR(a.j.loss, b.j.loss, eps * b.j.loss) << what;
  ASSERT_EQ(a.j.gradient.size(), b.j.gradient.size()) << what;
  double largest = 0;
  for (double g : b.j.gradient) largest = std::max(largest, std::abs(g));
  EXPECT_GT(largest, 0) << what;
  EXPECT_LE(worst_difference(a.j.gradient, b.j.gradient), eps * largest) << what << ": gradient";
}

struct Case {
  TfKind kind;
  Model model;
  Scheme scheme;
  Precision precision;
};

void expect_cases_same(const std::vector<Case>& cases) {
  const char* kinds[] = {"identity", "piecewise_linear", "table", "gaussian"};
  for (const Case& c : cases) {
    Scene s = two_view_scene(c.model, c.kind);
    for (Camera& cam : s.cameras) cam.width = 19;
    s.integrator.scheme = c.scheme;
    const std::string what = std::string(kinds[int(c.kind)]) +
                             (c.model == Model::absorption ? " absorption " : " ea ") +
                             scheme_name(c.scheme) + (c.precision == Precision::f64 ? " f64" : "");
    // (TF lanes never skip: JacobianOptions; float64 asks for it all the same.)
    expect_same(s, what, c.precision,
                c.precision == Precision::f64 ? EmptySpace::on : EmptySpace::off);
  }
}

// Each TF kind once, the models and schemes in turn, one in float64. 19 × 5 pixels per view: a
// full packet of 16 and a partial one per row.
TEST(JacobianPacket, EveryTfKindIsTheSame) {
  expect_cases_same(
      {{TfKind::identity, Model::emission_absorption, Scheme::trapezoid, Precision::f32},
       {TfKind::piecewise_linear, Model::emission_absorption, Scheme::midpoint, Precision::f32},
       {TfKind::table, Model::absorption, Scheme::midpoint, Precision::f32},
       {TfKind::gaussian, Model::absorption, Scheme::trapezoid, Precision::f32},
       {TfKind::piecewise_linear, Model::absorption, Scheme::trapezoid, Precision::f64},
       {TfKind::piecewise_linear, Model::emission_absorption, Scheme::preintegrated,
        Precision::f32},
       {TfKind::table, Model::absorption, Scheme::preintegrated, Precision::f32},
       {TfKind::identity, Model::emission_absorption, Scheme::preintegrated, Precision::f64},
       {TfKind::piecewise_linear, Model::absorption, Scheme::exact, Precision::f32},
       {TfKind::table, Model::absorption, Scheme::exact, Precision::f64}});
}

// The whole matrix (ctest -L extended): every TF kind × model × scheme × precision.
TEST(JacobianPacket, EveryTfKindModelSchemeAndPrecisionIsTheSameExtended) {
  std::vector<Case> cases;
  for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
    for (Model model : {Model::emission_absorption, Model::absorption})
      for (Scheme scheme :
           {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact})
        for (Precision precision : {Precision::f32, Precision::f64})
          // (exact: absorption; both exact schemes: TFs linear in density between knots)
          if ((scheme != Scheme::exact || model == Model::absorption) &&
              (scheme == Scheme::midpoint || scheme == Scheme::trapezoid ||
               kind != TfKind::gaussian))
            cases.push_back({kind, model, scheme, precision});
  expect_cases_same(cases);
}

// Background lanes alone with skipping in a half-empty volume (rays of a packet skip on their
// own), and early termination in an opaque one.
TEST(JacobianPacket, SkippingAndEarlyTerminationAreTheSame) {
  Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  for (Camera& c : s.cameras) c.width = 21;
  s.volume.nx = s.volume.ny = s.volume.nz = 16;
  s.volume.data.assign(16 * 16 * 16, 0.f);
  for (int z = 8; z < 16; ++z)
    for (int i = 0; i < 256; ++i) s.volume.data[std::size_t(z) * 256 + i] = 0.3f + 0.002f * float(i);
  const Image target = perturbed_target(s);
  const std::vector<Parameter> params = parameters_of(s, "background");
  for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated}) {
    Scene sc = s;
    sc.integrator.scheme = scheme;
    const Forward a = forward_with(sc, params, target, true, Precision::f32, EmptySpace::on),
                  b = forward_with(sc, params, target, false, Precision::f32, EmptySpace::on);
    EXPECT_TRUE(a.j.skipped_empty) << scheme_name(scheme);
    EXPECT_EQ(worst_difference(a.j.jacobian, b.j.jacobian), 0.0) << scheme_name(scheme);
    Scene opaque = sc;
    for (TfPoint& p : opaque.tf.points) p.extinction *= 60;
    opaque.integrator.min_transmittance = 0.05;
    const Forward c = forward_with(opaque, params, target, true, Precision::f32, EmptySpace::off),
                  d = forward_with(opaque, params, target, false, Precision::f32, EmptySpace::off);
    EXPECT_EQ(worst_difference(c.j.jacobian, d.j.jacobian), 0.0) << scheme_name(scheme) << " opaque";
    EXPECT_EQ(worst_difference(c.j.image.pixels, d.j.image.pixels), 0.0) << scheme_name(scheme);
  }
}

}  // namespace
}  // namespace ivr::test
