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

// The axis (0, 1, 2) of the brick plane that ends the window at `tb` (brick_window's end: the same
// expressions, so the same bits), -1 where none does (the ray's own end, or a ±∞ box face).
inline int brick_window_end_axis(real u0x, real u0y, real u0z, real dux, real duy, real duz,
                                 real4 lo, real4 hi, real tb) {
  const real u0[3] = {u0x, u0y, u0z}, du[3] = {dux, duy, duz};
  const real l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; ++a)
    if (du[a] != (real)0 && fmax((l[a] - u0[a]) / du[a], (h[a] - u0[a]) / du[a]) == tb) return a;
  return -1;
}

#endif
