// adjoint_tf.cl — derivatives of the transfer functions: with respect to density (for the voxel
// gradient) and to their own parameters (scattered into a work-group's local accumulator).
// At a control point or table entry the derivative is one-sided: the segment [d_k, d_k+1) that
// holds the density is used, as tf_sample() does.
#ifndef IVR_TF_GRAD_CL
#define IVR_TF_GRAD_CL
#include "atomics.cl"
#include "compositing.cl"
#include "tf.cl"

// Columns of the TF gradient (lib/adjoint/adjoint.cpp's tf_gradient_shape must agree).
#if IVR_TF == IVR_TF_IDENTITY
#define IVR_TF_GRAD_COLUMNS 2
#elif IVR_TF == IVR_TF_GAUSSIAN
#define IVR_TF_GRAD_COLUMNS 6
#else
#define IVR_TF_GRAD_COLUMNS 4
#endif

// Row `row`'s [r, g, b, sigma] (piecewise linear: after its density; table: the whole row).
inline __global const real* tf_rgbs(__global const real* tf, int row) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  return tf + row * IVR_TF_STRIDE_PIECEWISE_LINEAR + 1;
#else
  return tf + row * IVR_TF_STRIDE_TABLE;
#endif
}

#if IVR_RAYS == 1
// The one or two rows holding density d, their weights, and the slope of the weights in d.
typedef struct {
  int row0, row1;
  real w1;      // weight of row1; row0 has 1 - w1
  real dw1_dd;  // d w1 / d density (0 where the TF is constant)
} TfSegment;

inline TfSegment tf_segment(real d, __global const real* tf, int count, real4 scalars,
                            int* cursor) {
  TfSegment s;
  s.row0 = s.row1 = 0;
  s.w1 = (real)0;
  s.dw1_dd = (real)0;
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  if (d >= tf[(count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR]) {
    s.row0 = s.row1 = count - 1;
  } else if (d > tf[0]) {
    int k = *cursor;
    while (k > 0 && tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR] > d) --k;
    while (tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR] <= d) ++k;
    *cursor = k;
    const real da = tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR];
    const real db = tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR];
    s.row0 = k;
    s.row1 = k + 1;
    s.w1 = (d - da) / (db - da);
    s.dw1_dd = (real)1 / (db - da);
  }
#elif IVR_TF == IVR_TF_TABLE
  const real scale = (real)(count - 1) / (scalars.y - scalars.x);
  const real raw = (d - scalars.x) * scale;
  const real u = clamp(raw, (real)0, (real)(count - 1));
  s.row0 = min((int)u, count - 1);
  s.row1 = min(s.row0 + 1, count - 1);
  s.w1 = u - (real)s.row0;
  s.dw1_dd = (raw >= (real)0 && raw < (real)(count - 1)) ? scale : (real)0;
#endif
  return s;
}
#endif

// d sigma / d d and d emission / d d at density d, for the TF kinds that are not linear pieces
// (identity, Gaussians); tf_sample_slope() takes the others.
__attribute__((always_inline)) inline vreal tf_slope(vreal d, __global const real* tf, int count,
                                                     real4 scalars, vreal* der, vreal* deg,
                                                     vreal* deb) {
  *der = *deg = *deb = (vreal)(real)0;
#if IVR_TF == IVR_TF_IDENTITY
  (void)tf, (void)count;
#if IVR_EMISSION
  *der = *deg = *deb = (real)2 * scalars.x * scalars.y * d;  // E = a·b·d²
#endif
  return (vreal)scalars.x;
#elif IVR_TF == IVR_TF_GAUSSIAN
  (void)scalars;
  vreal slope = (vreal)(real)0;
  for (int k = 0; k < count; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_GAUSSIAN;
    const vreal z = (d - p[0]) / p[1];
    const vreal ds = -p[5] * vexp((real)-0.5 * z * z) * z / p[1];
    slope += ds;
#if IVR_EMISSION
    *der += ds * p[2];
    *deg += ds * p[3];
    *deb += ds * p[4];
#endif
  }
  return slope;
#else
  (void)d, (void)tf, (void)count, (void)scalars;
  return (vreal)(real)0;  // not called: tf_sample_slope() differentiates linear pieces itself
#endif
}

