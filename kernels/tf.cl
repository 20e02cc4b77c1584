// tf.cl — the transfer functions of docs/design.md: extinction sigma(d) and, for emission–absorption,
// the premultiplied emission sigma(d)·colour(d). Only the scene's TF kind is compiled.
#ifndef IVR_TF_CL
#define IVR_TF_CL
#include "config.cl"
#include "rays.cl"

// Packed parameters per kind (the host writes them in this layout):
//   identity:          none; scalars = (extinction_scale, color_scale)
//   piecewise_linear:  rows [density, r, g, b, sigma], sorted by density
//   table:             rows [r, g, b, sigma]; scalars = (lo, hi)
//   gaussian:          rows [mean, width, r, g, b, extinction]
#include "ivr_constants.h"  // IVR_TF_STRIDE_*: the row widths above

// sigma(d), and with IVR_EMISSION the premultiplied emission in (*er, *eg, *eb), for one ray or
// every ray of a packet (kernels/rays.cl). Scalars rather than real3 because PoCL compiles real3
// into padded 4-wide vectors with lane shuffles around them.
// *segment is the piecewise-linear search's cursor: a marching loop starts it at 0 and passes it
// from one sample to the next; densities along a ray are continuous, so the search mostly stays
// put or moves one segment instead of scanning from the first point. The segment found, and so
// the value, is the same from any start. A packet, whose rays would each move their own cursor
// through gathers, blends every segment instead (the TF's rows are the same for every ray:
// broadcasts), to the same value. Other kinds ignore it.
__attribute__((always_inline)) inline vreal tf_sample(vreal d, __global const real* tf, int count,
                                                      real4 scalars, vint* segment, vreal* er,
                                                      vreal* eg, vreal* eb) {
#if IVR_TF == IVR_TF_IDENTITY
  (void)tf, (void)count, (void)segment;
  const vreal sigma = scalars.x * d;
#if IVR_EMISSION
  *er = *eg = *eb = sigma * scalars.y * d;
#endif
  return sigma;

#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR
  (void)scalars;
#if IVR_RAYS == 1
  // Constant beyond the ends; in between, linear on the segment [d_k, d_k+1) holding d.
  __global const real* a = tf;
  __global const real* b = tf;
  real w = (real)0;
  if (d >= tf[(count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR]) {
    a = b = tf + (count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR;
  } else if (d > tf[0]) {  // so count >= 2, and the k with d_k <= d < d_k+1 exists
    int k = *segment;
    while (k > 0 && tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR] > d) --k;
    while (tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR] <= d) ++k;
    *segment = k;
    a = tf + k * IVR_TF_STRIDE_PIECEWISE_LINEAR;
    b = a + IVR_TF_STRIDE_PIECEWISE_LINEAR;
    w = (d - a[0]) / (b[0] - a[0]);  // b[0] > d >= a[0], never zero
  }
  const real sigma = lerp(a[4], b[4], w);
#if IVR_EMISSION
  *er = sigma * lerp(a[1], b[1], w);
  *eg = sigma * lerp(a[2], b[2], w);
  *eb = sigma * lerp(a[3], b[3], w);
#endif
  return sigma;
#else
  // The first point's values below it, the segment [d_k, d_k+1) holding d, the last point's
  // values from it on: lerp(a, a, 0) = a, so each is the one-ray search's value bit for bit.
  (void)segment;
  const int last = (count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR;
  vreal sigma = (vreal)tf[4], r = (vreal)tf[1], g = (vreal)tf[2], b = (vreal)tf[3];
  for (int k = 0; k + 1 < count; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_PIECEWISE_LINEAR;
    __global const real* q = p + IVR_TF_STRIDE_PIECEWISE_LINEAR;
    const vint in = vmask_of(d >= p[0]) && vmask_of(d < q[0]) && vmask_of(d > tf[0]);
    if (!vany(in)) continue;
    const vreal w = (d - p[0]) / (q[0] - p[0]);
    sigma = vsel(sigma, vlerp((vreal)p[4], (vreal)q[4], w), in);
    r = vsel(r, vlerp((vreal)p[1], (vreal)q[1], w), in);
    g = vsel(g, vlerp((vreal)p[2], (vreal)q[2], w), in);
    b = vsel(b, vlerp((vreal)p[3], (vreal)q[3], w), in);
  }
  const vint beyond = vmask_of(d >= tf[last]);
  sigma = vsel(sigma, (vreal)tf[last + 4], beyond);
#if IVR_EMISSION
  *er = sigma * vsel(r, (vreal)tf[last + 1], beyond);
  *eg = sigma * vsel(g, (vreal)tf[last + 2], beyond);
  *eb = sigma * vsel(b, (vreal)tf[last + 3], beyond);
#endif
  return sigma;
#endif

#elif IVR_TF == IVR_TF_TABLE
  // R entries at evenly spaced densities lo..hi, linear in between, constant beyond.
  (void)segment;
  const vreal u =
      clamp((d - scalars.x) / (scalars.y - scalars.x), (real)0, (real)1) * (real)(count - 1);
  const vint i0 = min(vto_int(u), count - 1);
  const vint i1 = min(i0 + 1, count - 1);
  const vreal w = u - vto_real(i0);
  const vint a = i0 * IVR_TF_STRIDE_TABLE, b = i1 * IVR_TF_STRIDE_TABLE;
  const vreal sigma = vlerp(vgather(tf, a + 3), vgather(tf, b + 3), w);
#if IVR_EMISSION
  *er = sigma * vlerp(vgather(tf, a), vgather(tf, b), w);
  *eg = sigma * vlerp(vgather(tf, a + 1), vgather(tf, b + 1), w);
  *eb = sigma * vlerp(vgather(tf, a + 2), vgather(tf, b + 2), w);
#endif
  return sigma;

#elif IVR_TF == IVR_TF_GAUSSIAN
  (void)scalars, (void)segment;
  vreal sigma = (vreal)(real)0;
#if IVR_EMISSION
  vreal r = sigma, g = sigma, bl = sigma;
#endif
  for (int k = 0; k < count; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_GAUSSIAN;
    const vreal z = (d - p[0]) / p[1];
    const vreal s = p[5] * vexp((real)-0.5 * z * z);
    sigma += s;
#if IVR_EMISSION
    r += s * p[2];
    g += s * p[3];
    bl += s * p[4];
#endif
  }
#if IVR_EMISSION
  *er = r;
  *eg = g;
  *eb = bl;
#endif
  return sigma;
#else
#error "unknown IVR_TF"
#endif
}

#if IVR_RAYS == 1
// sigma(d), and with IVR_EMISSION the premultiplied emission in *emission (absorption: untouched).
inline real tf_eval(real d, __global const real* tf, int count, real4 scalars, real3* emission) {
  int segment = 0;
  real r, g, b;
  const real sigma = tf_sample(d, tf, count, scalars, &segment, &r, &g, &b);
#if IVR_EMISSION
  *emission = (real3)(r, g, b);
#endif
  return sigma;
}
#endif

// --- The TF as linear pieces in density (identity, piecewise-linear and table TFs) ---------------
// `exact` and `preintegrated` integrate through the TF exactly, so they cut the density range at
// the TF's knots (control points, table entries): between consecutive knots σ and the colour are
// linear in density. Interval j ∈ [-1, K - 1] holds the densities [knot_j, knot_j+1) (-1: below
// the first knot, K - 1: at or above the last, where the TF is constant). The identity TF (σ = a·d,
// colour = b·d) is one linear piece: K = 0, interval -1.

inline int tf_knots(int count) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  return count;
#else
  return 0;
#endif
}

