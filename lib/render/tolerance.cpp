// tolerance.cpp — error-targeted stepping: pilot renders at a quarter of the resolution (a pilot
// session sharing the densities on the device), the Richardson estimate of the scheme's error,
// and the step that meets the tolerance.
#include "ivr/tolerance.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "ivr/error.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"
#include "render/render.hpp"
#include "render/tolerance.hpp"

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
  if (scene.has_ray_list()) {  // a ray list: every k-th ray, at most ~4096 of them
    const std::size_t n = scene.rays.count(), k = std::max<std::size_t>(1, n / 4096);
    pilot.rays.values.clear();
    for (std::size_t i = 0; i < n; i += k)
      pilot.rays.values.insert(pilot.rays.values.end(), scene.rays.values.begin() + i * 8,
                               scene.rays.values.begin() + (i + 1) * 8);
    return pilot;
  }
  const int w = scene.cameras.front().width, h = scene.cameras.front().height;
  if (w <= 8 || h <= 8) return pilot;  // small images: every ray
  for (Camera& c : pilot.cameras) {
    c.width = std::max(8, w / 4);
    c.height = std::max(8, h / 4);
  }
  return pilot;
}

// Richardson's estimate of the relative RMS error at step s from renders at s and s/2 by the
// pilot session.
double estimated_error(Session::Impl& pilot, double s) {
  Integrator it = pilot.scene.integrator;
  auto render_at = [&](double step) {
    it.step = step;
    pilot.scene.integrator = it;
    pilot.resolved.reset();
    return enqueue_render(pilot, pilot.begin("pilot render")).to_floats();
  };
  const std::vector<float> coarse = render_at(s), fine = render_at(s / 2);
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < fine.size(); ++i) {
    const double d = double(coarse[i]) - double(fine[i]);
    diff += d * d;
    norm += double(fine[i]) * double(fine[i]);
  }
  if (!(norm > 0)) return diff > 0 ? INFINITY : 0.0;  // a black image: any error is relative ∞
  return std::sqrt(diff / norm) / (1 - std::pow(2.0, -kOrder));
}

}  // namespace

StepChoice choose_session_step(Session::Impl& s, double tolerance) {
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw Error(Status::invalid_argument,
                "integrator.tolerance: must be > 0, got " + std::to_string(tolerance));
  const auto start = std::chrono::steady_clock::now();
  StepChoice c;
  c.step = s.scene.integrator.step;
  if (s.scene.integrator.scheme == Scheme::exact) return c;  // no step error to control
  // Differences below float32 rounding would read as no error at all.
  SessionOptions o = s.options;
  o.step = 0;
  if (tolerance < 1e-5 && s.dev.info.fp64) o.precision = Precision::f64;
  // The pilots march the session's own densities (converted where the precision differs).
  Session::Impl pilot(s.device, pilot_scene(s.scene), o, false);
  if (o.precision == s.options.precision) {
    pilot.volume = s.volume;
  } else {
    pilot.volume = make_array(s.device, s.dev, s.volume.shape(), real_dtype(pilot.f64),
                              "the pilots' densities");
    cl_call("converting the densities for the pilots", [&] {
      pilot.arrays.convert(buffer_of(s.volume), s.volume.dtype(), buffer_of(pilot.volume),
                           pilot.volume.dtype(), s.volume.size());
    });
  }
  pilot.has_volume = true;
  pilot.volume_min = s.volume_min;
  pilot.volume_max = s.volume_max;
  pilot.host_volume = s.host_volume;
  double step = 1.0;
  for (int round = 0; round < 4; ++round) {
    const double e = estimated_error(pilot, step);
    c.pilots += 2;
    const double target =
        std::clamp(e > 0 ? step * std::pow(kSafety * tolerance / e, 1 / kOrder) : kToleranceMaxStep,
                   kToleranceMinStep, kToleranceMaxStep);
    c.step = target;
    c.estimated_error = e * std::pow(target / step, kOrder);
    // Trust the power law only near where it was measured; else pilot again closer.
    if (target >= step / 2 && target <= 2 * step) break;
    step = std::clamp(target, step / 8, 4 * step);
  }
  c.reached = c.estimated_error <= tolerance;
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return c;
}

StepChoice choose_step(Device& device, const Scene& scene, double tolerance, Precision precision,
                       EmptySpace empty_space) {
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw Error(Status::invalid_argument,
                "integrator.tolerance: must be > 0, got " + std::to_string(tolerance));
  if (scene.integrator.scheme == Scheme::exact) return StepChoice{scene.integrator.step};
  SessionOptions o;
  o.precision = precision;
  o.empty_space = empty_space;
  Session session = one_shot_session(device, scene, o);
  return choose_session_step(session.impl(), tolerance);
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
