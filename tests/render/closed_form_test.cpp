// closed_form_test.cpp — the renderer against closed-form answers, in float32 and float64.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "reference/design_formulas.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

constexpr double kEps32 = 1.1920928955078125e-07;  // float32 machine epsilon

// ---------------------------------------------------------------------------------------------
// docs/design.md's transfer functions, re-derived here in double precision independently of the
// kernels (rays and chords: design_formulas.hpp).

// sigma(d) and colour(d) of every TF kind exactly as docs/design.md defines them.
struct TfValue {
  double sigma;
  glm::dvec3 color;
};
TfValue design_tf(const TransferFunction& tf, double d) {
  switch (tf.kind) {
    case TfKind::identity:
      return {tf.extinction_scale * d, glm::dvec3(tf.color_scale * d)};
    case TfKind::piecewise_linear: {
      const auto& p = tf.points;
      if (d <= p.front().density) return {p.front().extinction, p.front().color};
      if (d >= p.back().density) return {p.back().extinction, p.back().color};
      std::size_t k = 0;
      while (p[k + 1].density < d) ++k;
      const double w = (d - p[k].density) / (p[k + 1].density - p[k].density);
      return {p[k].extinction + w * (p[k + 1].extinction - p[k].extinction),
              p[k].color + w * (p[k + 1].color - p[k].color)};
    }
    case TfKind::table: {
      const auto& e = tf.entries;
      const double u =
          std::clamp((d - tf.range.x) / (tf.range.y - tf.range.x), 0.0, 1.0) * double(e.size() - 1);
      const std::size_t i = std::min(std::size_t(u), e.size() - 1),
                        j = std::min(i + 1, e.size() - 1);
      const glm::dvec4 row = e[i] + (u - double(i)) * (e[j] - e[i]);
      return {row.w, glm::dvec3(row)};
    }
    case TfKind::gaussian: {
      double sigma = 0;
      glm::dvec3 emission(0.0);  // sigma * colour
      for (const TfGaussian& g : tf.gaussians) {
        const double s = g.extinction * std::exp(-0.5 * std::pow((d - g.mean) / g.width, 2));
        sigma += s;
        emission += s * g.color;
      }
      return {sigma, sigma > 0 ? emission / sigma : glm::dvec3(0.0)};
    }
  }
  return {0, glm::dvec3(0.0)};
}

// ---------------------------------------------------------------------------------------------
// Error budget. f64: the float32 image store only (relative 2^-24, doubled). f32: the relative
// error of I is the absolute error of tau, made of (a) positions along the ray rounded at
// magnitude t (~eps·sigma·t per operation, a few operations) and (b) a few ulp per sample from
// exp() (OpenCL allows 3 ulp) and the running products. 1e-6 is the floor.
double rel_tol(Precision p, double sigma_t, double samples) {
  if (p == Precision::f64) return kEps32;
  return 1e-6 + kEps32 * (4 * sigma_t + 4 * samples);
}

std::vector<Precision> precisions() {
  std::vector<Precision> p{Precision::f32};
  if (test::device().info().fp64) p.push_back(Precision::f64);
  return p;
}

// Constant density d in the default box of a non-cubic volume (box 0.8 x 0.6 x 1, smallest
// voxel edge 0.2), two oblique perspective views of non-square size.
Scene oblique_scene(float d) {
  Scene s;
  s.volume.nx = 4;
  s.volume.ny = 3;
  s.volume.nz = 5;
  s.volume.data.assign(s.volume.voxel_count(), d);
  set_default_box(s);
  s.model = Model::absorption;
  Camera a;
  a.eye = {0.9, 0.7, 1.6};
  a.target = {0.05, -0.1, 0};
  a.up = {0, 1, 0};
  a.fov_y = 50;
  a.width = 12;
  a.height = 9;
  Camera b = a;
  b.eye = {-1.1, -0.4, -1.3};
  b.target = {0.1, 0.05, 0.02};
  b.up = {0.3, 1, 0};
  s.cameras = {a, b};
  s.integrator.min_transmittance = 0;
  return s;
}