inline real tf_knot(int k, __global const real* tf, int count, real4 scalars) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  return tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR];
#elif IVR_TF == IVR_TF_TABLE
  return count > 1 ? scalars.x + (scalars.y - scalars.x) * (real)k / (real)(count - 1) : scalars.x;
#else
  return (real)0;
#endif
}

// The interval holding density x (knot_j <= x < knot_j+1). *cursor: as tf_sample's search cursor.
inline int tf_interval(real x, __global const real* tf, int count, real4 scalars, int* cursor) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  if (x < tf[0]) return -1;
  if (x >= tf[(count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR]) return count - 1;
  int k = max(*cursor, 0);
  while (k > 0 && tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR] > x) --k;
  while (tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR] <= x) ++k;
  *cursor = k;
  return k;
#elif IVR_TF == IVR_TF_TABLE
  if (x < scalars.x) return -1;
  if (x >= scalars.y || count < 2) return count - 1;
  const int j = (int)((x - scalars.x) / (scalars.y - scalars.x) * (real)(count - 1));
  // Rounding may put x a knot off; the knots themselves decide.
  int k = clamp(j, 0, count - 2);
  if (tf_knot(k, tf, count, scalars) > x)
    --k;
  else if (tf_knot(k + 1, tf, count, scalars) <= x)
    ++k;
  return clamp(k, -1, count - 1);