// Where a density lies in the TF, as forward mode's TF partials need it (jacobian_tf.cl): the one
// or two rows blended there (row0 = row1 beyond the ends) with row1's weight w1, and the colour
// (not premultiplied). Filled by tf_sample_slope() for piecewise-linear and table TFs.
typedef struct {
  vint row0, row1;
  vreal w1;
  vreal cr, cg, cb;
} TfPoint;

// tf_sample() and tf_slope() in one: sigma and the premultiplied emission, computed exactly as
// tf_sample() computes them (so that the adjoint march recovers what the primal march rendered),
// with their density derivatives in *dsigma and (*der, *deg, *deb), from one segment search; and
// where d lies in the TF in *point. One ray or every ray of a packet (kernels/rays.cl).
__attribute__((always_inline)) inline vreal tf_sample_slope(vreal d, __global const real* tf,
                                                            int count, real4 scalars, vint* cursor,
                                                            vreal* er, vreal* eg, vreal* eb,
                                                            vreal* dsigma, vreal* der, vreal* deg,
                                                            vreal* deb, TfPoint* point) {
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  // The rows around d, as tf_sample() finds them.
  const TfRows t = tf_rows(d, tf, count, scalars, cursor);
  const vreal sigma = vlerp(t.a3, t.b3, t.w);
  *dsigma = (t.b3 - t.a3) * t.dw;
  const vreal cr = vlerp(t.a0, t.b0, t.w), cg = vlerp(t.a1, t.b1, t.w), cb = vlerp(t.a2, t.b2, t.w);
#if IVR_EMISSION
  *er = sigma * cr;
  *eg = sigma * cg;
  *eb = sigma * cb;
  // E = sigma·c: E' = sigma'·c + sigma·c'
  *der = *dsigma * cr + sigma * (t.b0 - t.a0) * t.dw;
  *deg = *dsigma * cg + sigma * (t.b1 - t.a1) * t.dw;
  *deb = *dsigma * cb + sigma * (t.b2 - t.a2) * t.dw;
#else
  *der = *deg = *deb = (vreal)(real)0;
#endif
  point->row0 = t.row0, point->row1 = t.row1, point->w1 = t.w;
  point->cr = cr, point->cg = cg, point->cb = cb;
  return sigma;
#else
  const vreal sigma = tf_sample(d, tf, count, scalars, cursor, er, eg, eb);
  *dsigma = tf_slope(d, tf, count, scalars, der, deg, deb);
  point->row0 = point->row1 = (vint)0;
  point->w1 = point->cr = point->cg = point->cb = (vreal)(real)0;
  return sigma;
#endif
}

// A ray's private TF-gradient accumulator: the rows its samples currently touch, each value summed
// with compensation (accumulate), flushed into the work-group's local accumulator when the rows
// change and when the ray ends. A ray of 1e5 samples in one TF segment would otherwise add 1e5
// float32 terms into one value and lose float32 accuracy.
#if IVR_TF == IVR_TF_GAUSSIAN
#if defined(IVR_TF_ROWS) && IVR_TF_ROWS <= 8
#define IVR_TF_CACHE_ROWS IVR_TF_ROWS  // every Gaussian, every sample
#else
#define IVR_TF_CACHE_ROWS 0  // many Gaussians: straight to local memory
#endif
#elif IVR_TF == IVR_TF_IDENTITY
#define IVR_TF_CACHE_ROWS 1
#else
#define IVR_TF_CACHE_ROWS 2   // the segment's two rows
#define IVR_TF_CACHE_KEYED 1  // slots re-keyed as the segment changes
#endif
#ifndef IVR_TF_CACHE_KEYED
#define IVR_TF_CACHE_KEYED 0  // slot k holds row k
#endif

