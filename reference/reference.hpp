// reference.hpp — an independent double-precision CPU evaluation of docs/design.md's continuous model
// (density, camera rays, transfer functions, both optical models), the yardstick for the kernels.
#pragma once
#include <limits>
#include <glm/vec3.hpp>
#include <vector>

#include "ivr/scene.hpp"

namespace ivr::reference {

// Trilinear density between cell centres, clamped to the edge centres inside the box, 0 outside.
double density(const ivr::Scene& scene, glm::dvec3 world_point);

// A pixel of a view, for what depends on more than its ray (the sample count).
struct Pixel {
  int view, x, y;
};

// The ray through the centre of pixel (x, y), row 0 at the top; dir is unit length.
void ray(const ivr::Camera& camera, int x, int y, glm::dvec3* origin, glm::dvec3* dir);

// Extinction sigma(d) and emission sigma(d)*colour(d) of the scene's transfer function.
struct TfSample {
  double sigma = 0;
  glm::dvec3 emission{0.0};  // sigma * colour
};
TfSample transfer(const ivr::TransferFunction& tf, double d);

// Parameter interval [t0, t1] of the ray inside the closed box within [lo, hi] (a camera's rays:
// from the origin on; a ray list's: its own interval); false if it is empty.
bool clip_to_box(const glm::dvec3& box_min, const glm::dvec3& box_max, const glm::dvec3& origin,
                 const glm::dvec3& dir, double* t0, double* t1, double lo = 0.0,
                 double hi = std::numeric_limits<double>::infinity());

// [t0, t1] cut where the ray o + t·dir crosses a plane through voxel centres, sorted (t0 and t1
// included): between two cuts the trilinear density is one polynomial in t.
std::vector<double> centre_plane_cuts(const ivr::Scene& scene, const glm::dvec3& o,
                                      const glm::dvec3& dir, double t0, double t1);

// Images of shape (views, H, W, C) like ivr::Image, integrated with a midpoint rule on the
// continuous integrand with sub-intervals of at most step_world (world units). With
// early_termination the march stops once exp(-tau) < scene.integrator.min_transmittance.
std::vector<double> render(const ivr::Scene& scene, double step_world,
                           bool early_termination = false);

// The `midpoint` integrator's own discretisation in double precision: each ray clipped to the box
// is cut into n = max(1, ceil((t1 − t0) / step_world)) equal segments sampled at their midpoints
// and composited exactly; with early_termination it stops after the sample that takes the
// transmittance below scene.integrator.min_transmittance. What a float32 midpoint render equals up
// to rounding (the benchmarks check renders against it before timing them).
// render() and render_midpoint() take a scene's ray list as they take its cameras (rays in
// order, each over its own interval; the sample count sample_count.hpp's ray-list definition).
std::vector<double> render_midpoint(const ivr::Scene& scene, double step_world,
                                    bool early_termination = false);

// The smallest voxel edge in world units (the unit of the integrator's step).
double min_voxel_edge(const ivr::Scene& scene);

// --- High-accuracy references (reference_continuous.cpp) ---------------------------------------
// Both integrate per ray "pieces" on which the density is a polynomial in t (a cubic between the
// planes through voxel centres, or a linear profile), split further where the density crosses a
// knot of a piecewise-linear or table TF, then use 8-point Gauss-Legendre on sub-intervals of
// optical depth <= 1 (emission-absorption), with the transmittance at each node from the exact
// spectral integration matrix of the same nodes. Emission-absorption rays stop once exp(-tau)
// < 1e-300 (the rest contributes nothing representable).

// The continuous integral of docs/design.md with no step parameter (same layout as render). With
// early_termination the ray stops exactly where tau reaches -log(min_transmittance): the output
// then holds transmittance min_transmittance and the emission up to that point. `refinement` > 1
// subdivides every sub-interval that many times more (for self-convergence checks only).
std::vector<double> render_continuous(const ivr::Scene& scene, bool early_termination = false,
                                      int refinement = 1);

// The exact optical depth int sigma(d(t)) dt along the ray origin + t*dir, t >= 0 (dir is
// normalised here, so t is in world units).
double optical_depth(const ivr::Scene& scene, glm::dvec3 origin, glm::dvec3 dir);

// The definition of the `preintegrated` integrator: each ray clipped to the box [t0, t1] is cut
// into n = max(1, ceil((t1 - t0) / step_world)) equal segments; the densities at their ends come
// from `density` (at points clamped into the closed box, which they lie in but for rounding); on
// each segment the density is taken linear between its ends and the optical model is integrated
// exactly (to ~1e-13) along that profile through the TF. No early termination.
std::vector<double> render_linear_segments(const ivr::Scene& scene, double step_world);

}  // namespace ivr::reference
