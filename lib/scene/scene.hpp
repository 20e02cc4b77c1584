// scene.hpp — scene validation with an integrator that overrides the scene's own.
#pragma once
#include "ivr/error.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// validate(scene) as if scene.integrator were `integrator` (e.g. a --step override).
void validate_with(const Scene& scene, const Integrator& integrator);
// The same without the densities (dims, box, cameras, TF, background, integrator): what a
// session checks on the host; its device pass checks the values.
void validate_description(const Scene& scene, const Integrator& integrator);
// The error for voxel i of `volume` holding `value` (not finite, or negative).
Error bad_density(const Volume& volume, std::size_t i, double value);

// A number as error messages show it (the shortest of 6 significant digits: 0.001, 1e+30, nan).
std::string number_text(double v);

// The grid (dims), box and cameras only: what the projector needs (lib/tomo/project.cpp).
void validate_geometry(const Scene& scene);

// A loss target must have the render's shape (views, H, W, C) and finite values; throws
// ivr::Error(invalid_argument) naming the shapes or the first bad element.
void check_target(const Scene& scene, const Image& target);

}  // namespace ivr
