// accuracy_suite.hpp — the scenes of the speed-against-error suite (ivr-bench's integrators suite):
// synthetic (smooth blob, sharp shell, Marschner–Lobb) and real volumes (headsq, neghip, tooth,
// C60, MNI152 from ../shared/data), each under the suite's transfer functions and models.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::bench {

// A transfer function and optical model the suite renders every volume with.
struct SuiteLook {
  std::string name;  // "ramps", "band", "absorption"
  Model model;
  std::string tf_json;
};

// ramps: emission–absorption, σ = 0 below density 0.1, two ramps up to 60 (a smooth TF);
// band: emission–absorption, a narrow band (σ up to 80 between densities 0.30 and 0.36, colour
// changing across it) on a faint ramp — the high-frequency TF that pre-integration is made for;
// absorption: the absorption model through ramps scaled to optical depths of a few per ray.
std::vector<SuiteLook> suite_looks();

struct SuiteVolume {
  std::string name;
  Volume volume;
  double empty = 0;  // the share of voxels below density 0.1 (σ = 0 under every look)
};

// The suite's volumes: the three synthetic ones at 64³, and those real ones found in `data`
// (skipped with a note on stderr when missing; none when quick).
std::vector<SuiteVolume> suite_volumes(const std::string& data, bool quick);

// The scene of a volume under a look: default box, two perspective views of image² pixels, no
// early termination (the error is then the integrator's alone).
Scene suite_scene(const SuiteVolume& volume, const SuiteLook& look, int image);

// Relative RMS ‖a − r‖₂/‖r‖₂ and relative max max|a − r|/max|r| over every element.
struct RelativeError {
  double rms = 0, max = 0;
};
RelativeError relative_error(const std::vector<float>& a, const std::vector<double>& r);

// The time at which the (time, error) curve reaches `target`, interpolated log-log between the
// two points around it, taking the points in order of time; NaN when none reaches it.
double time_at(std::vector<std::pair<double, double>> curve, double target);

}  // namespace ivr::bench
