// bench_scene.hpp — the benchmarks' common scene: ivr::calibration_scene (the Marschner–Lobb
// signal in an n³ volume, a four-point emission–absorption TF, one perspective camera looking at
// the box from a corner), so that benchmarks and `ivr calibrate` measure the same thing.
#pragma once
#include "ivr/core.hpp"

namespace ivr::bench {

inline Scene bench_scene(int n, int image) {
  return calibration_scene(n, image);
}

}  // namespace ivr::bench