// ---------------------------------------------------------------------------------------------

// Three axis-aligned orthographic views (down -z, along -x, along +y) of a unit box; the
// outer ring of pixels (centres at ±0.625) misses it and must show I_in itself.
TEST(ClosedForm, BeerLambertAxisAlignedOrthographic) {
  Scene s = test::constant_scene(0.5f, 4, 6);
  s.background = glm::dvec3(0.7);
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 6, 6, 1.5), ortho({2, 0, 0}, {0, 1, 0}, 6, 6, 1.5),
               ortho({0, -2, 0}, {0, 0, 1}, 6, 6, 1.5)};
  for (Precision p : precisions())
    for (double sigma : {0.5, 3.0, 20.0}) {
      s.tf.extinction_scale = sigma / 0.5;
      // Entry/exit distances, dt = 1/4 and sigma·dt are exact binary numbers here, so only exp()
      // and the products round: 4 samples x <= 3.5 ulp stay under 1e-6 in f32.
      const double exact_geometry_tol = p == Precision::f32 ? 1e-6 : kEps32;
      const Image img = render_checked(s, p, 1.0);
      for (int v = 0; v < img.views; ++v)
        for (int y = 0; y < img.height; ++y)
          for (int x = 0; x < img.width; ++x) {
            const double L = chord(design_ray(s.cameras[v], x, y), s.box_min, s.box_max);
            ASSERT_TRUE(L == 0 || std::abs(L - 1) < 1e-12) << L;  // setup: the full side or nothing
            const double want = 0.7 * std::exp(-sigma * L);
            EXPECT_NEAR(img.at(v, y, x, 0), want, exact_geometry_tol * want)
                << where(p, v, y, x, sigma);
          }
    }
}

// Oblique perspective rays: L from the test's own ray–box intersection of docs/design.md's ray.
TEST(ClosedForm, BeerLambertObliquePerspective) {
  Scene s = oblique_scene(1.0f);
  s.background = glm::dvec3(2.5);
  double max_len = 0;
  int hits = 0, misses = 0;
  for (const Camera& c : s.cameras)
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        const double L = chord(design_ray(c, x, y), s.box_min, s.box_max);
        max_len = std::max(max_len, L);
        (L > 0 ? hits : misses)++;
      }
  ASSERT_GT(hits, 50);    // the views cover the box ...
  ASSERT_GT(misses, 10);  // ... and some background around it
  for (Precision p : precisions())
    for (double sigma : {0.5, 3.0, 20.0 / max_len}) {  // the longest chord reaches sigma·L = 20
      s.tf.extinction_scale = sigma;
      const Image img = render_checked(s, p);
      for (int v = 0; v < img.views; ++v)
        for (int y = 0; y < img.height; ++y)
          for (int x = 0; x < img.width; ++x) {
            double t_far = 0;
            const double L = chord(design_ray(s.cameras[v], x, y), s.box_min, s.box_max, &t_far);
            const double want = 2.5 * std::exp(-sigma * L);
            const double n = std::ceil(L / (s.integrator.step * 0.2)) + 1;
            EXPECT_NEAR(img.at(v, y, x, 0), want, rel_tol(p, sigma * t_far, n) * want)
                << where(p, v, y, x, sigma * L);
          }
    }
}

