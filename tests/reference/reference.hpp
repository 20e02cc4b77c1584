// reference.hpp — an independent double-precision CPU evaluation of DESIGN.md's continuous model
// (density, camera rays, transfer functions, both optical models), the yardstick for the kernels.
#pragma once
#include <glm/vec3.hpp>
#include <vector>

#include "ivr/scene.hpp"

namespace ivr::reference {

// Trilinear density between cell centres, clamped to the edge centres inside the box, 0 outside.
double density(const ivr::Scene& scene, glm::dvec3 world_point);

// The ray through the centre of pixel (x, y), row 0 at the top; dir is unit length.
void ray(const ivr::Camera& camera, int x, int y, glm::dvec3* origin, glm::dvec3* dir);

// Extinction sigma(d) and emission sigma(d)*colour(d) of the scene's transfer function.
struct TfSample {
  double sigma = 0;
  glm::dvec3 emission{0.0};  // sigma * colour
};
TfSample transfer(const ivr::TransferFunction& tf, double d);

// Parameter interval [t0, t1] (t0 >= 0) of the ray inside the closed box; false if it misses.
bool clip_to_box(const glm::dvec3& box_min, const glm::dvec3& box_max, const glm::dvec3& origin,
                 const glm::dvec3& dir, double* t0, double* t1);

// Images of shape (views, H, W, C) like ivr::Image, integrated with a midpoint rule on the
// continuous integrand with sub-intervals of at most step_world (world units). With
// early_termination the march stops once exp(-tau) < scene.integrator.min_transmittance.
std::vector<double> render(const ivr::Scene& scene, double step_world,
                           bool early_termination = false);

// The smallest voxel edge in world units (the unit of the integrator's step).
double min_voxel_edge(const ivr::Scene& scene);

}  // namespace ivr::reference
