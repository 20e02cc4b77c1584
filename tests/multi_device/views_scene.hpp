// views_scene.hpp — the several-device and data-parallel tests' scene: a random 7×9 emission–
// absorption volume seen by `views` cameras around it, each view a share to split.
#pragma once
#include <cmath>
#include <random>

#include "test_support.hpp"

namespace ivr::test {

inline Scene views_scene(int views) {
  Scene s = constant_scene(0.5f, 7, 9);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (float& v : s.volume.data) v = u(rng);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.1, 0.2, 0.3}, 0.5}, {0.6, {1.0, 0.6, 0.2}, 9.0}, {1.0, {0.3, 0.9, 0.4}, 4.0}};
  s.background = {0.1, 0.2, 0.3};
  s.cameras.clear();
  for (int v = 0; v < views; ++v) {
    Camera c;
    c.eye = {2 * std::sin(v * 1.1), 0.5 - 0.2 * v, 2 * std::cos(v * 1.1)};
    c.width = 9, c.height = 8;
    s.cameras.push_back(c);
  }
  return s;
}

}  // namespace ivr::test
