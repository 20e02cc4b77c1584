// reference_continuous_test.cpp — checks the high-accuracy references (render_continuous,
// optical_depth, render_linear_segments) against closed forms derived here by other routes
// (Simpson on the few clamp pieces of a trilinear product, sums of voxel columns, trapezoids of
// piecewise-linear TFs over linear ramps, exponential integrals for constant extinction, and a
// fine Runge-Kutta integration). Limits and opaque media: reference_continuous_limits_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <random>

#include "reference/continuous_checks.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using reference::near;
using reference::Pixels;
using reference::x_profile_scene;

// --- Piecewise-linear TFs, evaluated here on their own (not through reference::transfer) ---
struct Pl {
  std::vector<TfPoint> p;
  // Linear interpolation of field f (0: extinction, 1..3: colour) at d, constant beyond the ends.
  double at(double d, int f) const {
    auto v = [&](const TfPoint& q) { return f == 0 ? q.extinction : q.color[f - 1]; };
    if (d <= p.front().density) return v(p.front());
    if (d >= p.back().density) return v(p.back());
    std::size_t i = 0;
    while (d > p[i + 1].density) ++i;
    const double w = (d - p[i].density) / (p[i + 1].density - p[i].density);
    return v(p[i]) + (v(p[i + 1]) - v(p[i])) * w;
  }
  // Extinction integrated along a segment of length len whose density goes linearly from da to
  // db: between knots sigma is linear, so its integral is the length times its midpoint value
  // (which also takes the right side of a jump).
  double tau(double da, double db, double len) const {
    if (da == db) return len * at(da, 0);
    std::vector<double> x{std::min(da, db), std::max(da, db)};
    for (const auto& q : p)
      if (q.density > x[0] && q.density < x[1]) x.push_back(q.density);
    std::sort(x.begin(), x.end());
    double s = 0;
    for (std::size_t i = 0; i + 1 < x.size(); ++i)
      s += (x[i + 1] - x[i]) * at(0.5 * (x[i] + x[i + 1]), 0);
    return len * s / std::abs(db - da);
  }
};

TransferFunction pl_tf(const std::vector<TfPoint>& p) {
  TransferFunction tf;
  tf.kind = TfKind::piecewise_linear;
  tf.points = p;
  return tf;
}

// A table TF is a piecewise-linear one with evenly spaced knots.
std::vector<TfPoint> table_as_points(const TransferFunction& tf) {
  std::vector<TfPoint> p;
  const int r = int(tf.entries.size());
  for (int i = 0; i < r; ++i) {
    const glm::dvec4& e = tf.entries[i];
    p.push_back({tf.range.x + (tf.range.y - tf.range.x) * i / (r - 1), {e.x, e.y, e.z}, e.w});
  }
  return p;
}

// Rays along +x through such a volume (x from box_min.x to box_max.x): tau by trapezoids of the
// TF over each linear stretch between voxel centres plus the two clamped half-voxels.
double tau_along_x(const Pl& tf, const std::vector<float>& vx, double h) {
  double tau = tf.tau(vx.front(), vx.front(), h / 2) + tf.tau(vx.back(), vx.back(), h / 2);
  for (std::size_t i = 0; i + 1 < vx.size(); ++i) tau += tf.tau(vx[i], vx[i + 1], h);
  return tau;
}

// (1 - e^-x)/x - e^-x without cancellation.
double ramp_weight(double x) {
  if (x > 0.1) return -std::expm1(-x) / x - std::exp(-x);
  double term = 1, sum = 0;  // sum_{k>=1} (-1)^{k+1} k x^k / (k+1)!
  for (int k = 1; k < 30; ++k) term *= (k == 1 ? x : -x) / (k + 1), sum += k * term;
  return sum;
}

