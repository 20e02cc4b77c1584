// adjoint_scatter.cl — the adjoint march's cell cache: the ray's current cell in registers, its 8
// corner densities (read once per cell, not once per sample) and the gradient of those corners,
// added to global memory when the ray leaves them behind, so that a ray adds to each voxel it
// touches once.
#ifndef IVR_ADJOINT_SCATTER_CL
#define IVR_ADJOINT_SCATTER_CL
#include "atomics.cl"
#include "config.cl"
#include "ivr_constants.h"
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
// order, so each contribution is scaled by 2^S, rounded to a long and added with atom_add. `grad`
// then points at longs: [0] S (the host's, from an a-priori bound on one ray's Σ |contribution|:
// lib/adjoint/adjoint_bound.hpp), [1] the cap on one ray's scaled Σ |contribution| (2^62 / rays: no
// voxel's sum leaves the long range, whatever the bound said), [2] rays (or single
// contributions) over the cap: the bound failed, the host runs again at a smaller S, [3] the
// largest |contribution| and [4] the largest ray's Σ |contribution|, as float bits
// (order-independent atomic_max: the bits S left, and the scale of a second pass), and voxel i at
// [IVR_FIXED_HEADER + i] (kernels/ivr_constants.h).
inline void fixed_max(volatile __global long* slot, const real value) {
  volatile __global uint* largest = (volatile __global uint*)slot;
  const uint bits = as_uint((float)value);
  if (bits > *largest) atomic_max(largest, bits);  // the plain read only filters
}
// `flushed` sums the ray's |contributions| (cell_flush checks it at the ray's end).
inline void fixed_add(__global real* grad, real* flushed, const int index, const real value) {
  volatile __global long* fx = (volatile __global long*)grad;
  fixed_max(fx + 3, fabs(value));
  *flushed += fabs(value);
  const real scaled = ldexp(value, (int)fx[0]);
  if (!(fabs(scaled) <= (real)fx[1])) {  // over the ray's own cap already (or not finite)
    atom_inc(fx + 2);
    return;
  }
  atom_add(fx + IVR_FIXED_HEADER + index, convert_long_rte(scaled));
}
inline void fixed_ray_end(__global real* grad, const real flushed) {
  volatile __global long* fx = (volatile __global long*)grad;
  fixed_max(fx + 4, flushed);
  if (!(ldexp(flushed, (int)fx[0]) <= (real)fx[1])) atom_inc(fx + 2);
}
#define IVR_ADD_DENSITY_GRAD(c, index, value) fixed_add(grad.out, &(c)->flushed, index, value)

// The fixed-point sums back to reals: out[i] = fx[header + i]·2^−S.
__kernel void fixed_to_real(const int n, __global const long* restrict fx,
                            __global real* restrict out) {
  const int i = get_global_id(0);
  if (i < n) out[i] = ldexp((real)fx[IVR_FIXED_HEADER + i], -(int)fx[0]);
}
#else
// Through the work-group's table where the host turned it on (kernels/scatter_cache.cl).
#define IVR_ADD_DENSITY_GRAD(c, index, value) scatter_add(grad, index, value)
#endif

// Corner k (bit 0: +x, bit 1: +y, bit 2: +z) is voxel base + IVR_CORNER(c, k); the offsets are 0
// on the clamped upper edges, as in trilinear_at().
typedef struct {
  real v[8];
#if IVR_GRAD_DENSITY
  real g[8];
#endif
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  real flushed;  // Σ |contribution| the ray has added so far
#endif
  int base, ox, oy, oz, ix, iy, iz;  // base < 0: no cell yet
} CellCache;

#define IVR_CORNER(c, k) \
  ((((k)&1) ? (c)->ox : 0) + (((k)&2) ? (c)->oy : 0) + (((k)&4) ? (c)->oz : 0))
#define IVR_LOAD(c, k) (c)->v[k] = volume[(c)->base + IVR_CORNER(c, k)]
#if IVR_GRAD_DENSITY
#define IVR_FLUSH(c, k)                                                                          \
  do {                                                                                           \
    if ((c)->g[k] != (real)0) IVR_ADD_DENSITY_GRAD(c, (c)->base + IVR_CORNER(c, k), (c)->g[k]); \
    (c)->g[k] = (real)0;                                                                         \
  } while (0)
