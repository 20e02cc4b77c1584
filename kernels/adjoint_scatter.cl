// adjoint_scatter.cl — the adjoint march's cell cache: the ray's current cell in registers, its 8
// corner densities (read once per cell, not once per sample) and the gradient of those corners,
// added to global memory when the ray leaves them behind, so that a ray adds to each voxel it
// touches once. One ray's, or (IVR_RAYS > 1, kernels/rays.cl) every ray's of a packet, each lane
// its own cell, flushing exactly what the one ray would.
#ifndef IVR_ADJOINT_SCATTER_CL
#define IVR_ADJOINT_SCATTER_CL
#include "atomics.cl"
#include "config.cl"
#include "ivr_constants.h"
#include "rays.cl"
#include "scatter_cache.cl"

#ifndef IVR_GRAD_DENSITY
#define IVR_GRAD_DENSITY 1
#endif
#ifndef IVR_DETERMINISTIC
#define IVR_DETERMINISTIC 0
#endif

#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
// The deterministic density gradient (lib/adjoint/adjoint.cpp): integer adds do not depend on their
// order, so each contribution — each sample's part for each corner of its cell — is scaled by 2^S
// and rounded to a long at once; the cell cache then sums longs and adds them with atom_add. How a
// ray's march is cut (cell crossings, the bricks' windows out of core, the slabs' workers) thus
// changes only when its integers are added, never their values: the gradient is the same bits in
// core, out of core and over slabs. `grad` then points at longs: [0] S (the host's, from an
// a-priori bound on one ray's Σ |contribution|: lib/adjoint/adjoint_bound.hpp), [1] the cap on
// one ray's scaled Σ |contribution| (2^62 / rays: no voxel's sum leaves the long range, whatever
// the bound said), [2] contributions or rays over the cap (the bound failed: the host runs again
// at a smaller S), [3] the largest |contribution| and [4] the largest ray's Σ |contribution|, as
// float bits (order-independent atomic_max: the bits S left, and the scale of a second pass), and
// voxel i at [IVR_FIXED_HEADER + i] (kernels/ivr_constants.h).
typedef long GradSum;
inline void fixed_max(volatile __global long* slot, const real value) {
  volatile __global uint* largest = (volatile __global uint*)slot;
  const uint bits = as_uint((float)value);
  if (bits > *largest) atomic_max(largest, bits);  // the plain read only filters
}
// The check at a ray's true end (the in-core march's, or the last brick's: the sum is carried
// across windows, AdjointPrefix.flushed) of its Σ |contribution| against the cap; every lane's.
inline void fixed_ray_end(__global real* grad, const vreal flushed) {
  volatile __global long* fx = (volatile __global long*)grad;
  real f[IVR_RAYS];
  IVR_STORE_RAYS(flushed, f);
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (f[l] == (real)0) continue;
    fixed_max(fx + 4, f[l]);
    if (!(ldexp(f[l], (int)fx[0]) <= (real)fx[1])) atom_inc(fx + 2);
  }
}
#define IVR_ADD_DENSITY_GRAD(c, index, value) \
  atom_add((volatile __global long*)grad.out + IVR_FIXED_HEADER + (index), (value))
// The fixed-point sums back to reals: out[i] = fx[header + i]·2^−S.
__kernel void fixed_to_real(const int n, __global const long* restrict fx,
                            __global real* restrict out) {
  const int i = get_global_id(0);
  if (i < n) out[i] = ldexp((real)fx[IVR_FIXED_HEADER + i], -(int)fx[0]);
}
#else
typedef real GradSum;
// Through the work-group's table where the host turned it on (kernels/scatter_cache.cl).
#define IVR_ADD_DENSITY_GRAD(c, index, value) scatter_add(grad, index, value)
#endif

// The cells of one ray, or of each ray of a packet (lane l), in arrays by corner and lane (the
// lanes' values of corner k side by side, where a packet's samples read them as one vector).
// Corner k (bit 0: +x, bit 1: +y, bit 2: +z) of lane l is voxel base[l] + IVR_CORNER(c, k); the
// offsets are 0 on the clamped upper edges, as in trilinear_at().
typedef struct {
  real v[8][IVR_RAYS];
#if IVR_GRAD_DENSITY
  GradSum g[8][IVR_RAYS];
#endif
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  vreal flushed, largest;  // the ray's Σ |contribution| so far; its largest in this window
  int exponent, over;      // S; the contributions found over the cap
  real cap;
#endif
  int base[IVR_RAYS], ox[IVR_RAYS], oy[IVR_RAYS], oz[IVR_RAYS];  // base < 0: no cell yet
  int ix[IVR_RAYS], iy[IVR_RAYS], iz[IVR_RAYS];
#if IVR_RAYS > 1
  vint cx, cy, cz;  // the lanes' cells as vectors (-1 before the first)
#endif
} CellCache;