// Emission-absorption along +x through an x-profile volume under a TF of constant extinction s0
// and piecewise-linear colour: the colour is linear in x between centres and knot crossings, and
// int s0 e^{-s0 x} (ca + beta (x - xa)) dx has a closed form. Stops at x_end (early termination).
glm::dvec3 emission_along_x(const Pl& tf, const std::vector<float>& vx, double h, double s0,
                            double x_end) {
  const int n = int(vx.size());
  std::vector<double> xs{0, n * h};
  for (int i = 0; i < n; ++i) xs.push_back((i + 0.5) * h);
  for (int i = 0; i + 1 < n; ++i)
    for (const auto& q : tf.p)
      if ((q.density - vx[i]) * (q.density - vx[i + 1]) < 0)
        xs.push_back((i + 0.5 + (q.density - vx[i]) / (vx[i + 1] - double(vx[i]))) * h);
  std::sort(xs.begin(), xs.end());
  auto d_at = [&](double x) {
    const double u = std::min(std::max(x / h - 0.5, 0.0), n - 1.0);
    const int i = std::min(int(u), n - 2 < 0 ? 0 : n - 2);
    return n == 1 ? double(vx[0]) : vx[i] + (vx[i + 1] - double(vx[i])) * (u - i);
  };
  glm::dvec3 c(0.0);
  for (std::size_t i = 0; i + 1 < xs.size() && xs[i] < x_end; ++i) {
    const double a = xs[i], b = std::min(xs[i + 1], x_end), len = b - a;
    if (!(len > 0)) continue;
    const double ea = std::exp(-s0 * a), x = s0 * len;
    for (int k = 0; k < 3; ++k) {
      const double ca = tf.at(d_at(a), k + 1), cb = tf.at(d_at(b), k + 1);
      c[k] += ea * (ca * -std::expm1(-x) + (cb - ca) * ramp_weight(x));
    }
  }
  return c;
}

// --- Closed forms ---

TEST(ReferenceContinuous, ConstantVolumeBeerLambertAndEmission) {
  Scene s = test::constant_scene(0.5f, 4, 6);  // unit box, ortho down -z: chord 1
  s.tf.extinction_scale = 3;                   // sigma = 1.5
  s.background = glm::dvec3(0.7);
  const Pixels want(36, 0.7 * std::exp(-1.5));
  EXPECT_TRUE(near(reference::render_continuous(s), want, 0, 1e-14));
  EXPECT_TRUE(near(reference::render_linear_segments(s, 0.37), want, 0, 1e-14));
  EXPECT_NEAR(reference::optical_depth(s, {2, 2, 2}, {-1, -1, -1}), 1.5 * std::sqrt(3.0), 1e-14);
  // Early termination stops where tau = -log(min_transmittance): the output is B * that value.
  s.integrator.min_transmittance = 0.5;
  EXPECT_TRUE(near(reference::render_continuous(s, true), Pixels(36, 0.7 * 0.5), 0, 1e-14));
  s.integrator.min_transmittance = 0.1;  // not reached (exp(-1.5) > 0.1)
  EXPECT_TRUE(near(reference::render_continuous(s, true), want, 0, 1e-14));
  s.integrator.min_transmittance = 0;
  // Emission-absorption, from transparent to opaque (sigma * voxel up to 2500): C = c (1 - T) + T
  // B.
  s.model = Model::emission_absorption;
  s.tf.color_scale = 1.2;  // colour 0.6
  const glm::dvec3 bg(0.2, 0.3, 0.4);
  s.background = bg;
  for (double scale : {1e-3, 4.0, 400.0, 2e4}) {
    s.tf.extinction_scale = scale;
    const double T = std::exp(-0.5 * scale);
    Pixels px;
    for (int p = 0; p < 36; ++p)
      for (int c = 0; c < 4; ++c) px.push_back(c < 3 ? 0.6 * (1 - T) + T * bg[c] : 1 - T);
    EXPECT_TRUE(near(reference::render_continuous(s), px, 1e-15, 1e-14)) << scale;
    EXPECT_TRUE(near(reference::render_linear_segments(s, 0.3), px, 1e-15, 1e-14)) << scale;
    // Early termination stops exactly at T = min_transmittance.
    s.integrator.min_transmittance = 1e-3;
    const double Te = std::max(T, 1e-3);
    for (int p = 0; p < 36; ++p)
      for (int c = 0; c < 4; ++c) px[p * 4 + c] = c < 3 ? 0.6 * (1 - Te) + Te * bg[c] : 1 - Te;
    EXPECT_TRUE(near(reference::render_continuous(s, true), px, 1e-15, 1e-14)) << scale;
    s.integrator.min_transmittance = 0;
  }
}