#define IVR_MOVE_GRAD(c, to, from) \
  do {                             \
    (c)->g[to] = (c)->g[from];     \
    (c)->g[from] = (real)0;        \
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

inline void cell_set(CellCache* c, int x, int y, int z, int4 dims) {
  c->ix = x;
  c->iy = y;
  c->iz = z;
  c->base = (z * dims.y + y) * dims.x + x;
  c->ox = x + 1 < dims.x ? 1 : 0;
  c->oy = y + 1 < dims.y ? dims.x : 0;
  c->oz = z + 1 < dims.z ? dims.x * dims.y : 0;
}

// Crossing one face along the axis of bit B: the 4 corners on the shared face carry over, density
// and gradient so far; the 4 left behind are flushed and the 4 ahead read. a..d are the corners
// with bit B clear; L is the bit of those left behind (0 going up, B going down), K = B − L that of
// those kept, which become corners with bit L.
#define IVR_CROSS_ONE(c, x, L, K)           \
  do {                                      \
    IVR_FLUSH(c, (x) | (L));                \
    IVR_MOVE_GRAD(c, (x) | (L), (x) | (K)); \
    (c)->v[(x) | (L)] = (c)->v[(x) | (K)];  \
  } while (0)
#define IVR_CROSS(c, L, K, a, b, cc, d, X, Y, Z) \
  do {                                           \
    IVR_CROSS_ONE(c, a, L, K);                   \
    IVR_CROSS_ONE(c, b, L, K);                   \
    IVR_CROSS_ONE(c, cc, L, K);                  \
    IVR_CROSS_ONE(c, d, L, K);                   \
    cell_set(c, X, Y, Z, dims);                  \
    IVR_LOAD(c, (a) | (K));                      \
    IVR_LOAD(c, (b) | (K));                      \
    IVR_LOAD(c, (cc) | (K));                     \
    IVR_LOAD(c, (d) | (K));                      \
  } while (0)

inline void cell_init(CellCache* c) {
  c->base = -1;
  c->ix = c->iy = c->iz = c->ox = c->oy = c->oz = 0;
#if IVR_GRAD_DENSITY
  for (int k = 0; k < 8; ++k) c->g[k] = (real)0;
#endif
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  c->flushed = (real)0;
#endif
}

// Makes (x, y, z) the current cell. Into a neighbouring cell (across a face, an edge or a corner)
// one face at a time; a straight ray keeps its direction along each axis, so these branches are
// predictable. Longer jumps and the first cell take the general path.
__attribute__((always_inline)) inline void cell_enter(CellCache* c, int x, int y, int z,
                                                      __global const real* volume, int4 dims,
                                                      const ScatterSink grad) {
  if (c->base >= 0 && x == c->ix && y == c->iy && z == c->iz) return;
  if (c->base < 0 || abs(x - c->ix) > 1 || abs(y - c->iy) > 1 || abs(z - c->iz) > 1) {
    if (c->base >= 0) IVR_EACH_CORNER(IVR_FLUSH, c);
    cell_set(c, x, y, z, dims);
    IVR_EACH_CORNER(IVR_LOAD, c);
    return;
  }
  if (x != c->ix) {
    if (x > c->ix)
      IVR_CROSS(c, 0, 1, 0, 2, 4, 6, x, c->iy, c->iz);
    else
      IVR_CROSS(c, 1, 0, 0, 2, 4, 6, x, c->iy, c->iz);
  }
  if (y != c->iy) {
    if (y > c->iy)
      IVR_CROSS(c, 0, 2, 0, 1, 4, 5, x, y, c->iz);
    else
      IVR_CROSS(c, 2, 0, 0, 1, 4, 5, x, y, c->iz);
  }
  if (z != c->iz) {
    if (z > c->iz)
      IVR_CROSS(c, 0, 4, 0, 1, 2, 3, x, y, z);
    else
      IVR_CROSS(c, 4, 0, 0, 1, 2, 3, x, y, z);
  }
}

// trilinear_at()'s interpolation, from the registers.
__attribute__((always_inline)) inline real cell_density(const CellCache* c, real fx, real fy,
                                                        real fz) {
  return lerp(lerp(lerp(c->v[0], c->v[1], fx), lerp(c->v[2], c->v[3], fx), fy),
              lerp(lerp(c->v[4], c->v[5], fx), lerp(c->v[6], c->v[7], fx), fy), fz);
}

// Adds gd = dL/d density at fractions (fx, fy, fz) of the current cell to its corners.
__attribute__((always_inline)) inline void cell_add(CellCache* c, real gd, real fx, real fy,
                                                    real fz) {
#if IVR_GRAD_DENSITY
  const real gx0 = gd * ((real)1 - fx), gx1 = gd * fx;
  const real wy0z0 = ((real)1 - fy) * ((real)1 - fz), wy1z0 = fy * ((real)1 - fz);
  const real wy0z1 = ((real)1 - fy) * fz, wy1z1 = fy * fz;
  c->g[0] += gx0 * wy0z0;
  c->g[1] += gx1 * wy0z0;
  c->g[2] += gx0 * wy1z0;
  c->g[3] += gx1 * wy1z0;
  c->g[4] += gx0 * wy0z1;
  c->g[5] += gx1 * wy0z1;
  c->g[6] += gx0 * wy1z1;
  c->g[7] += gx1 * wy1z1;
#else
  (void)c, (void)gd, (void)fx, (void)fy, (void)fz;
#endif
}

// Adds what the current cell's corners still hold to global memory (the end of the ray); in fixed
// point, checks the ray's Σ |contribution| against the cap.
inline void cell_flush(CellCache* c, const ScatterSink grad) {
  if (c->base >= 0) IVR_EACH_CORNER(IVR_FLUSH, c);
#if IVR_GRAD_DENSITY && IVR_DETERMINISTIC
  fixed_ray_end(grad.out, c->flushed);
#endif
}

#endif
