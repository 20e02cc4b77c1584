// ivr/tolerance.hpp — error-targeted stepping: the integrator step that keeps a render's error
// under a requested tolerance (scene "integrator": {"tolerance": ε}).
#pragma once
#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// The error a tolerance bounds: the relative RMS error of the whole image against the
// continuous integral, ‖I − I*‖₂ / ‖I*‖₂ over every pixel and channel of every view.
struct StepChoice {
  double step = 0;             // voxel units (the scene's own for `exact`, which has no step error)
  double estimated_error = 0;  // predicted relative RMS error at that step
  bool reached = true;         // false: even the smallest step allowed is estimated above ε
  int pilots = 0;              // pilot renders taken
  double seconds = 0;          // host time spent choosing
};

// Smallest and largest steps a tolerance may choose (voxel units): beyond 16 voxels a march takes
// a handful of samples per ray and can step over whole features that no pilot sees either.
constexpr double kToleranceMinStep = 1.0 / 512, kToleranceMaxStep = 16.0;

// Chooses the step for `tolerance` (> 0) before rendering: the error of the scene's scheme is
// estimated from pilot renders of the scene's cameras at a quarter of the resolution at two steps s
// and s/2 (Richardson: e(s) ≈ ‖I_s − I_s/2‖ / (1 − 2^−p), p = 2 for every fixed-step scheme),
// starting at one voxel and re-piloted near the answer; the step returned has an estimated error
// of half the tolerance, e(s)·(s'/s)^p = ε/2. Renders use it when the scene asks for a tolerance.
// Throws ivr::Error(invalid_argument) for a tolerance that is not > 0.
IVR_API StepChoice choose_step(Device& device, const Scene& scene, double tolerance,
                               Precision precision = Precision::f32,
                               EmptySpace empty_space = EmptySpace::automatic);

// The integrator a render of `scene` uses: its own, with `step_override` (> 0) or, where the
// scene asks for a tolerance (and no override), the chosen step. *choice (optional) receives the
// choice (step = the step used either way).
IVR_API Integrator integrator_for(Device& device, const Scene& scene, double step_override,
                                  Precision precision, EmptySpace empty_space,
                                  StepChoice* choice = nullptr);

}  // namespace ivr