#define IVR_TF_CACHE_SIZE (IVR_TF_CACHE_ROWS > 0 ? IVR_TF_CACHE_ROWS * IVR_TF_GRAD_COLUMNS : 1)

#if IVR_RAYS == 1  // one ray per work-item
typedef struct {
  int row[IVR_TF_CACHE_ROWS > 0 ? IVR_TF_CACHE_ROWS : 1];  // -1: slot unused
  real value[IVR_TF_CACHE_SIZE], error[IVR_TF_CACHE_SIZE];
} TfGradCache;

inline void tf_cache_init(TfGradCache* c) {
  for (int k = 0; k < (IVR_TF_CACHE_ROWS > 0 ? IVR_TF_CACHE_ROWS : 1); ++k)
    c->row[k] = IVR_TF_CACHE_KEYED ? -1 : k;
  for (int i = 0; i < IVR_TF_CACHE_SIZE; ++i) c->value[i] = c->error[i] = (real)0;
}

inline void tf_cache_flush(TfGradCache* c, volatile __local real* acc) {
  for (int k = 0; k < IVR_TF_CACHE_ROWS; ++k) {
    if (c->row[k] < 0) continue;
    for (int j = 0; j < IVR_TF_GRAD_COLUMNS; ++j) {
      const int i = k * IVR_TF_GRAD_COLUMNS + j;
      if (c->value[i] != (real)0)
        atomic_add_local(acc + c->row[k] * IVR_TF_GRAD_COLUMNS + j, c->value[i]);
      c->value[i] = c->error[i] = (real)0;
    }
  }
}

// Adds v to column j of cache slot k.
inline void tf_cache_add(TfGradCache* c, int k, int j, real v) {
  accumulate(&c->value[k * IVR_TF_GRAD_COLUMNS + j], &c->error[k * IVR_TF_GRAD_COLUMNS + j], v);
}

// Adds the parameter gradient of one sample, given gs = dL/dsigma and (gr, gg, gb) = dL/dE,
// into the ray's cache (flushing into acc, rows x IVR_TF_GRAD_COLUMNS in local memory).
inline void tf_scatter(real d, __global const real* tf, int count, real4 scalars, int* cursor,
                       real gs, real gr, real gg, real gb, TfGradCache* cache,
                       volatile __local real* acc) {
#if IVR_TF == IVR_TF_IDENTITY
  // sigma = a·d, E = a·b·d² (grey): dL/da = gs·d + (gr+gg+gb)·b·d², dL/db = (gr+gg+gb)·a·d².
  const real ge = gr + gg + gb;
  tf_cache_add(cache, 0, 0, gs * d + ge * scalars.y * d * d);
  tf_cache_add(cache, 0, 1, ge * scalars.x * d * d);
#elif IVR_TF == IVR_TF_GAUSSIAN
  for (int k = 0; k < count; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_GAUSSIAN;
    const real z = (d - p[0]) / p[1];
    const real g = vexp((real)-0.5 * z * z);  // the primal's exp (tf_sample)
    // sigma += e·G, E += e·G·c: d/de = G·(gs + gE·c), d/dc = e·G·gE, d/dmean = e·(gs + gE·c)·G·z/w,
    // d/dwidth = e·(gs + gE·c)·G·z²/w.
    const real through = gs + gr * p[2] + gg * p[3] + gb * p[4];
    const real v[6] = {p[5] * g * gr,
                       p[5] * g * gg,
                       p[5] * g * gb,
                       g * through,
                       p[5] * through * g * z / p[1],
                       p[5] * through * g * z * z / p[1]};
    for (int j = 0; j < 6; ++j) {
#if IVR_TF_CACHE_ROWS > 0
      tf_cache_add(cache, k, j, v[j]);
#else
      atomic_add_local(acc + k * IVR_TF_GRAD_COLUMNS + j, v[j]);
#endif
    }
  }
#else
  const TfSegment s = tf_segment(d, tf, count, scalars, cursor);
  if (s.row0 != cache->row[0] || s.row1 != cache->row[1]) {
    tf_cache_flush(cache, acc);
    cache->row[0] = s.row0;
    cache->row[1] = s.row1 == s.row0 ? -1 : s.row1;  // one row beyond the ends
  }
  __global const real* a = tf_rgbs(tf, s.row0);  // r, g, b, sigma
  __global const real* b = tf_rgbs(tf, s.row1);
  // sigma = lerp(s0, s1, w), c = lerp(c0, c1, w), E = sigma·c.
  const real sigma = lerp(a[3], b[3], s.w1);
  const real cr = lerp(a[0], b[0], s.w1), cg = lerp(a[1], b[1], s.w1), cb = lerp(a[2], b[2], s.w1);
  const real through = gs + gr * cr + gg * cg + gb * cb;  // dL/dsigma including E = sigma·c
  // Slot 0 holds row0 with weight 1 - w; slot 1 holds row1 with w (beyond the ends: row0, weight
  // 1).
  const real w[2] = {s.row1 == s.row0 ? (real)1 : (real)1 - s.w1, s.w1};
  for (int k = 0; k < (s.row1 == s.row0 ? 1 : 2); ++k) {
#if IVR_EMISSION
    tf_cache_add(cache, k, 0, w[k] * sigma * gr);
    tf_cache_add(cache, k, 1, w[k] * sigma * gg);
    tf_cache_add(cache, k, 2, w[k] * sigma * gb);
#endif
    tf_cache_add(cache, k, 3, w[k] * through);
  }
#endif
}

