// tolerance.cpp — error-targeted stepping: pilot renders at a quarter of the resolution, the
// Richardson estimate of the scheme's error, and the step that meets the tolerance.
#include "ivr/tolerance.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "ivr/error.hpp"
#include "scene_checks.hpp"

namespace ivr {

namespace {

// Order of the step error of every fixed-step scheme (midpoint, trapezoid, preintegrated).
constexpr double kOrder = 2;
// The step aims at this fraction of the tolerance: the estimate is a model, not a bound.
constexpr double kSafety = 0.5;

// The scene seen by the pilots: every camera at a quarter of the resolution (at least 8 pixels a
// side), the same views and fields of view; no tolerance of its own.
Scene pilot_scene(const Scene& scene) {
  Scene pilot = scene;
  pilot.integrator.tolerance = 0;
  const int w = scene.cameras.front().width, h = scene.cameras.front().height;
  if (w <= 8 || h <= 8) return pilot;  // small images: every ray
  for (Camera& c : pilot.cameras) {
    c.width = std::max(8, w / 4);
    c.height = std::max(8, h / 4);
  }
  return pilot;
}

// Richardson's estimate of the relative RMS error at step s from renders at s and s/2.
double estimated_error(Device& device, const Scene& pilot, double s, Precision precision,
                       EmptySpace empty_space) {
  RenderOptions o;
  o.precision = precision;
  o.empty_space = empty_space;
  o.step = s;
  const Image coarse = render(device, pilot, o);
  o.step = s / 2;
  const Image fine = render(device, pilot, o);
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < fine.pixels.size(); ++i) {
    const double d = double(coarse.pixels[i]) - double(fine.pixels[i]);
    diff += d * d;
    norm += double(fine.pixels[i]) * double(fine.pixels[i]);
  }
  if (!(norm > 0)) return diff > 0 ? INFINITY : 0.0;  // a black image: any error is relative ∞
  return std::sqrt(diff / norm) / (1 - std::pow(2.0, -kOrder));
}

}  // namespace

StepChoice choose_step(Device& device, const Scene& scene, double tolerance, Precision precision,
                       EmptySpace empty_space) {
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw Error(Status::invalid_argument,
                "integrator.tolerance: must be > 0, got " + std::to_string(tolerance));
  const auto start = std::chrono::steady_clock::now();
  StepChoice c;
  c.step = scene.integrator.step;
  if (scene.integrator.scheme == Scheme::exact) return c;  // no step error to control
  validate(scene);
  // Differences below float32 rounding would read as no error at all.
  if (tolerance < 1e-5 && device.info().fp64) precision = Precision::f64;
  const Scene pilot = pilot_scene(scene);
  double s = 1.0;
  for (int round = 0; round < 4; ++round) {
    const double e = estimated_error(device, pilot, s, precision, empty_space);
    c.pilots += 2;
    const double target =
        std::clamp(e > 0 ? s * std::pow(kSafety * tolerance / e, 1 / kOrder) : kToleranceMaxStep,
                   kToleranceMinStep, kToleranceMaxStep);
    c.step = target;
    c.estimated_error = e * std::pow(target / s, kOrder);
    // Trust the power law only near where it was measured; else pilot again closer.
    if (target >= s / 2 && target <= 2 * s) break;
    s = std::clamp(target, s / 8, 4 * s);
  }
  c.reached = c.estimated_error <= tolerance;
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return c;
}

Integrator integrator_for(Device& device, const Scene& scene, double step_override,
                          Precision precision, EmptySpace empty_space, StepChoice* choice) {
  Integrator it = scene.integrator;
  StepChoice c;
  if (step_override != 0) {
    it.step = step_override;
  } else if (it.tolerance > 0) {
    c = choose_step(device, scene, it.tolerance, precision, empty_space);
    it.step = c.step;
  }
  c.step = it.step;
  if (choice) *choice = c;
  return it;
}

}  // namespace ivr
