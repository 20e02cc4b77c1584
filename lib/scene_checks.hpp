// scene_checks.hpp — scene validation with an integrator that overrides the scene's own.
#pragma once
#include "ivr/scene.hpp"

namespace ivr {

// validate(scene) as if scene.integrator were `integrator` (e.g. a --step override).
void validate_with(const Scene& scene, const Integrator& integrator);

}  // namespace ivr