// Lane l's cell, as one ray keeps it (the macros read `l`, `volume`, `dims` and `grad`).
#define IVR_CORNER(c, k) \
  ((((k)&1) ? (c)->ox[l] : 0) + (((k)&2) ? (c)->oy[l] : 0) + (((k)&4) ? (c)->oz[l] : 0))
#define IVR_LOAD(c, k) (c)->v[k][l] = volume[(c)->base[l] + IVR_CORNER(c, k)]
#if IVR_GRAD_DENSITY
#define IVR_FLUSH(c, k)                                                               \
  do {                                                                                \
    if ((c)->g[k][l] != (GradSum)0)                                                   \
      IVR_ADD_DENSITY_GRAD(c, (c)->base[l] + IVR_CORNER(c, k), (c)->g[k][l]);         \
    (c)->g[k][l] = (GradSum)0;                                                        \
  } while (0)
#define IVR_MOVE_GRAD(c, to, from)     \
  do {                                 \
    (c)->g[to][l] = (c)->g[from][l];   \
    (c)->g[from][l] = (real)0;         \
  } while (0)
#else
#define IVR_FLUSH(c, k) (void)0
#define IVR_MOVE_GRAD(c, to, from) (void)0
#endif
#define IVR_EACH_CORNER(F, c) \
  do {                        \
    F(c, 0);                  \
    F(c, 1);                  \
    F(c, 2);                  \
    F(c, 3);                  \
    F(c, 4);                  \
    F(c, 5);                  \
    F(c, 6);                  \
    F(c, 7);                  \
  } while (0)

inline void lane_cell_set(CellCache* c, int l, int x, int y, int z, int4 dims) {
  c->ix[l] = x;
  c->iy[l] = y;
  c->iz[l] = z;
  c->base[l] = (z * dims.y + y) * dims.x + x;
  c->ox[l] = x + 1 < dims.x ? 1 : 0;
  c->oy[l] = y + 1 < dims.y ? dims.x : 0;
  c->oz[l] = z + 1 < dims.z ? dims.x * dims.y : 0;
}

// Crossing one face along the axis of bit B: the 4 corners on the shared face carry over, density
// and gradient so far; the 4 left behind are flushed and the 4 ahead read. a..d are the corners
// with bit B clear; L is the bit of those left behind (0 going up, B going down), K = B − L that of
// those kept, which become corners with bit L.
#define IVR_CROSS_ONE(c, x, L, K)                  \
  do {                                             \
    IVR_FLUSH(c, (x) | (L));                       \
    IVR_MOVE_GRAD(c, (x) | (L), (x) | (K));        \
    (c)->v[(x) | (L)][l] = (c)->v[(x) | (K)][l];   \
  } while (0)
#define IVR_CROSS(c, L, K, a, b, cc, d, X, Y, Z) \
  do {                                           \
    IVR_CROSS_ONE(c, a, L, K);                   \
    IVR_CROSS_ONE(c, b, L, K);                   \
    IVR_CROSS_ONE(c, cc, L, K);                  \
    IVR_CROSS_ONE(c, d, L, K);                   \
    lane_cell_set(c, l, X, Y, Z, dims);          \
    IVR_LOAD(c, (a) | (K));                      \
    IVR_LOAD(c, (b) | (K));                      \
    IVR_LOAD(c, (cc) | (K));                     \
    IVR_LOAD(c, (d) | (K));                      \
  } while (0)

inline void lane_cell_init(CellCache* c, int l) {
  c->base[l] = -1;
  c->ix[l] = c->iy[l] = c->iz[l] = c->ox[l] = c->oy[l] = c->oz[l] = 0;
  for (int k = 0; k < 8; ++k) {
    c->v[k][l] = (real)0;
#if IVR_GRAD_DENSITY
    c->g[k][l] = (GradSum)0;
#endif
  }
}

