// adjoint_support.hpp — helpers for the gradient tests: float64 losses and central differences,
// errors relative to the largest gradient entry, NaN/Inf checks of a whole AdjointGradient.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "ivr/adjoint.hpp"
#include "ivr/jacobian.hpp"
#include "test_support.hpp"

namespace ivr::test {

// The float64 loss, reduced on the device from float64 pixels (a render's image is float32,
// whose rounding would swamp the differences). Also reports the samples the march took, which
// tells whether a perturbation moved the point where early termination stops a ray.
inline double loss_of(const Scene& s, const Image& target, double step = 0, Loss loss = Loss::mse,
                      std::uint64_t* samples = nullptr) {
  AdjointOptions o;
  o.precision = Precision::f64;
  o.step = step;
  o.loss = loss;
  o.density = false;
  const AdjointGradient g = adjoint(device(), s, target, o);
  if (samples) *samples = g.samples;
  return g.loss;
}

// Central difference of the float64 loss in one scalar of the scene: set(scene, h) adds h to it
// and returns the increment actually applied (float32 voxels round d + h).
template <class Set>
double central_difference(const Scene& s, const Image& target, double h, Set set, double step = 0,
                          Loss loss = Loss::mse, bool same_samples = true) {
  Scene plus = s, minus = s;
  const double hp = set(plus, +h), hm = -set(minus, -h);
  std::uint64_t np = 0, nm = 0, n0 = 0;
  const double lp = loss_of(plus, target, step, loss, &np);
  const double lm = loss_of(minus, target, step, loss, &nm);
  if (same_samples) {
    loss_of(s, target, step, loss, &n0);
    EXPECT_TRUE(np == n0 && nm == n0)
        << "the perturbation moved an early-termination point: samples " << nm << ", " << n0 << ", "
        << np;
  }
  return (lp - lm) / (hp + hm);
}

// Adds h to voxel i; returns the increment the float32 voxel actually received.
inline double nudge_voxel(Scene& s, std::size_t i, double h) {
  const double d = s.volume.data[i];
  s.volume.data[i] = float(d + h);
  return double(s.volume.data[i]) - d;
}

template <class T>
double max_abs(const std::vector<T>& v) {
  double m = 0;
  for (T x : v) m = std::max(m, std::abs(double(x)));
  return m;
}

// max |got - want| / max |want| (0 for two zero vectors); NaN/Inf or a size mismatch give +inf.
template <class A, class B>
double relative_error(const std::vector<A>& got, const std::vector<B>& want) {
  if (got.size() != want.size()) return INFINITY;
  double e = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    if (!std::isfinite(double(got[i])) || !std::isfinite(double(want[i]))) return INFINITY;
    e = std::max(e, std::abs(double(got[i]) - double(want[i])));
  }
  const double scale = max_abs(want);
  return e == 0 ? 0.0 : e / scale;
}

// Every number of a gradient evaluation is finite.
inline ::testing::AssertionResult all_finite(const AdjointGradient& g) {
  if (!std::isfinite(g.loss)) return ::testing::AssertionFailure() << "loss is " << g.loss;
  const auto check = [](const auto& v, const char* what) -> ::testing::AssertionResult {
    for (std::size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(double(v[i])))
        return ::testing::AssertionFailure() << what << "[" << i << "] is " << v[i];
    return ::testing::AssertionSuccess();
  };
  if (auto r = check(g.density, "density"); !r) return r;
  if (auto r = check(g.tf, "tf"); !r) return r;
  return check(g.background, "background");
}

