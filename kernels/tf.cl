// tf.cl — the transfer functions of docs/design.md: extinction sigma(d) and, for
// emission–absorption, the premultiplied emission sigma(d)·colour(d). Only the scene's TF kind is
// compiled.
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

#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
// The one or two TF rows a density d blends, for one ray or every ray of a packet
// (kernels/rays.cl): their [r, g, b, sigma] (row0's in a*, row1's in b*), row1's weight w and its
// slope dw in d, and the rows' indices (row0 = row1, w = dw = 0, beyond the ends).
// Piecewise linear: the segment [d_k, d_k+1) holding d. *cursor is the one-ray search's start: a
// marching loop starts it at 0 and passes it from one sample to the next; densities along a ray
// are continuous, so the search mostly stays put or moves one segment instead of scanning from
// the first point. The segment found is the same from any start. A packet, whose rays would each
// move their own cursor through gathers, blends every segment in by masks instead (the rows are
// the same for every ray: broadcasts, not gathers). Table: R entries at evenly spaced densities
// lo..hi, linear in between, constant beyond.
// Points up to which a packet blends every segment (tf_rows).
#define IVR_TF_BLEND_ALL 8

typedef struct {
  vreal a0, a1, a2, a3, b0, b1, b2, b3;
  vreal w, dw;
  vint row0, row1;
} TfRows;

__attribute__((always_inline)) inline TfRows tf_rows(vreal d, __global const real* tf, int count,
                                                     real4 scalars, vint* cursor) {
  TfRows t;
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  (void)scalars;
  const int last = count - 1;
#if IVR_RAYS == 1
  int k0 = 0, k1 = 0;
  t.w = (real)0, t.dw = (real)0;
  if (d >= tf[last * IVR_TF_STRIDE_PIECEWISE_LINEAR]) {
    k0 = k1 = last;
  } else if (d > tf[0]) {  // so count >= 2, and the k with d_k <= d < d_k+1 exists
    int k = *cursor;
    while (k > 0 && tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR] > d) --k;
    while (tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR] <= d) ++k;
    *cursor = k;
    k0 = k, k1 = k + 1;
    const real width =
        tf[k1 * IVR_TF_STRIDE_PIECEWISE_LINEAR] - tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR];
    t.w = (d - tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR]) / width;  // never a zero width
    t.dw = (real)1 / width;
  }
  __global const real* a = tf + k0 * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;  // r, g, b, sigma
  __global const real* b = tf + k1 * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;
  t.a0 = a[0], t.a1 = a[1], t.a2 = a[2], t.a3 = a[3], t.b0 = b[0], t.b1 = b[1], t.b2 = b[2];
  t.b3 = b[3];
  t.row0 = k0, t.row1 = k1;
#else
  (void)cursor;
#if IVR_PERMUTE_ENTRIES
  if (count <= IVR_PERMUTE_ENTRIES) {
    // Each lane's row k by counting the points at or below d (the one ray's search finds the
    // same: the last point at or below d), then every column's value of rows k and k + 1 by one
    // permute of the column (ivr_constants.h: the columns follow the rows).
    __global const real* column = tf + count * IVR_TF_STRIDE_PIECEWISE_LINEAR;
    vint k = (vint)0;
    for (int j = 1; j < count; ++j)
      k -= vmask_of(d >= (vreal)tf[j * IVR_TF_STRIDE_PIECEWISE_LINEAR]);  // masks are −1
    const vint beyond = vmask_of(d >= (vreal)tf[last * IVR_TF_STRIDE_PIECEWISE_LINEAR]);
    const vint inside = !beyond && vmask_of(d > (vreal)tf[0]);
    t.row0 = vseli(vseli((vint)0, k, inside), (vint)last, beyond);
    t.row1 = vseli(t.row0, k + 1, inside);
#define IVR_COLUMN(c) IVR_VLOAD(0, column + (c)*IVR_TF_COLUMN_ENTRIES)
    const vreal start = vpermute(IVR_COLUMN(0), t.row0), end = vpermute(IVR_COLUMN(0), t.row1);
    t.a0 = vpermute(IVR_COLUMN(1), t.row0), t.b0 = vpermute(IVR_COLUMN(1), t.row1);
    t.a1 = vpermute(IVR_COLUMN(2), t.row0), t.b1 = vpermute(IVR_COLUMN(2), t.row1);
    t.a2 = vpermute(IVR_COLUMN(3), t.row0), t.b2 = vpermute(IVR_COLUMN(3), t.row1);
    t.a3 = vpermute(IVR_COLUMN(4), t.row0), t.b3 = vpermute(IVR_COLUMN(4), t.row1);
#undef IVR_COLUMN
    const vreal width = vsel((vreal)(real)1, end - start, inside);
    t.w = vsel((vreal)(real)0, (d - start) / width, inside);
    t.dw = vsel((vreal)(real)0, (real)1 / width, inside);
    return t;
  }