// Densities linear along every ray between voxel centres (an x-profile volume, rays along x) under
// piecewise-linear and table TFs, knots between and exactly at voxel values: tau is piecewise
// quadratic, and with constant extinction the emission has a closed form.
TEST(ReferenceContinuous, LinearProfilesThroughPiecewiseLinearTfs) {
  const std::vector<float> vx = {0.05f, 0.15f, 0.25f, 0.625f, 0.5f, 0.125f, 0.375f, 0.75f};
  const double h = 1.0 / vx.size();
  Scene s = x_profile_scene(vx);
  s.cameras = {test::ortho({-2, 0, 0}, {0, 1, 0}, 5, 4, 0.9)};  // rays along +x
  const std::vector<std::vector<TfPoint>> tfs = {
      {{0.0, {1, 0, 0}, 1}, {0.23, {0, 1, 0}, 6}, {0.4, {0, 0, 1}, 0.5}, {0.61, {1, 1, 0}, 9}},
      // knots exactly at voxel values, and a jump (two knots at one density)
      {{0.125, {1, 0, 0}, 2},
       {0.25, {0, 1, 0}, 7},
       {0.5, {0, 0, 1}, 1},
       {0.5, {1, 0, 1}, 4},
       {0.75, {0, 1, 1}, 11}}};
  for (int t = 0; t < 3; ++t) {
    if (t < 2) {
      s.tf = pl_tf(tfs[t]);
    } else {  // a table with entries at 0.125 + 0.125 i: knots at most voxel values
      s.tf = TransferFunction{};
      s.tf.kind = TfKind::table;
      s.tf.range = {0.125, 0.75};
      s.tf.entries = {{1, 0, 0, 3}, {0, 1, 0, 8},   {0, 0, 1, 1},
                      {1, 1, 0, 5}, {0, 1, 1, 0.5}, {1, 0, 1, 6}};
    }
    const Pl pl{t < 2 ? tfs[t] : table_as_points(s.tf)};
    s.model = Model::absorption;
    s.background = glm::dvec3(0.8);
    const double tau = tau_along_x(pl, vx, h);
    EXPECT_TRUE(near(reference::render_continuous(s), Pixels(20, 0.8 * std::exp(-tau)), 0, 1e-13,
                     "absorption, linear profiles"))
        << t;
    // A narrow perspective cone along x: every ray enters and leaves through the x faces, so
    // tau = tau_x / cos(angle to x).
    Scene p = s;
    p.cameras = {Camera{}};
    p.cameras[0].eye = {-2, 0.05, -0.03};
    p.cameras[0].target = {0, 0, 0};
    p.cameras[0].fov_y = 16;
    p.cameras[0].width = p.cameras[0].height = 4;
    const Pixels img = reference::render_continuous(p);
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) {
        glm::dvec3 o, d;
        reference::ray(p.cameras[0], x, y, &o, &d);
        EXPECT_NEAR(img[y * 4 + x], 0.8 * std::exp(-tau / d.x), 1e-13 * img[y * 4 + x]) << t;
      }
  }
  // Constant extinction s0 (from transparent to opaque), colour piecewise linear in density: the
  // emission in closed form, with and without early termination.
  s.model = Model::emission_absorption;
  s.background = glm::dvec3(0.1, 0.2, 0.3);
  for (double s0 : {0.7, 6.0, 300.0, 6000.0}) {
    std::vector<TfPoint> p = tfs[1];
    p.erase(p.begin() + 3);  // no jump in colour
    for (auto& q : p) q.extinction = s0;
    s.tf = pl_tf(p);
    const Pl pl{p};
    for (bool early : {false, true}) {
      s.integrator.min_transmittance = early ? 0.02 : 0;
      const double x_end = early ? -std::log(0.02) / s0 : 1e300;
      const double T = early ? std::max(0.02, std::exp(-s0)) : std::exp(-s0);
      const glm::dvec3 c = emission_along_x(pl, vx, h, s0, x_end) + T * *s.background;
      Pixels want;
      for (int i = 0; i < 20; ++i) want.insert(want.end(), {c.x, c.y, c.z, 1 - T});
      EXPECT_TRUE(near(reference::render_continuous(s, early), want, 1e-14, 1e-13,
                       "constant extinction, PL colour"))
          << s0 << " " << early;
    }
  }
}

