// jacobian_tf.cl — partial derivatives of the transfer function with respect to one of its own
// parameters (row, column of the TF gradient layout; column 4 of a piecewise-linear TF is the
// control point's density), at density d, for forward mode. One-sided at control points and
// table entries like tf_sample(): the segment [d_k, d_k+1) holding d is used.
#ifndef IVR_TF_TANGENT_CL
#define IVR_TF_TANGENT_CL
#include "adjoint_tf.cl"

// The per-sample part shared by every lane: the segment holding d (piecewise linear, table), and
// the colour there.
typedef struct {
  TfSegment s;
  real cr, cg, cb;  // colour(d) (not premultiplied)
} TfPoint;

inline TfPoint tf_point(real d, __global const real* tf, int count, real4 scalars, int* cursor) {
  TfPoint p;
  p.s = tf_segment(d, tf, count, scalars, cursor);
  p.cr = p.cg = p.cb = (real)0;
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  __global const real* a = tf_rgbs(tf, p.s.row0);  // r, g, b, sigma
  __global const real* b = tf_rgbs(tf, p.s.row1);
  p.cr = lerp(a[0], b[0], p.s.w1);
  p.cg = lerp(a[1], b[1], p.s.w1);
  p.cb = lerp(a[2], b[2], p.s.w1);
#endif
  return p;
}

// d sigma / d theta, and the premultiplied emission's in (*der, *deg, *deb), for theta = TF
// parameter (row, column), at density d with sigma = sigma(d) and the point found by tf_point().
inline real tf_param_partial(real d, real sigma, TfPoint pt, __global const real* tf, int count,
                             real4 scalars, int row, int column, real* der, real* deg, real* deb) {
  real ds = (real)0, dr = (real)0, dg = (real)0, db = (real)0;
#if IVR_TF == IVR_TF_IDENTITY
  // sigma = a·d, E = a·b·d² (grey)
  if (column == 0) {
    ds = d;
    dr = dg = db = scalars.y * d * d;
  } else {
    dr = dg = db = scalars.x * d * d;
  }
#elif IVR_TF == IVR_TF_GAUSSIAN
  __global const real* p = tf + row * IVR_TF_STRIDE_GAUSSIAN;  // mean, width, r, g, b, e
  const real z = (d - p[0]) / p[1];
  const real g = exp((real)-0.5 * z * z);
  real dgs = (real)0;  // d (e·G) / d theta, for the extinction and the emission through it
  if (column < 3) {
    const real v = p[5] * g;
    dr = column == 0 ? v : (real)0;
    dg = column == 1 ? v : (real)0;
    db = column == 2 ? v : (real)0;
  } else {
    dgs = column == 3 ? g : (column == 4 ? p[5] * g * z / p[1] : p[5] * g * z * z / p[1]);
    ds = dgs;
    dr = dgs * p[2];
    dg = dgs * p[3];
    db = dgs * p[4];
  }
#else
  const TfSegment s = pt.s;
  // Weight of this row in the sample (beyond the ends the one row has weight 1).
  const real weight = s.row0 == s.row1
                          ? (row == s.row0 ? (real)1 : (real)0)
                          : (row == s.row0 ? (real)1 - s.w1 : (row == s.row1 ? s.w1 : (real)0));
  __global const real* a = tf_rgbs(tf, s.row0);  // r, g, b, sigma
  __global const real* b = tf_rgbs(tf, s.row1);
  if (column < 3) {  // colour channel: E_c = sigma·c
    const real v = sigma * weight;
    dr = column == 0 ? v : (real)0;
    dg = column == 1 ? v : (real)0;
    db = column == 2 ? v : (real)0;
  } else if (column == 3) {  // extinction
    ds = weight;
    dr = weight * pt.cr;
    dg = weight * pt.cg;
    db = weight * pt.cb;
  }
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  else if (s.row0 != s.row1 && (row == s.row0 || row == s.row1)) {
    // Control-point density: w = (d - d_k) / (d_k+1 - d_k) moves with both ends.
    const real dw = row == s.row0 ? (s.w1 - (real)1) * s.dw1_dd : -s.w1 * s.dw1_dd;
    ds = (b[3] - a[3]) * dw;
    dr = ds * pt.cr + sigma * (b[0] - a[0]) * dw;
    dg = ds * pt.cg + sigma * (b[1] - a[1]) * dw;
    db = ds * pt.cb + sigma * (b[2] - a[2]) * dw;
  }
#endif
#endif
  *der = dr;
  *deg = dg;
  *deb = db;
  return ds;
}

// d σ and d colour (not premultiplied) at density x inside TF piece pc (tf.cl, tf_piece) for TF
// parameter (row, column): the integrators that integrate through the TF exactly. Column 4 of a
// piecewise-linear TF, the control point's density, moves the piece's end.
inline void tf_piece_partial(const TfPiece* pc, real x, int row, int column, real* ds, real* dcr,
                             real* dcg, real* dcb) {
  *ds = *dcr = *dcg = *dcb = (real)0;
#if IVR_TF == IVR_TF_IDENTITY
  (void)pc, (void)row;
  if (column == 0)
    *ds = x;  // σ = a·x
  else
    *dcr = *dcg = *dcb = x;  // colour = b·x
#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  const bool flat = pc->row0 == pc->row1;
  const real w1 = (x - pc->x0) * pc->inv_width;
  const real weight = flat ? (row == pc->row0 ? (real)1 : (real)0)
                           : (row == pc->row0 ? (real)1 - w1 : (row == pc->row1 ? w1 : (real)0));
  if (column < 3) {
    *dcr = column == 0 ? weight : (real)0;
    *dcg = column == 1 ? weight : (real)0;
    *dcb = column == 2 ? weight : (real)0;
  } else if (column == 3) {
    *ds = weight;
  } else if (!flat && (row == pc->row0 || row == pc->row1)) {
    // σ = σ0 + s1·(x − x0) with s1 = (σ1 − σ0)/(x1 − x0): d/dx0 = −s1·(1 − w), d/dx1 = −s1·w.
    const real k = row == pc->row0 ? w1 - (real)1 : -w1;
    *ds = k * pc->s1;
    *dcr = k * pc->c1r, *dcg = k * pc->c1g, *dcb = k * pc->c1b;
  }
#else
  (void)pc, (void)x, (void)row, (void)column;
#endif
}

#endif
