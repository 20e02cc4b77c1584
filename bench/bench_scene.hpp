// bench_scene.hpp — the benchmarks' common scene: the Marschner–Lobb signal in an n³ volume, a
// four-point emission–absorption TF, one perspective camera looking at the box from a corner.
#pragma once
#include "ivr/ivr.hpp"

namespace ivr::bench {

inline Scene bench_scene(int n, int image) {
  Scene s;
  s.volume = synthetic_volume("marschner_lobb", n, n, n);
  set_default_box(s);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0, 0, 0}, 0},
                 {0.35, {0.1, 0.3, 0.9}, 2},
                 {0.55, {0.9, 0.6, 0.2}, 10},
                 {0.8, {1, 1, 0.9}, 30}};
  s.background = glm::dvec3(0.05);
  Camera c;
  c.eye = {1.1, 0.8, 1.5};
  c.target = {0, 0, 0};
  c.fov_y = 38;
  c.width = c.height = image;
  s.cameras = {c};
  s.integrator.min_transmittance = 1e-4;
  return s;
}

}  // namespace ivr::bench