// A trilinear product volume v = X(i) Y(j) Z(k) of linear factors (dyadic, exact in float): between
// the planes where a coordinate starts clamping, the density along any ray is a product of three
// linear functions of t, a cubic, so Simpson's rule on the <= 7 clamp pieces is exact.
struct Product {
  Scene s;
  glm::dvec3 a{0.5, 0.75, 1.0}, b{0.125, -0.0625, 0.1875};
  Product() {
    s.volume.nx = 6, s.volume.ny = 5, s.volume.nz = 7;
    for (int k = 0; k < 7; ++k)
      for (int j = 0; j < 5; ++j)
        for (int i = 0; i < 6; ++i)
          s.volume.data.push_back(float((a.x + b.x * i) * (a.y + b.y * j) * (a.z + b.z * k)));
    s.box_min = {-0.3, -0.7, 0.1};
    s.box_max = {0.6, 0.2, 0.6};
    s.integrator.min_transmittance = 0;
  }
  double density(const glm::dvec3& p) const {
    const int n[3] = {s.volume.nx, s.volume.ny, s.volume.nz};
    double d = 1;
    for (int ax = 0; ax < 3; ++ax) {
      const double h = (s.box_max[ax] - s.box_min[ax]) / n[ax];
      d *= a[ax] + b[ax] * std::min(std::max((p[ax] - s.box_min[ax]) / h - 0.5, 0.0), n[ax] - 1.0);
    }
    return d;
  }
  // int sigma(d) along the ray for sigma = e0 + e1 d (linear, so still a cubic in t).
  double tau(const glm::dvec3& o, const glm::dvec3& dir, double e0, double e1) const {
    double t0, t1;
    if (!reference::clip_to_box(s.box_min, s.box_max, o, dir, &t0, &t1)) return 0;
    std::vector<double> ts{t0, t1};
    const int n[3] = {s.volume.nx, s.volume.ny, s.volume.nz};
    for (int ax = 0; ax < 3; ++ax) {
      const double h = (s.box_max[ax] - s.box_min[ax]) / n[ax];
      for (double u : {0.0, n[ax] - 1.0}) {
        const double t = (s.box_min[ax] + (u + 0.5) * h - o[ax]) / dir[ax];
        if (dir[ax] != 0 && t > t0 && t < t1) ts.push_back(t);
      }
    }
    std::sort(ts.begin(), ts.end());
    double tau = 0;
    auto f = [&](double t) { return e0 + e1 * density(o + t * dir); };
    for (std::size_t i = 0; i + 1 < ts.size(); ++i)
      tau += (ts[i + 1] - ts[i]) / 6 * (f(ts[i]) + 4 * f(0.5 * (ts[i] + ts[i + 1])) + f(ts[i + 1]));
    return tau;
  }
};

