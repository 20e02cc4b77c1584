// adjoint_packet_test.cpp — the adjoint in packets (adjoint.cl with 16 or 8 rays per work-item in
// vector lanes, the density and TF gradients of every integrator, on CPU devices) against one ray
// per
// work-item ($IVR_PACKET=0): the image and the loss bit for bit, the deterministic (fixed-point)
// density gradient bit for bit (each lane flushes what its ray would alone, and integer sums do not
// depend on their order), the float density and TF gradients to their summation order, for every
// TF kind, both models, float32 and float64, with and without empty-space skipping, on images
// whose rows end in a partial packet.
#include <gtest/gtest.h>

#include <cmath>

#include "adjoint/adjoint_support.hpp"
#include "ivr/session.hpp"

namespace ivr::test {
namespace {

struct Run {
  std::vector<double> image, loss, density, tf;
  std::string variant;
};

Run gradient_with(const Scene& scene, const Image& target, bool packet, Precision precision,
                  EmptySpace skip, bool deterministic) {
  const ScopedEnv env("IVR_PACKET", packet ? "1" : "0");
  SessionOptions so;
  so.precision = precision;
  so.empty_space = skip;
  so.brick_size = 4;
  Session session(device(), scene, so);
  session.set_target(target);
  GradientRequest r;
  r.wrt = {"density", "tf"};
  r.mode = Mode::adjoint;
  r.deterministic = deterministic;
  const SessionGradient g = session.gradient(r);
  Run out;
  out.variant = session.last_stats().variant;
  out.loss = g.loss.to_doubles();
  out.density = g["density"].to_doubles();
  out.tf = g["tf"].to_doubles();
  out.image = session.render().to_doubles();
  return out;
}

double worst_difference(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return INFINITY;
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(a[i]) || !std::isfinite(b[i])) return INFINITY;
    worst = std::max(worst, std::abs(a[i] - b[i]));
  }
  return worst;
}

