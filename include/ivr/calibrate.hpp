// ivr/calibrate.hpp — measuring a device's cost model for the planner (what `ivr calibrate` runs).
#pragma once
#include <cstdint>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/planner.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

struct CalibrateOptions {
  int volume = 64;  // the Marschner–Lobb volume's edge
  int image = 128;  // the image's width and height
  int repeats = 5;  // timed runs per measurement (median), after one warm-up round
  Precision precision = Precision::f32;
};

struct Calibration {
  CostModel model;
  double render_seconds = 0, adjoint_seconds = 0;  // kernel time, medians
  std::vector<int> lanes;                          // 1, 2, 4, ..., 32
  std::vector<double> forward_seconds;             // one forward pass with that many lanes
  std::vector<int> ray_lanes;                      // 1, 4, 16 voxel lanes (one ray per item)
  std::vector<double> forward_ray_seconds;         // one forward pass with that many
  std::uint64_t samples = 0;                       // of the render
};

// The calibration scene: Marschner–Lobb in a volume³ grid, a four-point emission–absorption TF,
// one perspective image² view from a corner.
IVR_API Scene calibration_scene(int volume, int image);

// Times a render, an adjoint gradient (d mse / d density), forward passes of 1..32 TF and
// background lanes and of 1, 4, 16 voxel lanes on the calibration scene and fits the cost model
// (each forward cost: least squares in the lane count).
IVR_API Calibration calibrate(Device& device, const CalibrateOptions& options = {});

}  // namespace ivr