// The midpoint march's TF gradient of one sample: tf_scatter (`sigma`, `point`: the sample's, as
// tf_sample_slope() found them, which the packet form reads instead of searching again; `take`:
// one ray samples where it is called).
inline void tf_scatter_sample(vreal d, vreal sigma, const TfPoint* point, vint take,
                              __global const real* tf, int count, real4 scalars, vint* cursor,
                              vreal gs, vreal gr, vreal gg, vreal gb, TfGradCache* cache,
                              volatile __local real* acc) {
  (void)sigma, (void)point, (void)take;
  tf_scatter(d, tf, count, scalars, cursor, gs, gr, gg, gb, cache, acc);
}

// Adds a gradient taken through a TF piece (tf.cl, tf_piece) at density x — gs = dL/dσ(x) and
// (gr, gg, gb) = dL/d colour(x), the colour not premultiplied — into the rows the piece blends:
// the parameterisation of the integrators that integrate through the TF exactly.
inline void tf_scatter_piece(const TfPiece* p, real x, real gs, real gr, real gg, real gb,
                             TfGradCache* cache, volatile __local real* acc) {
#if IVR_TF == IVR_TF_IDENTITY
  (void)p, (void)acc;
  tf_cache_add(cache, 0, 0, gs * x);              // σ = a·x
  tf_cache_add(cache, 0, 1, (gr + gg + gb) * x);  // colour = b·x
#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  const int row1 = p->row1 == p->row0 ? -1 : p->row1;  // one row for a constant piece
  if (p->row0 != cache->row[0] || row1 != cache->row[1]) {
    tf_cache_flush(cache, acc);
    cache->row[0] = p->row0;
    cache->row[1] = row1;
  }
  const real w1 = (x - p->x0) * p->inv_width;  // 0 for a constant piece
  const real w[2] = {(real)1 - w1, w1};
  for (int k = 0; k < (row1 < 0 ? 1 : 2); ++k) {
#if IVR_EMISSION
    tf_cache_add(cache, k, 0, w[k] * gr);
    tf_cache_add(cache, k, 1, w[k] * gg);
    tf_cache_add(cache, k, 2, w[k] * gb);
#else
    (void)gr, (void)gg, (void)gb;
#endif
    tf_cache_add(cache, k, 3, w[k] * gs);
  }
#else
  (void)p, (void)x, (void)gs, (void)gr, (void)gg, (void)gb, (void)cache, (void)acc;
#endif
}

