// preintegrated.cl — the `preintegrated` integrator's segment: the density linear between the two
// end samples, integrated exactly through the TF. Cut where the density crosses a TF knot, each
// sub-segment has σ and the colour linear along the ray, whose emission–absorption integral is
// closed (kernels/linear_segment.cl). The adjoint is kernels/adjoint_preintegrated.cl.
#ifndef IVR_PREINTEGRATED_CL
#define IVR_PREINTEGRATED_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (preintegrated)
#define IVR_SCHEME 3
#endif
#include "compositing.cl"
#include "config.cl"
#include "end_sample.cl"
#include "linear_segment.cl"
#include "tf.cl"
#include "rays.cl"

// Every function below takes one ray or a packet of rays in vector lanes (kernels/rays.cl): a
// packet's segments are cut each at its own knots, by masked loops that run as often as the segment
// with most sub-segments, and every lane computes what one ray computes.

// Below this density change the segment is not cut at a knot between its ends: the knot's
// position moves as 1/(db − da) with the densities, and its derivative would come from a difference
// of nearly equal terms divided by that. The integral changes by at most ~dt·|Δσ'|·|db − da|/8.
#if IVR_F64
#define IVR_MIN_CUT_DELTA 1e-9
#else
#define IVR_MIN_CUT_DELTA 1e-4f
#endif

// The sub-segments of a segment from density da (position φ = 0) to db (φ = 1).
typedef struct {
  vreal da, delta;
  vint direction;  // of the density: +1, -1, 0 (no cuts)
  vreal x, phi;    // where the next sub-segment starts
  vint knot;       // ... and whether that is a knot (else the segment's start)
  vint done;
  vint cursor;  // the TF search cursor (tf_interval), carried along the ray by the caller
} Cuts;

inline void cuts_begin(Cuts* c, vreal da, vreal db, vint cursor) {
  c->cursor = cursor;
  c->da = da;
  c->delta = db - da;
  const vint cut = vmask_of(fabs(c->delta) > IVR_MIN_CUT_DELTA * fmax(fabs(da), fabs(db)));
  c->direction = vseli((vint)0, vseli((vint)-1, (vint)1, vmask_of(c->delta > (real)0)), cut);
  c->x = da;
  c->phi = (vreal)(real)0;
  c->knot = (vint)0;
  c->done = (vint)0;
}

// One sub-segment: densities xs → xe at positions φs → φe, each end a knot or the segment's own,
// and the TF piece it lies in.
typedef struct {
  vreal xs, xe, phis, phie;
  vint knot_s, knot_e;
  TfPiece piece;
} SubSegment;

// The next sub-segment of every ray whose segment has one left; returns those rays (a mask; the
// others' *s is unspecified).
inline vint cuts_next(Cuts* c, vreal db, __global const real* tf, int count, real4 scalars,
                      SubSegment* s) {
  const vint go = !c->done;
  if (!vany(go)) return go;
  s->xs = c->x;
  s->phis = c->phi;
  s->knot_s = c->knot;
  vreal knot = c->x;
  vint at_knot = go && c->direction != 0;
  if (vany(at_knot)) {
    const vint j = tf_interval(c->x, tf, count, scalars, &c->cursor);
    at_knot = at_knot && tf_next_knot(c->x, j, c->direction, tf, count, scalars, &knot) &&
              vseli(vmask_of(knot > db), vmask_of(knot < db), c->direction > 0);
  }
  s->xe = vsel(db, knot, at_knot);
  s->phie = vsel((vreal)(real)1, (knot - c->da) / c->delta, at_knot);
  s->knot_e = at_knot;
  c->done = c->done || !at_knot;
  c->x = s->xe;
  c->phi = s->phie;
  c->knot = s->knot_e;
  s->piece = tf_piece(tf_interval((real)0.5 * (s->xs + s->xe), tf, count, scalars, &c->cursor), tf,
                      count, scalars);
  return go;
}

// A segment's opacity and transmittance, each accurate where it is small: the opacity summed from
// the sub-segments' α = p + q, the transmittance multiplied from their e^{−τ} (1 − α below τ = 0.1,
// where that keeps the precision; exp(−τ) above, where 1 − α would lose it to α ≈ 1).
typedef struct {
  vreal opacity, transmittance;
  vreal tau;  // the segment's optical depth (absorption sums it along the ray)
} Attenuation;

// Adds a sub-segment of depth tau and opacity alpha, where m is true.
inline void attenuation_add_where(Attenuation* at, vreal tau, vreal alpha, vint m) {
  at->tau = vsel(at->tau, at->tau + tau, m);
  at->opacity = vsel(at->opacity, fma(at->transmittance, alpha, at->opacity), m);
  const vint small = vmask_of(tau < (real)0.1);
  vreal next = fma(-at->transmittance, alpha, at->transmittance);
  if (!vall(small || !m)) next = vsel(at->transmittance * vexp(-tau), next, small);
  at->transmittance = vsel(at->transmittance, next, m);
}

inline void attenuation_add(Attenuation* at, vreal tau, vreal alpha) {
  attenuation_add_where(at, tau, alpha, vtrue);
}

// The ray's transmittance t behind a segment of attenuation at.
inline vreal attenuation_apply(const Attenuation* at, vreal t) {
  return vsel(t * at->transmittance, fma(-t, at->opacity, t), vmask_of(at->opacity < (real)0.5));
}

// The segment's emission per unit entering transmittance (er, eg, eb) and its attenuation, for
// the rays where `live` is true.
inline void preintegrated_segment(const EndSample* a, const EndSample* b, vreal dt,
                                  __global const real* tf, int count, real4 scalars, vint* cursor,
                                  vint live, Attenuation* at, vreal* er, vreal* eg, vreal* eb) {
  vreal r = (vreal)(real)0, g = r, bl = r;
  at->opacity = at->tau = (vreal)(real)0;
  at->transmittance = (vreal)(real)1;
  Cuts c;
  cuts_begin(&c, a->d, b->d, *cursor);
  c.done = !live;
  SubSegment s;
  vint go;
  while (vany(go = cuts_next(&c, b->d, tf, count, scalars, &s))) {
    const vreal length = dt * (s.phie - s.phis);
    const vreal ea = tf_piece_sigma(&s.piece, s.xs) * length,
                eb_ = tf_piece_sigma(&s.piece, s.xe) * length;
    vreal p, q;
    linear_segment_pq(ea, eb_, go, &p, &q);
#if IVR_EMISSION
    vreal csr, csg, csb, cer, ceg, ceb;
    tf_piece_color(&s.piece, s.xs, &csr, &csg, &csb);
    tf_piece_color(&s.piece, s.xe, &cer, &ceg, &ceb);
    r = vsel(r, r + at->transmittance * (csr * p + cer * q), go);
    g = vsel(g, g + at->transmittance * (csg * p + ceg * q), go);
    bl = vsel(bl, bl + at->transmittance * (csb * p + ceb * q), go);
#endif
    // p + q: the sub-segment's 1 − e^{−τ}
    attenuation_add_where(at, (real)0.5 * (ea + eb_), p + q, go);
  }
  *cursor = c.cursor;
  *er = r, *eg = g, *eb = bl;
}

#endif