#endif
  t.a0 = t.b0 = (vreal)tf[1], t.a1 = t.b1 = (vreal)tf[2], t.a2 = t.b2 = (vreal)tf[3];
  t.a3 = t.b3 = (vreal)tf[4];
  t.row0 = t.row1 = (vint)0;
  // Each lane's segment start and width, its weight computed once after the loop (one division
  // a sample, not one a segment); the same operands as one ray's, so the same bits.
  vreal start = (vreal)(real)0, width = (vreal)(real)1;
  vint inside = (vint)0;
  for (int k = 0; k < last; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_PIECEWISE_LINEAR;
    __global const real* q = p + IVR_TF_STRIDE_PIECEWISE_LINEAR;
    const vint in = vmask_of(d >= p[0]) && vmask_of(d < q[0]) && vmask_of(d > tf[0]);
    // A few segments are blended whole, without a branch (whether any lane is in one changes
    // from sample to sample, and a mispredicted branch costs more than the blend); many are
    // skipped where no lane is in them.
    if (count > IVR_TF_BLEND_ALL && !vany(in)) continue;
    inside = inside || in;
    start = vsel(start, (vreal)p[0], in);
    width = vsel(width, (vreal)(q[0] - p[0]), in);
    t.a0 = vsel(t.a0, (vreal)p[1], in), t.a1 = vsel(t.a1, (vreal)p[2], in);
    t.a2 = vsel(t.a2, (vreal)p[3], in), t.a3 = vsel(t.a3, (vreal)p[4], in);
    t.b0 = vsel(t.b0, (vreal)q[1], in), t.b1 = vsel(t.b1, (vreal)q[2], in);
    t.b2 = vsel(t.b2, (vreal)q[3], in), t.b3 = vsel(t.b3, (vreal)q[4], in);
    t.row0 = vseli(t.row0, (vint)k, in), t.row1 = vseli(t.row1, (vint)(k + 1), in);
  }
  t.w = vsel((vreal)(real)0, (d - start) / width, inside);
  t.dw = vsel((vreal)(real)0, (real)1 / width, inside);
  __global const real* z = tf + last * IVR_TF_STRIDE_PIECEWISE_LINEAR;
  const vint beyond = vmask_of(d >= z[0]);
  t.a0 = vsel(t.a0, (vreal)z[1], beyond), t.a1 = vsel(t.a1, (vreal)z[2], beyond);
  t.a2 = vsel(t.a2, (vreal)z[3], beyond), t.a3 = vsel(t.a3, (vreal)z[4], beyond);
  t.b0 = vsel(t.b0, (vreal)z[1], beyond), t.b1 = vsel(t.b1, (vreal)z[2], beyond);
  t.b2 = vsel(t.b2, (vreal)z[3], beyond), t.b3 = vsel(t.b3, (vreal)z[4], beyond);
  t.row0 = vseli(t.row0, (vint)last, beyond), t.row1 = vseli(t.row1, (vint)last, beyond);
#endif
#else
  (void)cursor;
  const vreal q = (d - scalars.x) / (scalars.y - scalars.x);
  const vreal u = clamp(q, (real)0, (real)1) * (real)(count - 1);
  t.row0 = min(vto_int(u), count - 1);
  t.row1 = min(t.row0 + 1, count - 1);
  t.w = u - vto_real(t.row0);
  t.dw = vsel((vreal)(real)0, (vreal)((real)(count - 1) / (scalars.y - scalars.x)),
              vmask_of(q >= (real)0) && vmask_of(q < (real)1));
