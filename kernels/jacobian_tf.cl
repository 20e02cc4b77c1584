// jacobian_tf.cl — partial derivatives of the transfer function with respect to one of its own
// parameters (row, column of the TF gradient layout; column 4 of a piecewise-linear TF is the
// control point's density), at density d, for forward mode. One-sided at control points and
// table entries like tf_sample(): the segment [d_k, d_k+1) holding d is used.
#ifndef IVR_TF_TANGENT_CL
#define IVR_TF_TANGENT_CL
#include "adjoint_tf.cl"

// d sigma / d theta, and the premultiplied emission's in (*der, *deg, *deb), for theta = TF
// parameter (row, column), at density d with sigma = sigma(d), its slopes in d (dsigma, der_dd,
// deg_dd, deb_dd) and where d lies in the TF (tf_sample_slope()'s point). One ray or every ray of
// a packet (kernels/rays.cl): a lane's parameter is the same for every ray.
inline vreal tf_param_partial(vreal d, vreal sigma, const TfPoint* pt, vreal dsigma, vreal der_dd,
                              vreal deg_dd, vreal deb_dd, __global const real* tf, int count,
                              real4 scalars, int row, int column, vreal* der, vreal* deg,
                              vreal* deb) {
  const vreal zero = (vreal)(real)0;
  vreal ds = zero, dr = zero, dg = zero, db = zero;
  (void)dsigma, (void)der_dd, (void)deg_dd, (void)deb_dd, (void)count;
#if IVR_TF == IVR_TF_IDENTITY
  // sigma = a·d, E = a·b·d² (grey)
  (void)sigma, (void)pt, (void)tf, (void)row;
  if (column == 0) {
    ds = d;
    dr = dg = db = scalars.y * d * d;
  } else {
    dr = dg = db = scalars.x * d * d;
  }
#elif IVR_TF == IVR_TF_GAUSSIAN
  (void)sigma, (void)pt, (void)scalars;
  __global const real* p = tf + row * IVR_TF_STRIDE_GAUSSIAN;  // mean, width, r, g, b, e
  const vreal z = (d - p[0]) / p[1];
  const vreal g = vexp((real)-0.5 * z * z);
  if (column < 3) {
    const vreal v = p[5] * g;
    if (column == 0) dr = v;
    if (column == 1) dg = v;
    if (column == 2) db = v;
  } else {
    // d (e·G) / d theta, for the extinction and the emission through it
    const vreal dgs = column == 3 ? g : (column == 4 ? p[5] * g * z / p[1] : p[5] * g * z * z / p[1]);
    ds = dgs;
    dr = dgs * p[2];
    dg = dgs * p[3];
    db = dgs * p[4];
  }
#else
  (void)d, (void)tf, (void)scalars;
  // Weight of this row in the sample (beyond the ends the one row has weight 1).
  const vint flat = pt->row0 == pt->row1;
  const vint at0 = pt->row0 == row, at1 = pt->row1 == row;
  const vreal weight =
      vsel(vsel(vsel(zero, pt->w1, at1), (real)1 - pt->w1, at0), vsel(zero, (vreal)(real)1, at0), flat);
  if (column < 3) {  // colour channel: E_c = sigma·c
    const vreal v = sigma * weight;
    if (column == 0) dr = v;
    if (column == 1) dg = v;
    if (column == 2) db = v;
  } else if (column == 3) {  // extinction
    ds = weight;
    dr = weight * pt->cr;
    dg = weight * pt->cg;
    db = weight * pt->cb;
  }
#if IVR_TF == IVR_TF_PIECEWISE_LINEAR
  else {
    // Control-point density: w = (d − d_k)/(d_k+1 − d_k) moves with both ends as d would, scaled
    // by k = w − 1 (row k) or −w (row k + 1): the partials are k times the slopes in d.
    const vreal k = vsel(vsel(vsel(zero, -pt->w1, at1), pt->w1 - (real)1, at0), zero, flat);
    ds = k * dsigma;
    dr = k * der_dd;
    dg = k * deg_dd;
    db = k * deb_dd;
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
// piecewise-linear TF, the control point's density, moves the piece's end. One ray or a packet.
inline void tf_piece_partial(const TfPiece* pc, vreal x, int row, int column, vreal* ds,
                             vreal* dcr, vreal* dcg, vreal* dcb) {
  const vreal zero = (vreal)(real)0, one = (vreal)(real)1;
  *ds = *dcr = *dcg = *dcb = zero;
#if IVR_TF == IVR_TF_IDENTITY
  (void)pc, (void)row, (void)zero, (void)one;
  if (column == 0)
    *ds = x;  // σ = a·x
  else
    *dcr = *dcg = *dcb = x;  // colour = b·x
#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR || IVR_TF == IVR_TF_TABLE
  const vint flat = pc->row0 == pc->row1, at0 = pc->row0 == row, at1 = pc->row1 == row;
  const vreal w1 = (x - pc->x0) * pc->inv_width;
  const vreal weight = vsel(vsel(vsel(zero, w1, at1), one - w1, at0), vsel(zero, one, at0), flat);
  if (column < 3) {
    *dcr = column == 0 ? weight : zero;
    *dcg = column == 1 ? weight : zero;
    *dcb = column == 2 ? weight : zero;
  } else if (column == 3) {
    *ds = weight;
  } else {
    // σ = σ0 + s1·(x − x0) with s1 = (σ1 − σ0)/(x1 − x0): d/dx0 = −s1·(1 − w), d/dx1 = −s1·w.
    const vint moves = !flat && (at0 || at1);
    const vreal k = vsel(-w1, w1 - (real)1, at0);
    *ds = vsel(zero, k * pc->s1, moves);
    *dcr = vsel(zero, k * pc->c1r, moves), *dcg = vsel(zero, k * pc->c1g, moves);
    *dcb = vsel(zero, k * pc->c1b, moves);
  }
#else
  (void)pc, (void)x, (void)row, (void)column, (void)one;
#endif
}

#endif
