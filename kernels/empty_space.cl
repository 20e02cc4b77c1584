// empty_space.cl — empty-space skipping: the brick a sample reads, where the ray leaves it, and
// the brick ranges behind the occupancy grid (lib/empty_space/empty_space.cpp maps them through the
// TF).
#ifndef IVR_EMPTY_SPACE_CL
#define IVR_EMPTY_SPACE_CL
#include "config.cl"
#include "march.cl"

// Each function takes one ray or every ray of a packet (kernels/rays.cl), lane by lane the same.

// The brick of the cell that trilinear_at() reads at u (clamped as there).
__attribute__((always_inline)) inline vint brick_axis(vreal u, int n) {
  return vto_int(vclamp(u, (real)0, (real)(n - 1))) / IVR_BRICK_SIZE;
}

// The ray parameter at which u = u0 + t·du leaves brick b of `bricks` along this axis; +inf
// where it never does (parallel, or the brick is the last one the ray meets on this axis).
__attribute__((always_inline)) inline vreal brick_exit(vreal u0, vreal du, vint b, int bricks) {
  const vint up = vmask_of(du > (real)0) && (b + 1 < bricks);
  const vint down = vmask_of(du < (real)0) && (b > 0);
  const vreal face = vto_real(vseli(b, b + 1, up) * IVR_BRICK_SIZE);
  return vsel((vreal)(real)INFINITY, (face - u0) / du, up || down);
}

// The ray parameter at which the ray leaves brick (bx, by, bz).
__attribute__((always_inline)) inline vreal brick_leave(const March* m, vint bx, vint by, vint bz,
                                                        int4 bricks) {
  return fmin(
      brick_exit(m->u0x, m->dux, bx, bricks.x),
      fmin(brick_exit(m->u0y, m->duy, by, bricks.y), brick_exit(m->u0z, m->duz, bz, bricks.z)));
}

// Where voxel coordinates u lie in an empty brick, the ray parameter at which the ray leaves
// that brick (+inf where it never does); -1 where the brick is occupied.
__attribute__((always_inline)) inline vreal empty_brick_exit(vreal ux, vreal uy, vreal uz,
                                                             const March* m, int4 dims,
                                                             __global const uchar* occupied,
                                                             int4 bricks) {
  const vint bx = brick_axis(ux, dims.x), by = brick_axis(uy, dims.y), bz = brick_axis(uz, dims.z);
  const vint full = vgather_flag(occupied, (bz * bricks.y + by) * bricks.x + bx);
#if IVR_RAYS == 1
  if (full) return (real)-1;  // the exit only where it is needed
#endif
  return vsel(brick_leave(m, bx, by, bz, bricks), (vreal)(real)-1, full);
}

// Midpoint samples t0 + (i + 1/2)·dt: the first one at or past `exit`, where the ray leaves the
// empty brick that sample i is in; at least i + 1, at most n. Rounding may move a sample on the
// brick's face to either side: the grid's one-voxel margin keeps both sides' densities in the
// brick's range.
__attribute__((always_inline)) inline vint skip_to(vint i, vint n, vreal t0, vreal dt, vreal exit) {
  const vreal k = ceil((exit - t0) / dt - (real)0.5);
  return vseli(max(i + 1, vto_int(fmax(k, (vreal)(real)0))), n, vmask_of(k >= vto_real(n)));
}

// End samples t0 + i·dt: the last one before `exit`, where the ray leaves the empty brick that
// sample i is in (at least i, at most n). Every segment between sample i and it has both ends in
// that brick, so its densities, and any density between them, lie in the brick's range, where
// σ = 0: the segments add nothing, whatever the integrator does between its ends.
__attribute__((always_inline)) inline vint last_sample_before(vint i, vint n, vreal t0, vreal dt,
                                                              vreal exit) {
  const vreal k = ceil((exit - t0) / dt) - (real)1;
  return vseli(max(i, vto_int(fmax(k, (vreal)(real)0))), n, vmask_of(k >= vto_real(n)));
}