#if IVR_PERMUTE_ENTRIES
  if (count <= IVR_PERMUTE_ENTRIES) {  // the columns after the rows (ivr_constants.h)
    __global const real* column = tf + count * IVR_TF_STRIDE_TABLE;
#define IVR_COLUMN(c) IVR_VLOAD(0, column + (c)*IVR_TF_COLUMN_ENTRIES)
    t.a0 = vpermute(IVR_COLUMN(0), t.row0), t.b0 = vpermute(IVR_COLUMN(0), t.row1);
    t.a1 = vpermute(IVR_COLUMN(1), t.row0), t.b1 = vpermute(IVR_COLUMN(1), t.row1);
    t.a2 = vpermute(IVR_COLUMN(2), t.row0), t.b2 = vpermute(IVR_COLUMN(2), t.row1);
    t.a3 = vpermute(IVR_COLUMN(3), t.row0), t.b3 = vpermute(IVR_COLUMN(3), t.row1);
#undef IVR_COLUMN
    return t;
  }
#endif
  const vint ia = t.row0 * IVR_TF_STRIDE_TABLE, ib = t.row1 * IVR_TF_STRIDE_TABLE;
  t.a0 = vgather(tf, ia), t.a1 = vgather(tf, ia + 1), t.a2 = vgather(tf, ia + 2);
  t.a3 = vgather(tf, ia + 3);
  t.b0 = vgather(tf, ib), t.b1 = vgather(tf, ib + 1), t.b2 = vgather(tf, ib + 2);
  t.b3 = vgather(tf, ib + 3);
#endif
  return t;
}
#endif

// sigma(d), and with IVR_EMISSION the premultiplied emission in (*er, *eg, *eb), for one ray or
// every ray of a packet (kernels/rays.cl). Scalars rather than real3 because PoCL compiles real3
// into padded 4-wide vectors with lane shuffles around them. *segment: tf_rows()'s search cursor
// (piecewise linear); other kinds ignore it.
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

#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  // Constant beyond the ends (lerp(a, a, 0) = a); in between, linear between the two rows.
  const TfRows t = tf_rows(d, tf, count, scalars, segment);
  const vreal sigma = vlerp(t.a3, t.b3, t.w);
#if IVR_EMISSION
  *er = sigma * vlerp(t.a0, t.b0, t.w);
  *eg = sigma * vlerp(t.a1, t.b1, t.w);
  *eb = sigma * vlerp(t.a2, t.b2, t.w);
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
// colour = b·d) is one linear piece: K = 0, interval -1. Every function below takes one ray's
// values or a packet's (kernels/rays.cl); a packet's rays search each on its own (masked loops
// that run as often as the ray that needs most steps), so each lane finds what one ray finds.

inline int tf_knots(int count) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  return count;
#else
  return 0;
#endif
}

// Knot k (0 <= k < tf_knots(count)).
inline vreal tf_knot(vint k, __global const real* tf, int count, real4 scalars) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  (void)count, (void)scalars;
  return vgather(tf, k * IVR_TF_STRIDE_PIECEWISE_LINEAR);
#elif IVR_TF == IVR_TF_TABLE
  (void)tf;
  if (count < 2) return (vreal)scalars.x;
  return scalars.x + (scalars.y - scalars.x) * vto_real(k) / (real)(count - 1);
#else
  (void)k, (void)tf, (void)count, (void)scalars;
  return (vreal)(real)0;
#endif
}

// The interval holding density x (knot_j <= x < knot_j+1). *cursor: as tf_rows' search cursor.
inline vint tf_interval(vreal x, __global const real* tf, int count, real4 scalars, vint* cursor) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  (void)scalars;
  const int last = count - 1;
  const vint below = vmask_of(x < tf[0]);
  const vint above = vmask_of(x >= tf[last * IVR_TF_STRIDE_PIECEWISE_LINEAR]);
  const vint inside = !below && !above;  // so count >= 2, and the k with d_k <= x < d_k+1 exists
  vint k = max(*cursor, 0), step;
  if (vany(inside)) {
    while (vany(step = inside && k > 0 && vmask_of(tf_knot(k, tf, count, scalars) > x)))
      k -= vcount(step);
    while (vany(step = inside && vmask_of(tf_knot(min(k + 1, last), tf, count, scalars) <= x)))
      k += vcount(step);
    *cursor = vseli(*cursor, k, inside);
  }
  return vseli(vseli(k, (vint)last, above), (vint)-1, below);
#elif IVR_TF == IVR_TF_TABLE
  (void)cursor;
  const vint below = vmask_of(x < scalars.x);
  const vint above = vmask_of(x >= scalars.y) || count < 2;
  // The entry below x, clamped before the conversion (lanes outside the range are chosen away).
  const vreal u = (x - scalars.x) / (scalars.y - scalars.x) * (real)(count - 1);
  vint k = vto_int(fmin(fmax(u, (real)0), (real)max(count - 2, 0)));
  // Rounding may put x a knot off; the knots themselves decide.
  const vint down = vmask_of(tf_knot(k, tf, count, scalars) > x);
  const vint up = !down && vmask_of(tf_knot(min(k + 1, count - 1), tf, count, scalars) <= x);
  k = clamp(k - vcount(down) + vcount(up), -1, count - 1);
  return vseli(vseli(k, (vint)(count - 1), above), (vint)-1, below);
