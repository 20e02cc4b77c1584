// bench_scene.hpp — the benchmarks' common scenes: ivr::calibration_scene (the Marschner–Lobb
// signal in an n³ volume, a four-point emission–absorption TF, one perspective camera looking at
// the box from a corner), so that benchmarks and `ivr calibrate` measure the same thing, and the
// tomography scene.
#pragma once
#include <cmath>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::bench {

inline Scene bench_scene(int n, int image) {
  return calibration_scene(n, image);
}

// The benchmark scene in another look: "" as it is; "identity" (σ = 20·d, colour d); "absorption"
// (the TF at a quarter of its extinction: optical depths of a few per ray); "trapezoid" and
// "preintegrated" (those integrators); "exact" (absorption, as "absorption", the exact integral).
inline Scene look_scene(int n, int image, const std::string& look) {
  Scene s = bench_scene(n, image);
  if (look == "identity") {
    s.tf.kind = TfKind::identity;
    s.tf.extinction_scale = 20;
    s.tf.color_scale = 1;
  } else if (look == "absorption" || look == "exact") {
    s.model = Model::absorption;
    s.background.reset();
    for (TfPoint& p : s.tf.points) p.extinction *= 0.25;
    if (look == "exact") s.integrator.scheme = Scheme::exact;
  } else if (look == "preintegrated") {
    s.integrator.scheme = Scheme::preintegrated;
  } else if (look == "trapezoid") {
    s.integrator.scheme = Scheme::trapezoid;
  }
  return s;
}

// n³ Shepp–Logan (cell averages of 4³ samples) in the unit box, `views` cameras over a half orbit
// about z: parallel beam with an n×n detector as wide as the box, or cone beam from distance 2.
inline Scene tomo_scene(int n, int views, bool cone, int supersample = 4) {
  Scene s;
  s.volume = phantom("shepp-logan", n, 1, supersample);
  s.model = Model::absorption;
  set_default_box(s);
  for (int k = 0; k < views; ++k) {
    const double a = M_PI * k / views;
    Camera c;
    c.eye = {2 * std::cos(a), 2 * std::sin(a), 0};
    c.up = {0, 0, 1};
    c.width = c.height = n;
    if (cone) {
      c.fov_y = 45;
    } else {
      c.projection = Projection::orthographic;
      c.ortho_height = 1.0;
    }
    s.cameras.push_back(c);
  }
  return s;
}

// The phantom's TF of the test suite (tests/reconstruct/reconstruct_support.hpp): every density visible.
inline TransferFunction phantom_tf() {
  TransferFunction tf;
  tf.kind = TfKind::piecewise_linear;
  tf.points = {{0, {0, 0, 0}, 0}, {1, {1, 0.7, 0.4}, 8}, {2, {0.5, 0.8, 1}, 16}};
  return tf;
}

// Cameras on a circle about `axis` at distance 2.2, 40° field of view.
inline std::vector<Camera> orbit(int views, glm::dvec3 axis, double start_deg, int size) {
  axis = glm::normalize(axis);
  const glm::dvec3 helper = std::abs(axis.x) > 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 e1 = glm::normalize(helper - glm::dot(helper, axis) * axis);
  const glm::dvec3 e2 = glm::cross(axis, e1);
  std::vector<Camera> out;
  for (int k = 0; k < views; ++k) {
    const double a = (start_deg + 360.0 * k / views) * M_PI / 180;
    Camera c;
    c.eye = 2.2 * (std::cos(a) * e1 + std::sin(a) * e2);
    c.up = axis;
    c.fov_y = 40;
    c.width = c.height = size;
    out.push_back(c);
  }
  return out;
}

inline Scene phantom_scene(int n, std::vector<Camera> cameras) {
  Scene s;
  s.volume = phantom("shepp-logan", n, 1, 2);
  set_default_box(s);
  s.tf = phantom_tf();
  s.background = glm::dvec3(0);
  s.cameras = std::move(cameras);
  return s;
}

}  // namespace ivr::bench
