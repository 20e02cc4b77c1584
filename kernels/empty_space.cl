// empty_space.cl — empty-space skipping: the brick a sample reads, and where the ray leaves it
// (lib/empty_space.cpp builds the occupancy grid on the host).
#ifndef IVR_EMPTY_SPACE_CL
#define IVR_EMPTY_SPACE_CL
#include "config.cl"

// The brick of the cell that trilinear_at() reads at u (clamped as there).
__attribute__((always_inline)) inline int brick_axis(real u, int n) {
  return (int)fmin(fmax(u, (real)0), (real)(n - 1)) / IVR_BRICK_SIZE;
}

// The ray parameter at which u = u0 + t·du leaves brick b of `bricks` along this axis; +inf
// where it never does (parallel, or the brick is the last one the ray meets on this axis).
__attribute__((always_inline)) inline real brick_exit(real u0, real du, int b, int bricks) {
  if (du > (real)0 && b + 1 < bricks) return ((real)((b + 1) * IVR_BRICK_SIZE) - u0) / du;
  if (du < (real)0 && b > 0) return ((real)(b * IVR_BRICK_SIZE) - u0) / du;
  return (real)INFINITY;
}

// The ray parameter at which the ray leaves brick (bx, by, bz).
__attribute__((always_inline)) inline real brick_leave(real u0x, real u0y, real u0z, real dux,
                                                       real duy, real duz, int bx, int by, int bz,
                                                       int4 bricks) {
  return fmin(brick_exit(u0x, dux, bx, bricks.x),
              fmin(brick_exit(u0y, duy, by, bricks.y), brick_exit(u0z, duz, bz, bricks.z)));
}

// The index of the first sample (midpoints t0 + (i + 1/2)·dt) at or past `exit`, where the ray
// leaves the empty brick that sample i is in; at least i + 1, at most n. Rounding may move a sample
// on the brick's face to either side: the grid's one-voxel margin keeps both sides' densities in
// the brick's range.
__attribute__((always_inline)) inline uint skip_to(uint i, uint n, real t0, real dt, real exit) {
  const real k = ceil((exit - t0) / dt - (real)0.5);
  return k >= (real)n ? n : max(i + 1, (uint)fmax(k, (real)0));
}

// In a marching loop `for (uint i = 0; i < n;)` that advances i at the end of its body: when
// sample i (at voxel coordinates u) lies in an empty brick, jump i to the first sample past it
// and go on with the loop (`continue`). Samples there add nothing: σ = 0, so no emission and no
// attenuation. Names the kernel's own dims, occupied, bricks, t0, dt, u0*, du*.
#define IVR_SKIP_EMPTY_BRICK(i, n, ux, uy, uz)                                                 \
  {                                                                                            \
    const int bx_ = brick_axis(ux, dims.x), by_ = brick_axis(uy, dims.y),                      \
              bz_ = brick_axis(uz, dims.z);                                                    \
    if (!occupied[(bz_ * bricks.y + by_) * bricks.x + bx_]) {                                  \
      i = skip_to(i, n, t0, dt, brick_leave(u0x, u0y, u0z, dux, duy, duz, bx_, by_, bz_, bricks)); \
      continue;                                                                                \
    }                                                                                          \
  }

// Per brick (one work-item each): the min and max density over the voxels its samples read,
// [b·size − 1, (b+1)·size + 1] clamped along each axis (lib/empty_space.hpp), as float pairs.
__kernel void brick_ranges(__global const real* restrict volume, const int4 dims, const int4 bricks,
                           __global float* restrict ranges) {
  const int bx = get_global_id(0), by = get_global_id(1), bz = get_global_id(2);
  if (bx >= bricks.x || by >= bricks.y || bz >= bricks.z) return;
  const int x0 = max(bx * IVR_BRICK_SIZE - 1, 0),
            x1 = min((bx + 1) * IVR_BRICK_SIZE + 1, dims.x - 1);
  const int y0 = max(by * IVR_BRICK_SIZE - 1, 0),
            y1 = min((by + 1) * IVR_BRICK_SIZE + 1, dims.y - 1);
  const int z0 = max(bz * IVR_BRICK_SIZE - 1, 0),
            z1 = min((bz + 1) * IVR_BRICK_SIZE + 1, dims.z - 1);
  real lo = (real)INFINITY, hi = -(real)INFINITY;
  for (int z = z0; z <= z1; ++z)
    for (int y = y0; y <= y1; ++y) {
      __global const real* row = volume + ((size_t)z * dims.y + y) * dims.x;
      for (int x = x0; x <= x1; ++x) {
        lo = fmin(lo, row[x]);
        hi = fmax(hi, row[x]);
      }
    }
  const size_t b = ((size_t)bz * bricks.y + by) * bricks.x + bx;
  // As floats (nearest): the host widens every range by 1e-6 relative before using it.
  ranges[2 * b] = (float)lo;
  ranges[2 * b + 1] = (float)hi;
}

#endif
