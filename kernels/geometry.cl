// geometry.cl — camera rays, exact ray–box clipping and trilinear density with DESIGN.md's
// conventions (values at cell centres, clamped to the edge centres inside the box).
#ifndef IVR_GEOMETRY_CL
#define IVR_GEOMETRY_CL
#include "config.cl"

typedef struct {
  real3 origin;
  real3 dir;  // unit length
} Ray;

// Ray through the centre of pixel (x, y), row 0 at the top.
inline Ray camera_ray(__global const real* cam, int x, int y, int width, int height) {
  const real sx = (real)2 * ((real)x + (real)0.5) / (real)width - (real)1;
  const real sy = (real)1 - (real)2 * ((real)y + (real)0.5) / (real)height;
  const real3 eye = (real3)(cam[0], cam[1], cam[2]);
  const real3 fwd = (real3)(cam[3], cam[4], cam[5]);
  const real3 right = (real3)(cam[6], cam[7], cam[8]);
  const real3 up = (real3)(cam[9], cam[10], cam[11]);
  Ray r;
  if (cam[12] != (real)0) {  // orthographic
    r.origin = eye + sx * right + sy * up;
    r.dir = fwd;
  } else {
    r.origin = eye;
    r.dir = normalize(fwd + sx * right + sy * up);
  }
  return r;
}

// Slab test for one axis; shrinks [*t0, *t1]. A ray parallel to the slab keeps its interval when
// its origin lies within the (closed) slab and empties it otherwise.
inline void clip_slab(real o, real d, real lo, real hi, real* t0, real* t1) {
  if (d != (real)0) {
    const real inv = (real)1 / d;
    const real ta = (lo - o) * inv, tb = (hi - o) * inv;
    *t0 = fmax(*t0, fmin(ta, tb));
    *t1 = fmin(*t1, fmax(ta, tb));
  } else if (o < lo || o > hi) {
    *t1 = (real)-1;
  }
}

// Parameter interval of the ray inside the box, starting no earlier than the origin.
inline bool clip_box(Ray r, real3 bmin, real3 bmax, real* t0, real* t1) {
  *t0 = (real)0;
  *t1 = INFINITY;
  clip_slab(r.origin.x, r.dir.x, bmin.x, bmax.x, t0, t1);
  clip_slab(r.origin.y, r.dir.y, bmin.y, bmax.y, t0, t1);
  clip_slab(r.origin.z, r.dir.z, bmin.z, bmax.z, t0, t1);
  return *t0 < *t1;
}

// Trilinear density at continuous voxel coordinates u (voxel centre i at u = i), clamped to the
// edge centres: the value is constant in the outer half-voxel.
inline real trilinear(__global const real* vol, int4 dims, real3 u) {
  u = clamp(u, (real3)(0), convert_real3(dims.xyz - 1));
  const int3 i0 = convert_int3(u);  // u >= 0, so truncation is floor
  const int3 i1 = min(i0 + 1, dims.xyz - 1);
  const real3 f = u - convert_real3(i0);
  const int sx = dims.x, sxy = dims.x * dims.y;
  const int z0 = i0.z * sxy, z1 = i1.z * sxy, y0 = i0.y * sx, y1 = i1.y * sx;
  const real c00 = mix(vol[z0 + y0 + i0.x], vol[z0 + y0 + i1.x], f.x);
  const real c10 = mix(vol[z0 + y1 + i0.x], vol[z0 + y1 + i1.x], f.x);
  const real c01 = mix(vol[z1 + y0 + i0.x], vol[z1 + y0 + i1.x], f.x);
  const real c11 = mix(vol[z1 + y1 + i0.x], vol[z1 + y1 + i1.x], f.x);
  return mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
}

#endif