// A linear ramp along x, v_i = 0.25 + 0.125·i (exact in float), constant in y and z: the density
// is v_0 and v_{X-1} in the border half-voxels and linear in between.
struct Ramp {
  Scene scene;
  std::vector<double> v;
  double a = 2, h = 0.125, slope = 0.125;  // sigma = a·d; voxel edge; dv per voxel
  // tau of a ray running the whole box along x, in closed form.
  double tau_full() const {
    const std::size_t X = v.size();
    return a *
           (h / 2 * v.front() + double(X - 1) * h * (v.front() + v.back()) / 2 + h / 2 * v.back());
  }
  // docs/design.md's density at world x: linear between centres, clamped to the edge centres.
  double density(double x) const {
    const double u = std::clamp((x - scene.box_min.x) / h - 0.5, 0.0, double(v.size() - 1));
    const std::size_t i = std::min(std::size_t(u), v.size() - 2);
    return v[i] + (u - double(i)) * (v[i + 1] - v[i]);
  }
  // Exact integral of the density over [x0, x1]: trapezoids between the centre planes (kinks).
  double integral(double x0, double x1) const {
    std::vector<double> cuts{x0};
    for (std::size_t i = 0; i < v.size(); ++i) {
      const double c = scene.box_min.x + (double(i) + 0.5) * h;
      if (c > x0 && c < x1) cuts.push_back(c);
    }
    cuts.push_back(x1);
    double sum = 0;
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k)
      sum += (cuts[k + 1] - cuts[k]) * (density(cuts[k]) + density(cuts[k + 1])) / 2;
    return sum;
  }
};
Ramp ramp_along_x() {
  Ramp r;
  Scene& s = r.scene;
  s.volume.nx = s.volume.ny = 8;
  s.volume.nz = 2;  // default box 1 x 1 x 0.25, h = 1/8 on every axis
  for (int z = 0; z < 2; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) s.volume.data.push_back(float(0.25 + r.slope * x));
  for (int x = 0; x < 8; ++x) r.v.push_back(double(s.volume.data[x]));
  set_default_box(s);
  s.model = Model::absorption;
  s.tf.extinction_scale = r.a;
  s.background = glm::dvec3(1.3);
  // 2 x 2 pixels through y/z voxel centres (y, z = ±1/16), looking along +x and along -x.
  s.cameras = {ortho({-2, 0, 0}, {0, 1, 0}, 2, 2, 0.25), ortho({2, 0, 0}, {0, 1, 0}, 2, 2, 0.25)};
  s.integrator.min_transmittance = 0;
  return r;
}

TEST(ClosedForm, RampAlongXAlignedStepIsExact) {
  const Ramp r = ramp_along_x();
  ASSERT_NEAR(r.tau_full(), r.a * r.integral(-0.5, 0.5), 1e-15);  // the two closed forms agree
  // Step 0.5 voxels: 16 equal sub-steps whose boundaries include every centre plane, so each
  // sub-step sees a linear density and the midpoint rule is exact.
  const double want = 1.3 * std::exp(-r.tau_full());
  for (Precision p : precisions()) {
    const Image img = render_checked(r.scene, p, 0.5);
    for (int v = 0; v < 2; ++v)
      for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x)
          EXPECT_NEAR(img.at(v, y, x, 0), want, rel_tol(p, r.tau_full(), 16) * want)
              << where(p, v, y, x);
  }
}

// The density along a ray has kinks only where it crosses the first and last centre planes
// (slope change (slope/h)·|dir.x| per unit t); only sub-steps holding a kink are inexact, each
// by at most a·(slope/h)·|dir.x|·dt²/8 with dt <= step·h. Along x the two errors cancel by
// symmetry, so oblique rays entering through a y face (one kink, or two unevenly placed) make
// the bound bite.
TEST(ClosedForm, RampNonAlignedStepWithinMidpointBound) {
  Ramp r = ramp_along_x();
  r.scene.cameras = {ortho({-2, 0, 0}, {0, 0, 1}, 16, 2, 0.25),     // along +x
                     ortho({-2, -1, 0}, {0, 0, 1}, 16, 2, 0.25),    // direction (2, 1, 0)/sqrt(5)
                     ortho({2, -1.5, 0}, {0, 0, 1}, 16, 2, 0.25)};  // direction (-4, 3, 0)/5
  for (Precision p : precisions())
    for (double step : {0.3, 0.7}) {
      const double dt = step * r.h;
      const Image img = render_checked(r.scene, p, step);
      for (int v = 0; v < img.views; ++v)
        for (int y = 0; y < img.height; ++y)
          for (int x = 0; x < img.width; ++x) {
            const Ray ray = design_ray(r.scene.cameras[v], x, y);
            double t_far = 0;
            const double L = chord(ray, r.scene.box_min, r.scene.box_max, &t_far);
            const double dx = std::abs(ray.dir.x);
            const double x0 = ray.origin.x + (t_far - L) * ray.dir.x,
                         x1 = ray.origin.x + t_far * ray.dir.x;
            const double tau =
                L > 0 ? r.a / dx * r.integral(std::min(x0, x1), std::max(x0, x1)) : 0;
            const double bound = 2 * r.a * (r.slope / r.h) * dx * dt * dt / 8;
            const double got = -std::log(img.at(v, y, x, 0) / 1.3);
            EXPECT_NEAR(got, tau, bound + rel_tol(p, r.a * 1.125 * t_far, std::ceil(L / dt) + 1))
                << where(p, v, y, x, step);
          }
    }
}