// tf_scatter_piece in the rays of `m` (one ray: wherever it is called).
inline void tf_scatter_piece_where(const TfPiece* p, real x, real gs, real gr, real gg, real gb,
                                   int m, TfGradCache* cache, volatile __local real* acc) {
  (void)m;
  tf_scatter_piece(p, x, gs, gr, gg, gb, cache, acc);
}

#else  // IVR_RAYS > 1: each lane of a packet its own cache, as its ray would have alone

typedef struct {
  vint row[IVR_TF_CACHE_ROWS > 0 ? IVR_TF_CACHE_ROWS : 1];  // -1: slot unused
  vreal value[IVR_TF_CACHE_SIZE], error[IVR_TF_CACHE_SIZE];
} TfGradCache;

inline void tf_cache_init(TfGradCache* c) {
  for (int k = 0; k < (IVR_TF_CACHE_ROWS > 0 ? IVR_TF_CACHE_ROWS : 1); ++k)
    c->row[k] = (vint)(IVR_TF_CACHE_KEYED ? -1 : k);
  for (int i = 0; i < IVR_TF_CACHE_SIZE; ++i) c->value[i] = c->error[i] = (vreal)(real)0;
}

// The lanes in `m`: their sums into the work-group's accumulator (lane by lane), and 0.
inline void tf_cache_flush_where(TfGradCache* c, volatile __local real* acc, vint m) {
  if (!vany(m)) return;
  int flag[IVR_RAYS];
  IVR_VSTORE(m, 0, flag);
  for (int k = 0; k < IVR_TF_CACHE_ROWS; ++k) {
    int row[IVR_RAYS];
    IVR_VSTORE(c->row[k], 0, row);
    for (int j = 0; j < IVR_TF_GRAD_COLUMNS; ++j) {
      const int i = k * IVR_TF_GRAD_COLUMNS + j;
      real v[IVR_RAYS];
      IVR_VSTORE(c->value[i], 0, v);
      for (int l = 0; l < IVR_RAYS; ++l)
        if (flag[l] && row[l] >= 0 && v[l] != (real)0)
          atomic_add_local(acc + row[l] * IVR_TF_GRAD_COLUMNS + j, v[l]);
      c->value[i] = vsel(c->value[i], (vreal)(real)0, m);
      c->error[i] = vsel(c->error[i], (vreal)(real)0, m);
    }
  }
}

inline void tf_cache_flush(TfGradCache* c, volatile __local real* acc) {
  tf_cache_flush_where(c, acc, vtrue);
}

// Adds v to column j of cache slot k in the lanes of `m`.
inline void tf_cache_add(TfGradCache* c, int k, int j, vreal v, vint m) {
  accumulate_where(&c->value[k * IVR_TF_GRAD_COLUMNS + j], &c->error[k * IVR_TF_GRAD_COLUMNS + j], v,
                   m);
}

