// march.cl — where a ray meets the box and how the fixed-step integrators cut it: n equal
// segments of at most `step` covering the clipped interval exactly, and the ray in continuous
// voxel coordinates u(t) = u0 + t·du (voxel centre i at u = i).
#ifndef IVR_MARCH_CL
#define IVR_MARCH_CL
#include "config.cl"
#include "geometry.cl"

// Scalars rather than real3: PoCL compiles real3 into padded 4-wide vectors and lane shuffles.
typedef struct {
  real t0, t1;  // the ray inside the box, t0 >= 0
  real dt;      // segment length
  uint n;       // segments
  real u0x, u0y, u0z, dux, duy, duz;
} March;

// Sets *m for the ray; false where the ray misses the box (then *m is unset).
inline bool march_begin(Ray ray, real4 box_min, real4 box_max, real4 inv_voxel, real step,
                        March* m) {
  if (!clip_box(ray, box_min.xyz, box_max.xyz, &m->t0, &m->t1)) return false;
  const real length = m->t1 - m->t0;
  m->n = max((uint)1, (uint)ceil(length / step));
  m->dt = length / (real)m->n;
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