#else
  (void)x, (void)tf, (void)count, (void)scalars, (void)cursor;
  return (vint)-1;
#endif
}

// The linear piece of interval j: σ(x) = s0 + s1·(x − x0), colour(x) = c0 + c1·(x − x0) (not
// premultiplied), and the TF rows it blends, with the weight of row1 w(x) = (x − x0)·inv_width.
typedef struct {
  vint row0, row1;  // equal: a constant piece; -1: the identity TF
  vreal x0, inv_width;
  vreal s0, s1;
  vreal c0r, c0g, c0b, c1r, c1g, c1b;
} TfPiece;

inline TfPiece tf_piece(vint j, __global const real* tf, int count, real4 scalars) {
  TfPiece p;
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  p.row0 = max(j, 0);
  p.row1 = vseli(min(j + 1, count - 1), (vint)0, j < 0);
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  const vint ia = p.row0 * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;  // r, g, b, sigma
  const vint ib = p.row1 * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;
#else
  const vint ia = p.row0 * IVR_TF_STRIDE_TABLE, ib = p.row1 * IVR_TF_STRIDE_TABLE;
#endif
  p.x0 = tf_knot(p.row0, tf, count, scalars);
  const vreal width = tf_knot(p.row1, tf, count, scalars) - p.x0;
  p.inv_width =
      vsel((vreal)(real)0, (real)1 / width, p.row0 != p.row1 && vmask_of(width > (real)0));
  const vreal a0 = vgather(tf, ia), a1 = vgather(tf, ia + 1), a2 = vgather(tf, ia + 2),
              a3 = vgather(tf, ia + 3);
  const vreal b0 = vgather(tf, ib), b1 = vgather(tf, ib + 1), b2 = vgather(tf, ib + 2),
              b3 = vgather(tf, ib + 3);
  p.s0 = a3;
  p.s1 = (b3 - a3) * p.inv_width;
  p.c0r = a0, p.c0g = a1, p.c0b = a2;
  p.c1r = (b0 - a0) * p.inv_width;
  p.c1g = (b1 - a1) * p.inv_width;
  p.c1b = (b2 - a2) * p.inv_width;
#else
  // identity: σ = a·x, colour = b·x (grey)
  (void)j, (void)tf, (void)count;
  p.row0 = p.row1 = (vint)-1;
  p.x0 = p.inv_width = p.s0 = (vreal)(real)0;
  p.s1 = (vreal)scalars.x;
  p.c0r = p.c0g = p.c0b = (vreal)(real)0;
  p.c1r = p.c1g = p.c1b = (vreal)scalars.y;
#endif
  return p;
}

inline vreal tf_piece_sigma(const TfPiece* p, vreal x) {
  return p->s0 + p->s1 * (x - p->x0);
}

inline void tf_piece_color(const TfPiece* p, vreal x, vreal* r, vreal* g, vreal* b) {
  const vreal dx = x - p->x0;
  *r = p->c0r + p->c1r * dx;
  *g = p->c0g + p->c1g * dx;
  *b = p->c0b + p->c1b * dx;
}

// The first knot strictly above x (direction > 0) or strictly below it (< 0), given the interval
// j of x, in *knot; the rays that have one (direction 0: none).
inline vint tf_next_knot(vreal x, vint j, vint direction, __global const real* tf, int count,
                         real4 scalars, vreal* knot) {
  const int knots = tf_knots(count);
  const vint rising = direction > 0;
  vint k = vseli(min(j, knots - 1), j + 1, rising);
  vint found = (vint)0;
  vint search = direction != 0 && k >= 0 && k < knots;
  while (vany(search)) {
    const vreal v = tf_knot(clamp(k, 0, knots - 1), tf, count, scalars);
    const vint hit = search && vseli(vmask_of(v < x), vmask_of(v > x), rising);
    *knot = vsel(*knot, v, hit);
    found = found || hit;
    k += vseli((vint)-1, (vint)1, rising);
    search = search && !hit && k >= 0 && k < knots;
  }
  return found;
}

#endif
