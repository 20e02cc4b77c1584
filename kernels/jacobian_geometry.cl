// jacobian_geometry.cl — forward-mode derivatives of the geometry: a pixel's ray with respect to
// its camera's eye, target and fov_y, and the ray–box entry and exit with respect to the ray.
#ifndef IVR_GEOMETRY_TANGENT_CL
#define IVR_GEOMETRY_TANGENT_CL
#include "geometry.cl"

#include "ivr_constants.h"  // IVR_CAMERA_PARAMS_STRIDE: the camera-parameter layout

inline real component(real3 v, int axis) {
  return axis == 0 ? v.x : (axis == 1 ? v.y : v.z);
}

// d origin and d direction of the ray through (sx, sy) (camera_ray()'s screen coordinates) for a
// unit change of camera component k: 0..2 eye, 3..5 target, 6 fov_y in degrees. docs/design.md's
// camera: f = normalize(target - eye), r = normalize(f x up), u = r x f.
inline void camera_ray_tangent(__global const real* cp, real sx, real sy, int k, real3* dorigin,
                               real3* ddir) {
  const real3 eye = (real3)(cp[0], cp[1], cp[2]);
  const real3 target = (real3)(cp[3], cp[4], cp[5]);
  const real3 up = (real3)(cp[6], cp[7], cp[8]);
  const real aspect = cp[10];
  const real one = (real)1, zero = (real)0;
  const real3 de = (real3)(k == 0 ? one : zero, k == 1 ? one : zero, k == 2 ? one : zero);
  const real3 dt = (real3)(k == 3 ? one : zero, k == 4 ? one : zero, k == 5 ? one : zero);
  const real dfov = k == 6 ? (real)0.017453292519943295 : (real)0;  // radians per degree
  // d normalize(v) = (dv - n (n . dv)) / |v|
  const real3 fr = target - eye, dfr = dt - de;
  const real fl = length(fr);
  const real3 f = fr / fl, df = (dfr - f * dot(f, dfr)) / fl;
  const real3 rr = cross(f, up), drr = cross(df, up);
  const real rl = length(rr);
  const real3 r = rr / rl, dr = (drr - r * dot(r, drr)) / rl;
  const real3 u = cross(r, f), du = cross(dr, f) + cross(r, df);
  if (cp[12] != (real)0) {  // orthographic: origin = eye + sx·h·aspect·r + sy·h·u, dir = f
    const real h = (real)0.5 * cp[11];
    *dorigin = de + sx * h * aspect * dr + sy * h * du;
    *ddir = df;
  } else {  // dir = normalize(f + sx·tan(fov/2)·aspect·r + sy·tan(fov/2)·u)
    const real th = tan((real)0.5 * (real)0.017453292519943295 * cp[9]);
    const real dth = ((real)1 + th * th) * (real)0.5 * dfov;
    const real3 v = f + sx * th * aspect * r + sy * th * u;
    const real3 dv = df + sx * aspect * (dth * r + th * dr) + sy * (dth * u + th * du);
    const real vl = length(v);
    const real3 dir = v / vl;
    *dorigin = de;
    *ddir = (dv - dir * dot(dir, dv)) / vl;
  }
}

// The box face whose plane meets the ray at `t` as the entry (`entry`) or exit of clip_box(): its
// axis, or -1 where none does. t moves with the ray as dt = -(d o_a + t · d dir_a) / dir_a on the
// plane of axis a. A ray list's march may begin at a face behind its origin (t <= 0).
inline int face_axis(Ray ray, real3 bmin, real3 bmax, real t, bool entry) {
  for (int a = 0; a < 3; ++a) {
    const real o = component(ray.origin, a), d = component(ray.dir, a);
    if (d == (real)0) continue;
    // As clip_slab() computes them, bit for bit.
    const real ta = geometry_divide(component(bmin, a) - o, d),
               tb = geometry_divide(component(bmax, a) - o, d);
    if ((entry ? fmin(ta, tb) : fmax(ta, tb)) == t) return a;
  }
  return -1;
}

// The slab that sets t0 of a camera ray's clip_box() (`entry`) or t1 (exit): its axis, or -1
// where t0 is the ray's origin (t0 = 0: the camera is inside the box).
inline int clip_axis(Ray ray, real3 bmin, real3 bmax, real t, bool entry) {
  if (entry && t <= (real)0) return -1;
  return face_axis(ray, bmin, bmax, t, entry);
}

#endif