double largest(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

// Deterministic (fixed-point) sums, and with `float_sums` the float atomics too.
void expect_same(const Scene& scene, const std::string& what, Precision precision,
                 EmptySpace skip, bool float_sums = true) {
  const Image target = perturbed_target(scene);
  for (bool deterministic : {true, false}) {
    if (!deterministic && !float_sums) continue;
    const std::string w = what + (deterministic ? " deterministic" : " float sums");
    const Run a = gradient_with(scene, target, true, precision, skip, deterministic),
              b = gradient_with(scene, target, false, precision, skip, deterministic);
    if (device().info().type == "cpu") {
      EXPECT_NE(a.variant.find("packet"), std::string::npos) << w << ": " << a.variant;
    }
    EXPECT_EQ(b.variant.find("packet"), std::string::npos) << w << ": " << b.variant;
    EXPECT_EQ(worst_difference(a.image, b.image), 0.0) << w << ": image";
    EXPECT_EQ(worst_difference(a.loss, b.loss), 0.0) << w << ": loss";
    const double scale = largest(b.density);
    EXPECT_GT(scale, 0) << w;
    if (deterministic) {
      EXPECT_EQ(worst_difference(a.density, b.density), 0.0) << w << ": density gradient";
    } else {  // float atomics in another order: to the rounding of the sums
      const double eps = precision == Precision::f64 ? 1e-12 : 2e-5;
      EXPECT_LE(worst_difference(a.density, b.density), eps * scale) << w << ": density gradient";
    }
    // The TF gradient: each lane's compensated sums, added to the work-group's in another order.
    const double eps = precision == Precision::f64 ? 1e-12 : 1e-5;
    EXPECT_GT(largest(b.tf), 0) << w;
    EXPECT_LE(worst_difference(a.tf, b.tf), eps * largest(b.tf)) << w << ": TF gradient";
  }
}

struct Case {
  TfKind kind;
  Model model;
  Precision precision;
  EmptySpace skip;
  Scheme scheme = Scheme::midpoint;
};

void expect_cases_same(const std::vector<Case>& cases) {
  const char* kinds[] = {"identity", "piecewise_linear", "table", "gaussian"};
  for (const Case& c : cases) {
    Scene s = two_view_scene(c.model, c.kind);
    for (Camera& cam : s.cameras) cam.width = 19;  // a full packet and a partial one per row
    s.integrator.scheme = c.scheme;
    const std::string what = std::string(kinds[int(c.kind)]) + " " + scheme_name(c.scheme) +
                             (c.model == Model::absorption ? " absorption" : " ea") +
                             (c.precision == Precision::f64 ? " f64" : "") +
                             (c.skip == EmptySpace::on ? " skipping" : "");
    expect_same(s, what, c.precision, c.skip);
  }
}

// Each TF kind, model and scheme at least once, one in float64, skipping in each scheme (the rest:
// the Extended matrix).
TEST(AdjointPacket, EveryTfKindIsTheSame) {
  expect_cases_same(
      {{TfKind::piecewise_linear, Model::emission_absorption, Precision::f32, EmptySpace::off},
       {TfKind::gaussian, Model::emission_absorption, Precision::f32, EmptySpace::off},
       {TfKind::table, Model::absorption, Precision::f32, EmptySpace::off},
       {TfKind::piecewise_linear, Model::absorption, Precision::f64, EmptySpace::off},
       {TfKind::piecewise_linear, Model::emission_absorption, Precision::f32, EmptySpace::on},
       {TfKind::piecewise_linear, Model::emission_absorption, Precision::f32, EmptySpace::off,
        Scheme::trapezoid},
       {TfKind::identity, Model::absorption, Precision::f32, EmptySpace::on, Scheme::trapezoid},
       {TfKind::piecewise_linear, Model::emission_absorption, Precision::f32, EmptySpace::off,
        Scheme::preintegrated},
       {TfKind::table, Model::absorption, Precision::f32, EmptySpace::on,
        Scheme::preintegrated},
       {TfKind::piecewise_linear, Model::absorption, Precision::f32, EmptySpace::off,
        Scheme::exact},
       {TfKind::identity, Model::absorption, Precision::f64, EmptySpace::on, Scheme::exact}});
}

// The whole matrix (ctest -L extended): every scheme × TF kind × model × precision × skipping.
TEST(AdjointPacket, EveryTfKindModelPrecisionAndSkippingIsTheSameExtended) {
  std::vector<Case> cases;
  for (Scheme scheme :
       {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact})
    for (TfKind kind : {TfKind::identity, TfKind::piecewise_linear, TfKind::table, TfKind::gaussian})
      for (Model model : {Model::emission_absorption, Model::absorption})
        for (Precision precision : {Precision::f32, Precision::f64})
          for (EmptySpace skip : {EmptySpace::off, EmptySpace::on})
            // (exact: absorption; both exact schemes: TFs linear in density between knots)
            if ((scheme != Scheme::exact || model == Model::absorption) &&
                (scheme == Scheme::midpoint || scheme == Scheme::trapezoid ||
                 kind != TfKind::gaussian))
              cases.push_back({kind, model, precision, skip, scheme});
  expect_cases_same(cases);
}

// Rays of a packet that skip on their own (a half-empty volume) and stop early on their own (an
// opaque one): the deterministic density gradient and the loss bit for bit (the float sums: the
// cases above).
TEST(AdjointPacket, SkippingAndEarlyTerminationAreTheSame) {
  Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  for (Camera& c : s.cameras) c.width = 21;
  s.volume.nx = s.volume.ny = s.volume.nz = 16;
  s.volume.data.assign(16 * 16 * 16, 0.f);
  for (int z = 8; z < 16; ++z)
    for (int i = 0; i < 256; ++i) s.volume.data[std::size_t(z) * 256 + i] = 0.3f + 0.002f * float(i);
  for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated}) {
    Scene sc = s;
    sc.integrator.scheme = scheme;
    expect_same(sc, std::string("half empty ") + scheme_name(scheme), Precision::f32,
                EmptySpace::on, false);
    Scene opaque = sc;
    for (TfPoint& p : opaque.tf.points) p.extinction *= 60;
    opaque.integrator.min_transmittance = 0.05;
    expect_same(opaque, std::string("opaque ") + scheme_name(scheme), Precision::f32,
                EmptySpace::off, false);
  }
}

}  // namespace
}  // namespace ivr::test