// Emission–absorption of a constant medium: C = c(1 - e^{-sigma L}) + e^{-sigma L} B,
// A = 1 - e^{-sigma L}. Checks every channel against `tf` evaluated at d.
void expect_constant_emission(const Scene& s, const Image& img, Precision p, double d,
                              double step_voxels) {
  const TfValue f = design_tf(s.tf, d);
  const glm::dvec3 bg = s.effective_background();
  const double hmin = std::min({s.voxel_size().x, s.voxel_size().y, s.voxel_size().z});
  for (int v = 0; v < img.views; ++v)
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        double t_far = 0;
        const double L = chord(design_ray(s.cameras[v], x, y), s.box_min, s.box_max, &t_far);
        const double T = std::exp(-f.sigma * L);
        // Relative error r of T is absolute error r·T·|c - B| of C; the emitted sum adds r·c.
        const double r = rel_tol(p, f.sigma * t_far, std::ceil(L / (step_voxels * hmin)) + 1);
        for (int c = 0; c < 3; ++c) {
          const double want = f.color[c] * (1 - T) + T * bg[c];
          EXPECT_NEAR(img.at(v, y, x, c), want,
                      r * (std::abs(want) + std::abs(f.color[c]) + std::abs(bg[c])) + 1e-12)
              << where(p, v, y, x, d) << " channel " << c;
        }
        EXPECT_NEAR(img.at(v, y, x, 3), 1 - T, r * T + kEps32 * (1 - T) + 1e-12)
            << where(p, v, y, x, d) << " alpha";
      }
}

TEST(ClosedForm, ConstantEmissionIdentity) {
  Scene s = test::constant_scene(0.5f, 4, 4);  // every pixel runs the full side L = 1
  s.model = Model::emission_absorption;
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 4, 4, 1), ortho({2, 0, 0}, {0, 1, 0}, 4, 4, 1),
               ortho({0, -2, 0}, {0, 0, 1}, 4, 4, 1)};
  s.tf.color_scale = 1.6;  // c = 0.8
  for (Precision p : precisions())
    for (double a : {1.0, 6.0, 40.0}) {  // sigma L = 0.5, 3, 20
      s.tf.extinction_scale = a;
      for (glm::dvec3 bg : {glm::dvec3(0.0), glm::dvec3(0.2, 0.5, 0.9), glm::dvec3(1.0)}) {
        s.background = bg;
        const Image img = render_checked(s, p, 0.5);
        expect_constant_emission(s, img, p, 0.5, 0.5);
      }
    }
  // Anchor the helper by hand: sigma L = 3, c = 0.8, B = 0.2 → C_r = 0.8 - 0.6·e^{-3}.
  const double T = std::exp(-3.0);
  EXPECT_NEAR(0.8 * (1 - T) + T * 0.2, 0.8 - 0.6 * T, 1e-15);
}