// A random 6x5x4 volume (densities in [0.15, 0.85]) in a non-cubic box, parameters for every TF
// kind, two perspective 6x5 views, step 0.7, early termination off.
inline Scene two_view_scene(Model model, TfKind kind) {
  Scene s;
  s.volume.nx = 6;
  s.volume.ny = 5;
  s.volume.nz = 4;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.15, 0.85);
  for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) s.volume.data.push_back(float(u(rng)));
  set_default_box(s);
  s.model = model;
  s.tf.kind = kind;
  s.tf.extinction_scale = 3;
  s.tf.color_scale = 0.8;
  s.tf.points = {
      {0.1, {0.2, 0.3, 0.9}, 1.0}, {0.45, {0.9, 0.5, 0.1}, 4.0}, {0.8, {1, 1, 0.8}, 2.0}};
  s.tf.range = {0.1, 0.9};
  s.tf.entries = {{0.1, 0.2, 0.9, 0.5}, {0.9, 0.6, 0.2, 3.0}, {0.3, 0.8, 0.4, 1.5}, {1, 1, 1, 4}};
  s.tf.gaussians = {{0.35, 0.15, {0.9, 0.3, 0.2}, 3.0}, {0.7, 0.1, {0.2, 0.6, 1.0}, 5.0}};
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  Camera a, b;
  a.eye = {0.3, 0.4, 1.6};
  b.eye = {-1.4, 0.2, 0.5};
  a.width = b.width = 6;
  a.height = b.height = 5;
  a.fov_y = b.fov_y = 35;
  s.cameras = {a, b};
  s.integrator.step = 0.7;
  s.integrator.min_transmittance = 0;
  return s;
}

// A fixed target: the scene rendered with perturbed densities, so the loss gradient is not zero.
inline Image perturbed_target(const Scene& s) {
  Scene t = s;
  for (std::size_t i = 0; i < t.volume.data.size(); ++i)
    t.volume.data[i] = float(std::min(1.0, t.volume.data[i] * (1.0 + 0.3 * std::sin(double(i)))));
  return render(device(), t, {Precision::f64});
}

// Adds h to TF parameter (row r, column c) in tf_gradient_shape's layout (column 4 of a
// piecewise-linear TF: the control point's density); returns h.
inline double nudge_tf(Scene& x, std::size_t r, std::size_t c, double h) {
  TransferFunction& tf = x.tf;
  switch (tf.kind) {
    case TfKind::identity:
      (c == 0 ? tf.extinction_scale : tf.color_scale) += h;
      break;
    case TfKind::piecewise_linear:
      (c < 3    ? tf.points[r].color[int(c)]
       : c == 3 ? tf.points[r].extinction
                : tf.points[r].density) += h;
      break;
    case TfKind::table:
      tf.entries[r][int(c)] += h;
      break;
    case TfKind::gaussian: {
      TfGaussian& g = tf.gaussians[r];
      double* p[6] = {&g.color.x, &g.color.y, &g.color.z, &g.extinction, &g.mean, &g.width};
      *p[c] += h;
    } break;
  }
  return h;
}

// The value of TF parameter (row r, column c), to scale its difference step.
inline double tf_parameter(const TransferFunction& tf, std::size_t r, std::size_t c) {
  switch (tf.kind) {
    case TfKind::identity:
      return c == 0 ? tf.extinction_scale : tf.color_scale;
    case TfKind::piecewise_linear:
      return c < 3 ? tf.points[r].color[int(c)] : tf.points[r].extinction;
    case TfKind::table:
      return tf.entries[r][int(c)];
    case TfKind::gaussian: {
      const TfGaussian& g = tf.gaussians[r];
      const double p[6] = {g.color.x, g.color.y, g.color.z, g.extinction, g.mean, g.width};
      return p[c];
    }
  }
  return 0;
}

// Adds h to background channel c (the single I_in for absorption); returns h.
inline double nudge_background(Scene& x, int c, double h) {
  glm::dvec3 b = x.effective_background();
  if (x.model == Model::absorption)
    b += h;
  else
    b[c] += h;
  x.background = b;
  return h;
}

// Adds h to parameter p of the scene; returns the increment applied.
inline double nudge(Scene& s, const Parameter& p, double h) {
  switch (p.group) {
    case ParameterGroup::tf:
      return nudge_tf(s, std::size_t(p.index), std::size_t(p.column), h);
    case ParameterGroup::background:
      return nudge_background(s, int(p.index), h);
    case ParameterGroup::camera: {
      Camera& c = s.cameras[std::size_t(p.index)];
      if (p.column < 3)
        c.eye[p.column] += h;
      else if (p.column < 6)
        c.target[p.column - 3] += h;
      else
        c.fov_y += h;
      return h;
    }
    case ParameterGroup::step:
      s.integrator.step += h;
      return h;
    case ParameterGroup::voxel:
      return nudge_voxel(s, std::size_t(p.index), h);
  }
  return 0;
}

}  // namespace ivr::test