// tf_scatter() in every lane of `take`, the rows and weights from `point` (tf_sample_slope()'s).
inline void tf_scatter_sample(vreal d, vreal sigma, const TfPoint* point, vint take,
                              __global const real* tf, int count, real4 scalars, vint* cursor,
                              vreal gs, vreal gr, vreal gg, vreal gb, TfGradCache* cache,
                              volatile __local real* acc) {
  (void)cursor;
#if IVR_TF == IVR_TF_IDENTITY
  (void)sigma, (void)point, (void)tf, (void)count, (void)acc;
  const vreal ge = gr + gg + gb;
  tf_cache_add(cache, 0, 0, gs * d + ge * scalars.y * d * d, take);
  tf_cache_add(cache, 0, 1, ge * scalars.x * d * d, take);
#elif IVR_TF == IVR_TF_GAUSSIAN
  (void)sigma, (void)point, (void)scalars;
  for (int k = 0; k < count; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_GAUSSIAN;
    const vreal z = (d - p[0]) / p[1];
    const vreal g = vexp((real)-0.5 * z * z);
    const vreal through = gs + gr * p[2] + gg * p[3] + gb * p[4];
    const vreal v[6] = {p[5] * g * gr,
                        p[5] * g * gg,
                        p[5] * g * gb,
                        g * through,
                        p[5] * through * g * z / p[1],
                        p[5] * through * g * z * z / p[1]};
    for (int j = 0; j < 6; ++j) {
#if IVR_TF_CACHE_ROWS > 0
      tf_cache_add(cache, k, j, v[j], take);
#else
      real lane[IVR_RAYS];
      int flag[IVR_RAYS];
      IVR_VSTORE(v[j], 0, lane);
      IVR_VSTORE(take, 0, flag);
      for (int l = 0; l < IVR_RAYS; ++l)
        if (flag[l]) atomic_add_local(acc + k * IVR_TF_GRAD_COLUMNS + j, lane[l]);
#endif
    }
  }
#else
  (void)d, (void)tf, (void)count, (void)scalars;
  const vint one = point->row1 == point->row0;  // beyond the ends: one row, weight 1
  const vint row1 = vseli(point->row1, (vint)-1, one);
  const vint change = take && (point->row0 != cache->row[0] || row1 != cache->row[1]);
  if (vany(change)) {
    tf_cache_flush_where(cache, acc, change);
    cache->row[0] = vseli(cache->row[0], point->row0, change);
    cache->row[1] = vseli(cache->row[1], row1, change);
  }
  // sigma = lerp(s0, s1, w), c = lerp(c0, c1, w), E = sigma·c; slot 1 adds 0 where one row.
  const vreal through = gs + gr * point->cr + gg * point->cg + gb * point->cb;
  const vreal w[2] = {vsel((real)1 - point->w1, (vreal)(real)1, one),
                      vsel(point->w1, (vreal)(real)0, one)};
  for (int k = 0; k < 2; ++k) {
#if IVR_EMISSION
    tf_cache_add(cache, k, 0, w[k] * sigma * gr, take);
    tf_cache_add(cache, k, 1, w[k] * sigma * gg, take);
    tf_cache_add(cache, k, 2, w[k] * sigma * gb, take);
#else
    (void)sigma;
#endif
    tf_cache_add(cache, k, 3, w[k] * through, take);
  }
#endif
}

// A gradient taken through a TF piece at density x (tf_scatter_piece) in the rays of `m`.
inline void tf_scatter_piece_where(const TfPiece* p, vreal x, vreal gs, vreal gr, vreal gg,
                                   vreal gb, vint m, TfGradCache* cache,
                                   volatile __local real* acc) {
#if IVR_TF == IVR_TF_IDENTITY
  (void)p, (void)acc;
  tf_cache_add(cache, 0, 0, gs * x, m);              // σ = a·x
  tf_cache_add(cache, 0, 1, (gr + gg + gb) * x, m);  // colour = b·x
#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  const vint one = p->row1 == p->row0;  // one row for a constant piece
  const vint row1 = vseli(p->row1, (vint)-1, one);
  const vint change = m && (p->row0 != cache->row[0] || row1 != cache->row[1]);
  if (vany(change)) {
    tf_cache_flush_where(cache, acc, change);
    cache->row[0] = vseli(cache->row[0], p->row0, change);
    cache->row[1] = vseli(cache->row[1], row1, change);
  }
  const vreal w1 = vsel((x - p->x0) * p->inv_width, (vreal)(real)0, one);
  const vreal w[2] = {(real)1 - w1, w1};
  for (int k = 0; k < 2; ++k) {
#if IVR_EMISSION
    tf_cache_add(cache, k, 0, w[k] * gr, m);
    tf_cache_add(cache, k, 1, w[k] * gg, m);
    tf_cache_add(cache, k, 2, w[k] * gb, m);
#else
    (void)gr, (void)gg, (void)gb;
#endif
    tf_cache_add(cache, k, 3, w[k] * gs, m);
  }
#else
  (void)p, (void)x, (void)gs, (void)gr, (void)gg, (void)gb, (void)m, (void)cache, (void)acc;
#endif
}
#endif  // IVR_RAYS

#endif