TEST(ClosedForm, ConstantEmissionPiecewiseLinearTableGaussian) {
  Scene s = test::constant_scene(0.5f, 4, 4);
  s.model = Model::emission_absorption;
  s.background = glm::dvec3(0.2, 0.5, 0.9);

  TransferFunction pwl;
  pwl.kind = TfKind::piecewise_linear;
  pwl.points = {{0.0, {0, 0, 0}, 0}, {0.5, {1, 0.5, 0.25}, 8}, {1.0, {0.2, 0.4, 1}, 2}};
  TransferFunction table;
  table.kind = TfKind::table;
  table.range = {0.2, 1.0};  // entries at d = 0.2, 0.4, 0.6, 0.8, 1.0
  table.entries = {{0, 0, 0, 0}, {1, 0, 0, 4}, {0, 1, 0.5, 6}, {0.3, 0.3, 1, 1}, {1, 1, 1, 10}};
  TransferFunction gauss;
  gauss.kind = TfKind::gaussian;
  gauss.gaussians = {{0.3, 0.1, {1, 0.2, 0.1}, 5}, {0.7, 0.2, {0.1, 0.6, 1}, 3}};

  // Hand values that anchor design_tf: pwl at d = 0.75 is halfway between the last two points;
  // the table at 0.5 halfway between entries 1 and 2; a Gaussian at its mean gives e_k.
  EXPECT_NEAR(design_tf(pwl, 0.75).sigma, 5, 1e-12);
  EXPECT_NEAR(design_tf(pwl, 0.75).color.z, 0.625, 1e-12);
  EXPECT_NEAR(design_tf(table, 0.5).sigma, 5, 1e-12);
  EXPECT_NEAR(design_tf(table, 0.5).color.x, 0.5, 1e-12);
  EXPECT_NEAR(design_tf(gauss, 0.3).sigma, 5 + 3 * std::exp(-0.5 * 4), 1e-12);

  const struct {
    const TransferFunction* tf;
    std::vector<float> densities;  // inside segments, on a control point, beyond both ends
  } cases[] = {{&pwl, {0.2f, 0.5f, 0.75f, 1.5f}},
               {&table, {0.05f, 0.5f, 0.7f, 1.2f}},
               {&gauss, {0.0f, 0.3f, 0.55f, 0.9f}}};
  for (const auto& k : cases) {
    s.tf = *k.tf;
    for (float d : k.densities) {
      std::fill(s.volume.data.begin(), s.volume.data.end(), d);
      for (Precision p : precisions()) {
        const Image img = render_checked(s, p, 0.5);
        expect_constant_emission(s, img, p, double(d), 0.5);  // d as stored (float)
      }
    }
  }
}

// For a constant medium every step gives the same exact answer, for both models.
TEST(ClosedForm, ConstantMediumDoesNotDependOnStep) {
  Scene s = oblique_scene(0.5f);
  s.tf.extinction_scale = 8;  // sigma = 4 per world unit
  s.tf.color_scale = 1.6;     // c = 0.8
  for (Model m : {Model::absorption, Model::emission_absorption}) {
    s.model = m;
    s.background = m == Model::absorption ? glm::dvec3(0.7) : glm::dvec3(0.2, 0.5, 0.9);
    for (Precision p : precisions())
      for (double step : {1.0, 0.5, 0.1, 0.013}) {
        const Image img = render_checked(s, p, step);
        if (m == Model::emission_absorption) {
          expect_constant_emission(s, img, p, 0.5, step);
          continue;
        }
        for (int v = 0; v < img.views; ++v)
          for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
              double t_far = 0;
              const double L = chord(design_ray(s.cameras[v], x, y), s.box_min, s.box_max, &t_far);
              const double want = 0.7 * std::exp(-4 * L);
              const double n = std::ceil(L / (step * 0.2)) + 1;
              EXPECT_NEAR(img.at(v, y, x, 0), want, rel_tol(p, 4 * t_far, n) * want)
                  << where(p, v, y, x, step);
            }
      }
  }
}

}  // namespace
}  // namespace ivr::test