#else
  (void)x, (void)tf, (void)count, (void)scalars, (void)cursor;
  return -1;
#endif
}

// The linear piece of interval j: σ(x) = s0 + s1·(x − x0), colour(x) = c0 + c1·(x − x0) (not
// premultiplied), and the TF rows it blends, with the weight of row1 w(x) = (x − x0)·inv_width.
typedef struct {
  int row0, row1;  // equal: a constant piece; -1: the identity TF
  real x0, inv_width;
  real s0, s1;
  real c0r, c0g, c0b, c1r, c1g, c1b;
} TfPiece;

inline TfPiece tf_piece(int j, __global const real* tf, int count, real4 scalars) {
  TfPiece p;
  p.x0 = (real)0;
  p.inv_width = (real)0;
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  p.row0 = max(j, 0);
  p.row1 = j < 0 ? 0 : min(j + 1, count - 1);
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  __global const real* a = tf + p.row0 * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;  // r, g, b, sigma
  __global const real* b = tf + p.row1 * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;
#else
  __global const real* a = tf + p.row0 * IVR_TF_STRIDE_TABLE;
  __global const real* b = tf + p.row1 * IVR_TF_STRIDE_TABLE;
#endif
  p.x0 = tf_knot(p.row0, tf, count, scalars);
  const real width = tf_knot(p.row1, tf, count, scalars) - p.x0;
  if (p.row0 != p.row1 && width > (real)0) p.inv_width = (real)1 / width;
  p.s0 = a[3];
  p.s1 = (b[3] - a[3]) * p.inv_width;
  p.c0r = a[0], p.c0g = a[1], p.c0b = a[2];
  p.c1r = (b[0] - a[0]) * p.inv_width;
  p.c1g = (b[1] - a[1]) * p.inv_width;
  p.c1b = (b[2] - a[2]) * p.inv_width;
#else
  // identity: σ = a·x, colour = b·x (grey)
  (void)j, (void)tf, (void)count;
  p.row0 = p.row1 = -1;
  p.s0 = (real)0;
  p.s1 = scalars.x;
  p.c0r = p.c0g = p.c0b = (real)0;
  p.c1r = p.c1g = p.c1b = scalars.y;
#endif
  return p;
}

inline real tf_piece_sigma(const TfPiece* p, real x) {
  return p->s0 + p->s1 * (x - p->x0);
}

inline void tf_piece_color(const TfPiece* p, real x, real* r, real* g, real* b) {
  const real dx = x - p->x0;
  *r = p->c0r + p->c1r * dx;
  *g = p->c0g + p->c1g * dx;
  *b = p->c0b + p->c1b * dx;
}

// The first knot strictly above x (direction > 0) or strictly below it (< 0), given the interval
// j of x; false when there is none.
inline bool tf_next_knot(real x, int j, int direction, __global const real* tf, int count,
                         real4 scalars, real* knot) {
  const int knots = tf_knots(count);
  if (direction > 0) {
    for (int k = j + 1; k < knots; ++k) {
      *knot = tf_knot(k, tf, count, scalars);
      if (*knot > x) return true;
    }
  } else {
    for (int k = min(j, knots - 1); k >= 0; --k) {
      *knot = tf_knot(k, tf, count, scalars);
      if (*knot < x) return true;
    }
  }
  return false;
}

#endif
