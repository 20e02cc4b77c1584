// design_formulas.hpp — docs/design.md camera rays and ray–box chords in double precision, for tests.
#pragma once
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "ivr/scene.hpp"

namespace ivr::test {

struct Ray {
  glm::dvec3 origin, dir;
};

// The ray through the centre of pixel (x, y), row 0 at the top.
inline Ray design_ray(const Camera& c, int x, int y) {
  const glm::dvec3 fwd = glm::normalize(c.target - c.eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, c.up));
  const glm::dvec3 up = glm::cross(right, fwd);
  const double sx = 2.0 * (x + 0.5) / c.width - 1, sy = 1 - 2.0 * (y + 0.5) / c.height;
  const double aspect = double(c.width) / c.height;
  if (c.projection == Projection::orthographic) {
    const double half = 0.5 * c.ortho_height;
    return {c.eye + sx * half * aspect * right + sy * half * up, fwd};
  }
  const double t = std::tan(0.5 * c.fov_y * M_PI / 180.0);
  return {c.eye, glm::normalize(fwd + sx * t * aspect * right + sy * t * up)};
}

// Length of the ray inside the box (from its origin on), slab method; *t_far = exit distance.
inline double chord(const Ray& r, const glm::dvec3& lo, const glm::dvec3& hi,
                    double* t_far = nullptr) {
  double t0 = 0, t1 = INFINITY;
  for (int a = 0; a < 3; ++a) {
    if (r.dir[a] == 0) {
      if (r.origin[a] < lo[a] || r.origin[a] > hi[a]) return 0;
      continue;
    }
    const double ta = (lo[a] - r.origin[a]) / r.dir[a], tb = (hi[a] - r.origin[a]) / r.dir[a];
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  if (t_far) *t_far = t1 > t0 ? t1 : 0;
  return t1 > t0 ? t1 - t0 : 0;
}

}  // namespace ivr::test