// End-sample schemes: where sample i (at voxel coordinates u) lies in an empty brick, the last
// sample before the ray leaves it (last_sample_before), and on through the following empty bricks:
// where sample k + 1 past the exit lies in an empty brick that touches the current one (face, edge
// or corner), the segment [k, k + 1] adds nothing either — both bricks' ranges hold their shared
// margin voxels, so they overlap and σ = 0 on every density between the two ends, whatever the
// integrator does between them. i where sample i's brick is occupied, and for the rays where
// `active` is false.
__attribute__((always_inline)) inline vint endpoint_skip(vint i, vint n, vreal ux, vreal uy,
                                                         vreal uz, const March* m, int4 dims,
                                                         __global const uchar* occupied,
                                                         int4 bricks, vint active) {
  const vreal exit = empty_brick_exit(ux, uy, uz, m, dims, occupied, bricks);
  vint go = active && vmask_of(exit >= (real)0);
  if (!vany(go)) return i;
  vint k = vseli(i, last_sample_before(i, n, m->t0, m->dt, exit), go);
  vint bx = brick_axis(ux, dims.x), by = brick_axis(uy, dims.y), bz = brick_axis(uz, dims.z);
  go = go && (k < n);
  while (vany(go)) {
    const vreal t = m->t0 + vto_real(k + 1) * m->dt;
    const vint cx = brick_axis(IVR_POINT(m, t, x), dims.x),
               cy = brick_axis(IVR_POINT(m, t, y), dims.y),
               cz = brick_axis(IVR_POINT(m, t, z), dims.z);
    go = go && !(abs(cx - bx) > 1u || abs(cy - by) > 1u || abs(cz - bz) > 1u ||
                 vgather_flag(occupied, (cz * bricks.y + cy) * bricks.x + cx));
    if (!vany(go)) break;
    const vreal leave = brick_leave(m, cx, cy, cz, bricks);
    k = vseli(k, last_sample_before(k + 1, n, m->t0, m->dt, leave), go);
    bx = vseli(bx, cx, go), by = vseli(by, cy, go), bz = vseli(bz, cz, go);
    go = go && (k < n);
  }
  return k;
}

// The midpoint marches' skipping step at sample i (voxel coordinates u): the live rays whose
// sample lies in an empty brick move i past it (skip_to), and those now past their last sample
// stop. Returns the rays that sample in this round (none: the march goes round again).
__attribute__((always_inline)) inline vint midpoint_skip(vint* i, vint n, vint* live, vreal ux,
                                                         vreal uy, vreal uz, const March* m,
                                                         int4 dims, __global const uchar* occupied,
                                                         int4 bricks) {
  const vreal exit = empty_brick_exit(ux, uy, uz, m, dims, occupied, bricks);
  const vint skip = *live && vmask_of(exit >= (real)0);
  if (vany(skip)) {
    *i = vseli(*i, skip_to(*i, n, m->t0, m->dt, exit), skip);
    *live = *live && (*i < n);
  }
  return *live && !skip;
}

// The end-sample marches' skipping step from sample i (voxel coordinates u): the live rays move i
// to endpoint_skip()'s sample, and those now at their last stop. Returns the rays that moved and
// go on, whose sample i the march takes again.
__attribute__((always_inline)) inline vint endpoint_skip_step(vint* i, vint n, vint* live, vreal ux,
                                                              vreal uy, vreal uz, const March* m,
                                                              int4 dims,
                                                              __global const uchar* occupied,
                                                              int4 bricks) {
  const vint k = endpoint_skip(*i, n, ux, uy, uz, m, dims, occupied, bricks, *live);
  const vint moved = *live && (k > *i);
  if (!vany(moved)) return moved;
  *i = vseli(*i, k, moved);
  *live = *live && (*i < n);
  return moved && *live;
}

// Per brick (one work-item each): the min and max density over the voxels its samples read,
// [b·size − 1, (b+1)·size + 1] clamped along each axis (lib/empty_space/empty_space.hpp), as float
// pairs.
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
