// march.cl — where a ray meets the box and how the fixed-step integrators cut it: n equal
// segments of at most `step` (n from sample_count.cl) covering the clipped interval exactly, and the ray in continuous
// voxel coordinates u(t) = u0 + t·du (voxel centre i at u = i).
#ifndef IVR_MARCH_CL
#define IVR_MARCH_CL
#include "config.cl"
#include "geometry.cl"
#include "sample_count.cl"

// Scalars rather than real3: PoCL compiles real3 into padded 4-wide vectors and lane shuffles.
typedef struct {
  real t0, t1;  // the ray inside the box, t0 >= 0
  real dt;      // segment length
  uint n;       // segments
  real u0x, u0y, u0z, dux, duy, duz;
} March;

// Sets *m for `ray`, the ray of pixel (x, y) of camera `cam`; false where it misses the box
// (then *m is unset). Whether it meets the box and its segment count n come from
// sample_count.cl's definition, which no precision, device or compiler moves; the interval and
// positions are this precision's. Where the two disagree on a grazing ray (a hit here, an empty
// interval in this precision), the n samples lie at t0 with dt = 0 and add nothing.
inline bool march_begin(Ray ray, __global const real* cam, int x, int y, int width, int height,
                        real4 box_min, real4 box_max, real4 inv_voxel, real step, March* m) {
  m->n = sample_count(cam, x, y, width, height, box_min, box_max, step);
  if (m->n == 0u) return false;
  clip_box(ray, box_min.xyz, box_max.xyz, &m->t0, &m->t1);
  if (!(m->t1 > m->t0)) m->t1 = m->t0;  // also a parallel ray's t1 = −1 outside a slab
  const real length = m->t1 - m->t0;
  m->dt = geometry_divide(length, (real)m->n);
  m->u0x = (ray.origin.x - box_min.x) * inv_voxel.x - (real)0.5;
  m->u0y = (ray.origin.y - box_min.y) * inv_voxel.y - (real)0.5;
  m->u0z = (ray.origin.z - box_min.z) * inv_voxel.z - (real)0.5;
  m->dux = ray.dir.x * inv_voxel.x;
  m->duy = ray.dir.y * inv_voxel.y;
  m->duz = ray.dir.z * inv_voxel.z;
  return true;
}

// Ray parameter of sample i: segment midpoints (midpoint) or segment ends (i = 0..n).
inline real sample_t(const March* m, uint i) {
#if IVR_ENDPOINT_SAMPLES
  return m->t0 + (real)i * m->dt;
#else
  return m->t0 + ((real)i + (real)0.5) * m->dt;
#endif
}

#endif