TEST(ReferenceContinuous, TrilinearProductIsACubicAlongEveryRay) {
  Product pr;
  Scene& s = pr.s;
  const glm::dvec3 mid = 0.5 * (s.box_min + s.box_max);
  Camera inside;  // inside the box, wide angle: rays leave through several faces
  inside.eye = mid + glm::dvec3(0.1, -0.15, 0.05);
  inside.target = inside.eye + glm::dvec3(0.4, 0.3, -0.5);
  inside.fov_y = 100;
  Camera oblique;
  oblique.eye = mid + glm::dvec3(1.1, 0.8, 1.4);
  oblique.target = mid;
  oblique.fov_y = 20;
  Camera axis = test::ortho(mid + glm::dvec3(0, 0, 3), {0, 1, 0}, 5, 4, 0.6);  // along -z
  axis.target = mid;
  for (Camera* c : {&inside, &oblique}) c->width = 5, c->height = 4;
  s.cameras = {axis, oblique, inside};
  s.model = Model::absorption;
  s.tf.extinction_scale = 1.7;
  const Pixels img = reference::render_continuous(s);
  Pixels want, depth, want_depth;
  for (int v = 0; v < 3; ++v)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 5; ++x) {
        glm::dvec3 o, d;
        reference::ray(s.cameras[v], x, y, &o, &d);
        want_depth.push_back(pr.tau(o, d, 0, 1.7));
        depth.push_back(reference::optical_depth(s, o, 3.0 * d));  // any length of dir
        want.push_back(std::exp(-want_depth.back()));
      }
  EXPECT_TRUE(near(depth, want_depth, 1e-15, 1e-14, "product volume, optical depth"));
  EXPECT_TRUE(near(img, want, 0, 1e-14, "product volume, absorption"));
  // Emission-absorption with a linear extinction and one colour: C = c (1 - T) + T B.
  s.model = Model::emission_absorption;
  s.tf = pl_tf({{-1, {0.3, 0.6, 0.9}, 0.5}, {5, {0.3, 0.6, 0.9}, 6.5}});  // sigma = 1.5 + d
  s.background = glm::dvec3(0.2, 0.1, 0.4);
  const Pixels ea = reference::render_continuous(s);
  Pixels want_ea;
  for (int v = 0; v < 3; ++v)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 5; ++x) {
        glm::dvec3 o, d;
        reference::ray(s.cameras[v], x, y, &o, &d);
        const double T = std::exp(-pr.tau(o, d, 1.5, 1));
        for (int c = 0; c < 3; ++c)
          want_ea.push_back(s.tf.points[0].color[c] * (1 - T) + T * (*s.background)[c]);
        want_ea.push_back(1 - T);
      }
  EXPECT_TRUE(near(ea, want_ea, 1e-15, 1e-14, "product volume, emission"));
}

