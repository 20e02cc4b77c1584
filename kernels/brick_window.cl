// brick_window.cl — a ray's part inside one brick of a bricked volume (docs/scaling.md): the
// brick's planes cut the ray's global march, computed from the global march alone so that the
// windows of one ray in neighbouring bricks meet at the same value and partition the ray exactly.
#ifndef IVR_BRICK_WINDOW_CL
#define IVR_BRICK_WINDOW_CL
#include "config.cl"

// Cuts [*ta, *tb] to the ray's part with lo <= u < hi on one axis (u = u0 + t·du, global
// voxel-centre coordinates; ±∞ planes at the box faces); a ray parallel to the planes is inside
// where lo <= u0 < hi, so that it lies in exactly one brick.
inline void brick_slab(real u0, real du, real lo, real hi, real* ta, real* tb) {
  if (du != (real)0) {
    const real a = (lo - u0) / du, b = (hi - u0) / du;
    *ta = fmax(*ta, fmin(a, b));
    *tb = fmin(*tb, fmax(a, b));
  } else if (!(u0 >= lo && u0 < hi)) {
    *tb = -INFINITY;
  }
}

// The window [*ta, *tb] (empty where !(*tb > *ta)) of the march from u0 along du in the brick with
// planes [lo, hi).
inline void brick_window(real u0x, real u0y, real u0z, real dux, real duy, real duz, real4 lo,
                         real4 hi, real* ta, real* tb) {
  brick_slab(u0x, dux, lo.x, hi.x, ta, tb);
  brick_slab(u0y, duy, lo.y, hi.y, ta, tb);
  brick_slab(u0z, duz, lo.z, hi.z, ta, tb);
}

#endif