// Makes (x, y, z) lane l's current cell. Into a neighbouring cell (across a face, an edge or a
// corner) one face at a time; a straight ray keeps its direction along each axis, so these
// branches are predictable. Longer jumps and the first cell take the general path.
__attribute__((always_inline)) inline void lane_cell_enter(CellCache* c, int l, int x, int y, int z,
                                                           __global const real* volume, int4 dims,
                                                           const ScatterSink grad) {
  if (c->base[l] >= 0 && x == c->ix[l] && y == c->iy[l] && z == c->iz[l]) return;
  if (c->base[l] < 0 || abs(x - c->ix[l]) > 1 || abs(y - c->iy[l]) > 1 || abs(z - c->iz[l]) > 1) {
    if (c->base[l] >= 0) IVR_EACH_CORNER(IVR_FLUSH, c);
    lane_cell_set(c, l, x, y, z, dims);
    IVR_EACH_CORNER(IVR_LOAD, c);
    return;
  }
  if (x != c->ix[l]) {
    if (x > c->ix[l])
      IVR_CROSS(c, 0, 1, 0, 2, 4, 6, x, c->iy[l], c->iz[l]);
    else
      IVR_CROSS(c, 1, 0, 0, 2, 4, 6, x, c->iy[l], c->iz[l]);
  }
  if (y != c->iy[l]) {
    if (y > c->iy[l])
      IVR_CROSS(c, 0, 2, 0, 1, 4, 5, x, y, c->iz[l]);
    else
      IVR_CROSS(c, 2, 0, 0, 1, 4, 5, x, y, c->iz[l]);
  }
  if (z != c->iz[l]) {
    if (z > c->iz[l])
      IVR_CROSS(c, 0, 4, 0, 1, 2, 3, x, y, z);
    else
      IVR_CROSS(c, 4, 0, 0, 1, 2, 3, x, y, z);
  }
}

// Adds what lane l's corners still hold to global memory (the end of its ray or window).
inline void lane_cell_flush(CellCache* c, int l, const ScatterSink grad) {
  if (c->base[l] >= 0) IVR_EACH_CORNER(IVR_FLUSH, c);
}

// Corner k's values of every lane as one vreal, and back.
#if IVR_RAYS == 1
#define IVR_CORNER_LANES(a) ((a)[0])
#define IVR_SET_CORNER_LANES(a, x) ((a)[0] = (x))
#else
#define IVR_CORNER_LANES(a) IVR_VLOAD(0, a)
#define IVR_SET_CORNER_LANES(a, x) IVR_VSTORE(x, 0, a)
#endif

// `flushed`: the ray's Σ |contribution| before this window (AdjointPrefix.flushed).
inline void cell_init(CellCache* c, const ScatterSink grad, vreal flushed) {
  for (int l = 0; l < IVR_RAYS; ++l) lane_cell_init(c, l);
#if IVR_RAYS > 1
  c->cx = c->cy = c->cz = (vint)-1;
#endif
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  __global const long* fx = (__global const long*)grad.out;
  c->exponent = (int)fx[0];
  c->cap = (real)fx[1];
  c->over = 0;
  c->flushed = flushed;
  c->largest = (vreal)(real)0;
#else
  (void)grad, (void)flushed;
#endif
}

// Makes (x, y, z) the current cell of each ray where `take` holds (one ray: always); in a packet
// the lanes that moved one after another in scalar code, each as its ray would alone (the same
// flushes, at the same points, of the same sums — the fixed-point gradient is the one-ray
// kernel's bit for bit).
__attribute__((always_inline)) inline void cell_enter(CellCache* c, vint x, vint y, vint z,
                                                      __global const real* volume, int4 dims,
                                                      const ScatterSink grad, vint take) {
#if IVR_RAYS == 1
  (void)take;
  lane_cell_enter(c, 0, x, y, z, volume, dims, grad);
#else
  const vint moved = take && (x != c->cx || y != c->cy || z != c->cz);
  if (!vany(moved)) return;
  int flag[IVR_RAYS], xs[IVR_RAYS], ys[IVR_RAYS], zs[IVR_RAYS];
  IVR_VSTORE(moved, 0, flag);
  IVR_VSTORE(x, 0, xs);
  IVR_VSTORE(y, 0, ys);
  IVR_VSTORE(z, 0, zs);
  for (int l = 0; l < IVR_RAYS; ++l)
    if (flag[l]) lane_cell_enter(c, l, xs[l], ys[l], zs[l], volume, dims, grad);
  c->cx = vseli(c->cx, x, moved);
  c->cy = vseli(c->cy, y, moved);
  c->cz = vseli(c->cz, z, moved);
#endif
}