// Rays along voxel-centre planes and through centre nodes (pixel centres on voxel columns): the
// density along a column is the piecewise-linear interpolation of its voxels, so tau = h sum v
// under the identity TF.
TEST(ReferenceContinuous, RaysAlongCentrePlanesAndThroughNodes) {
  Scene s;
  s.volume.nx = 5, s.volume.ny = 4, s.volume.nz = 6;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < 120; ++i) s.volume.data.push_back(u(rng));
  s.box_min = {-0.25, -0.2, -0.3};  // voxel edge 0.1
  s.box_max = {0.25, 0.2, 0.3};
  s.model = Model::absorption;
  s.tf.extinction_scale = 2.5;
  s.integrator.min_transmittance = 0;
  s.cameras = {test::ortho({0, 0, 5}, {0, 1, 0}, 5, 4, 0.4)};  // pixel (x, y): column (x, 3 - y)
  const auto v = [&](int i, int j, int k) { return double(s.volume.at(i, j, k)); };
  Pixels want, img = reference::render_continuous(s);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 5; ++x) {
      double sum = 0;
      for (int k = 0; k < 6; ++k) sum += v(x, 3 - y, k);
      want.push_back(std::exp(-2.5 * 0.1 * sum));
    }
  EXPECT_TRUE(near(img, want, 0, 1e-14, "through centre nodes"));
  // A quarter voxel along +x: still on the y centre planes, weights 3:1 (clamped in the last).
  s.cameras[0].eye.x = s.cameras[0].target.x = 0.025;
  img = reference::render_continuous(s);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 5; ++x) {
      double sum = 0;
      for (int k = 0; k < 6; ++k)
        sum += x < 4 ? 0.75 * v(x, 3 - y, k) + 0.25 * v(x + 1, 3 - y, k) : v(4, 3 - y, k);
      want[y * 5 + x] = std::exp(-2.5 * 0.1 * sum);
    }
  EXPECT_TRUE(near(img, want, 0, 1e-14, "along centre planes"));
  // Through the nodes again under a piecewise-linear TF: trapezoids of the TF along each column.
  s.cameras[0].eye.x = s.cameras[0].target.x = 0;
  const Pl pl{
      {{0.1, {1, 0, 0}, 0.5}, {0.35, {0, 1, 0}, 9}, {0.5, {0, 0, 1}, 2}, {0.8, {1, 1, 1}, 6}}};
  s.tf = pl_tf(pl.p);
  img = reference::render_continuous(s);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 5; ++x) {
      std::vector<float> col;
      for (int k = 0; k < 6; ++k) col.push_back(float(v(x, 3 - y, k)));
      want[y * 5 + x] = std::exp(-tau_along_x(pl, col, 0.1));
    }
  EXPECT_TRUE(near(img, want, 0, 1e-13, "through centre nodes, PL TF"));
}

// A one-voxel volume is constant in its box: C = c (1 - e^{-sigma L}) + e^{-sigma L} B with L the
// chord, for a TF knot exactly at the voxel value; three views in one image (layout checked).
TEST(ReferenceContinuous, OneVoxelVolumeSeveralViews) {
  Scene s;
  s.volume.nx = s.volume.ny = s.volume.nz = 1;
  s.volume.data = {0.375f};
  s.box_min = {-0.2, 0.1, -0.4};
  s.box_max = {0.3, 0.4, 0.35};
  s.model = Model::emission_absorption;
  s.tf = pl_tf({{0.2, {1, 0, 0}, 1}, {0.375, {0.2, 0.5, 0.7}, 3.5}, {0.6, {0, 0, 1}, 9}});
  s.background = glm::dvec3(0.05, 0.1, 0.15);
  s.integrator.min_transmittance = 0;
  const glm::dvec3 mid = 0.5 * (s.box_min + s.box_max);
  Camera a, b;
  a.eye = mid + glm::dvec3(1, 0.8, 1.5), a.target = mid, a.fov_y = 35;
  b.eye = mid + glm::dvec3(-1.2, 0.3, -0.4), b.target = mid + glm::dvec3(0, 0.1, 0), b.fov_y = 50;
  Camera c = test::ortho(mid + glm::dvec3(0.3, -2, 0.1), {0, 0, 1}, 6, 5, 0.8);
  c.target = mid;
  for (Camera* k : {&a, &b}) k->width = 6, k->height = 5;
  s.cameras = {a, b, c};
  const Pixels img = reference::render_continuous(s);
  Pixels want;
  int misses = 0;
  for (int v = 0; v < 3; ++v)
    for (int y = 0; y < 5; ++y)
      for (int x = 0; x < 6; ++x) {
        glm::dvec3 o, d;
        reference::ray(s.cameras[v], x, y, &o, &d);
        double t0 = 0, t1 = 0;
        if (!reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1)) ++misses;
        const double T = std::exp(-3.5 * (t1 - t0));
        for (int k = 0; k < 3; ++k)
          want.push_back(glm::dvec3(0.2, 0.5, 0.7)[k] * (1 - T) + T * (*s.background)[k]);
        want.push_back(1 - T);
      }
  EXPECT_GT(misses, 0);
  EXPECT_TRUE(near(img, want, 1e-15, 1e-14, "one voxel"));
  for (int v = 0; v < 3; ++v) {
    Scene one = s;
    one.cameras = {s.cameras[v]};
    const Pixels single = reference::render_continuous(one);
    EXPECT_TRUE(near(single, Pixels(img.begin() + v * 120, img.begin() + (v + 1) * 120), 0, 0));
  }
}