// Every lane's corners into global memory at the end of a window; returns the rays' Σ
// |contribution| so far (AdjointPrefix.flushed; 0 in float sums), whose check waits for the
// ray's end (adjoint_ray_end).
inline vreal cell_flush(CellCache* c, const ScatterSink grad) {
  for (int l = 0; l < IVR_RAYS; ++l) lane_cell_flush(c, l, grad);
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  volatile __global long* fx = (volatile __global long*)grad.out;
  real largest[IVR_RAYS];
  IVR_STORE_RAYS(c->largest, largest);
  for (int l = 0; l < IVR_RAYS; ++l)
    if (largest[l] != (real)0) fixed_max(fx + 3, largest[l]);
  if (c->over) atom_add(fx + 2, (long)c->over);
  return c->flushed;
#else
  (void)grad;
  return (vreal)(real)0;
#endif
}

// The end of the rays' whole march (in core; out of core where the last brick leaves it): the
// fixed-point cap's check of each ray's Σ |contribution|.
inline void adjoint_ray_end(const ScatterSink grad, vreal flushed) {
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  fixed_ray_end(grad.out, flushed);
#else
  (void)grad, (void)flushed;
#endif
}

// trilinear_at()'s interpolation, from the cached corners (every lane of a packet).
__attribute__((always_inline)) inline vreal cell_density(const CellCache* c, vreal fx, vreal fy,
                                                         vreal fz) {
#define IVR_V(k) IVR_CORNER_LANES(c->v[k])
  return vlerp(vlerp(vlerp(IVR_V(0), IVR_V(1), fx), vlerp(IVR_V(2), IVR_V(3), fx), fy),
               vlerp(vlerp(IVR_V(4), IVR_V(5), fx), vlerp(IVR_V(6), IVR_V(7), fx), fy), fz);
#undef IVR_V
}

#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
// One contribution of every lane as its integer, 2^S·w rounded to nearest; one over the cap (or
// not finite) counts and adds nothing — the pass is run again at a smaller S.
__attribute__((always_inline)) inline vlong fixed_of(CellCache* c, vreal w) {
  const vreal a = fabs(w);
  c->flushed += a;  // (a NaN or an infinity stays in it: the host's check of the largest ray)
  c->largest = fmax(c->largest, a);
  const vreal scaled = ldexp(w, c->exponent);
  const vint fits = vmask_of(fabs(scaled) <= (vreal)c->cap);
  if (!vall(fits)) {
    int f[IVR_RAYS];
    IVR_STORE_RAYS(fits, f);
    for (int l = 0; l < IVR_RAYS; ++l) c->over += f[l] ? 0 : 1;
  }
  return vto_long_rte(vsel((vreal)(real)0, scaled, fits));
}
#endif

// Adds gd = dL/d density at fractions (fx, fy, fz) of the current cell to its corners (every
// lane of a packet; a lane that does not sample adds gd = 0).
__attribute__((always_inline)) inline void cell_add(CellCache* c, vreal gd, vreal fx, vreal fy,
                                                    vreal fz) {
#if IVR_GRAD_DENSITY
  const vreal gx0 = gd * ((real)1 - fx), gx1 = gd * fx;
  const vreal wy0z0 = ((real)1 - fy) * ((real)1 - fz), wy1z0 = fy * ((real)1 - fz);
  const vreal wy0z1 = ((real)1 - fy) * fz, wy1z1 = fy * fz;
#if IVR_DETERMINISTIC
#define IVR_ADD(k, w) IVR_SET_CORNER_LANES(c->g[k], IVR_CORNER_LANES(c->g[k]) + fixed_of(c, w))
#else
#define IVR_ADD(k, w) IVR_SET_CORNER_LANES(c->g[k], IVR_CORNER_LANES(c->g[k]) + (w))
#endif
  IVR_ADD(0, gx0 * wy0z0);
  IVR_ADD(1, gx1 * wy0z0);
  IVR_ADD(2, gx0 * wy1z0);
  IVR_ADD(3, gx1 * wy1z0);
  IVR_ADD(4, gx0 * wy0z1);
  IVR_ADD(5, gx1 * wy0z1);
  IVR_ADD(6, gx0 * wy1z1);
  IVR_ADD(7, gx1 * wy1z1);
#undef IVR_ADD
#else
  (void)c, (void)gd, (void)fx, (void)fy, (void)fz;
#endif
}

// One ray's 8 corner densities in corner order (the exact and camera adjoints' cubic and
// gradient): v[k][0] for k = 0..7 lie side by side.
#define IVR_CELL_CORNERS(c) (&(c)->v[0][0])


#endif