// Varying extinction and colour together: the product volume's emission integrated here as the
// ODE tau' = sigma, C' = e^{-tau} sigma c by classical Runge-Kutta (4th order, fine steps) on each
// clamp piece, where the integrand is smooth (identity and Gaussian TFs).
TEST(ReferenceContinuous, ProductVolumeEmissionAgainstRungeKutta) {
  Product pr;
  Scene& s = pr.s;
  const glm::dvec3 mid = 0.5 * (s.box_min + s.box_max);
  Camera cam;
  cam.eye = mid + glm::dvec3(1.1, 0.8, 1.4), cam.target = mid, cam.fov_y = 22;
  cam.width = 4, cam.height = 3;
  s.cameras = {cam};
  s.model = Model::emission_absorption;
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  TransferFunction gauss;
  gauss.kind = TfKind::gaussian;
  gauss.gaussians = {{0.3, 0.07, {1, 0.2, 0}, 30}, {0.6, 0.2, {0, 0.5, 1}, 5}};
  for (int t = 0; t < 2; ++t) {
    if (t == 0) {
      s.tf = TransferFunction{};
      s.tf.extinction_scale = 7;
      s.tf.color_scale = 0.9;
    } else {
      s.tf = gauss;
    }
    const Pixels img = reference::render_continuous(s);
    Pixels want;
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 4; ++x) {
        glm::dvec3 o, d;
        reference::ray(cam, x, y, &o, &d);
        double t0, t1;
        ASSERT_TRUE(reference::clip_to_box(s.box_min, s.box_max, o, d, &t0, &t1));
        std::vector<double> ts{t0, t1};
        for (int ax = 0; ax < 3; ++ax)
          for (double u : {0.5, (ax == 0 ? 6 : ax == 1 ? 5 : 7) - 0.5}) {
            const double tc = (s.box_min[ax] + u * s.voxel_size()[ax] - o[ax]) / d[ax];
            if (tc > t0 && tc < t1) ts.push_back(tc);
          }
        std::sort(ts.begin(), ts.end());
        auto f = [&](double tt, double tau) {  // (sigma, e^{-tau} sigma c)
          const reference::TfSample q = reference::transfer(s.tf, pr.density(o + tt * d));
          return std::make_pair(q.sigma, std::exp(-tau) * q.emission);
        };
        double tau = 0;
        glm::dvec3 c(0.0);
        for (std::size_t i = 0; i + 1 < ts.size(); ++i) {
          const int n = 6400;
          const double h = (ts[i + 1] - ts[i]) / n;
          for (int k = 0; k < n; ++k) {
            const double a = ts[i] + k * h;
            const auto k1 = f(a, tau), k2 = f(a + h / 2, tau + h / 2 * k1.first),
                       k3 = f(a + h / 2, tau + h / 2 * k2.first), k4 = f(a + h, tau + h * k3.first);
            tau += h / 6 * (k1.first + 2 * k2.first + 2 * k3.first + k4.first);
            c += h / 6 * (k1.second + 2.0 * k2.second + 2.0 * k3.second + k4.second);
          }
        }
        const double T = std::exp(-tau);
        c += T * *s.background;
        want.insert(want.end(), {c.x, c.y, c.z, 1 - T});
      }
    EXPECT_TRUE(near(img, want, 1e-12, 0, "product volume, RK4")) << t;
  }
}

}  // namespace
}  // namespace ivr
