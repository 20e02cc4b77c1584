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

#if IVR_RAYS == 1  // one ray per work-item (kernels/rays.cl)

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
  real da, delta;
  int direction;  // of the density: +1, -1, 0 (no cuts)
  real x, phi;    // where the next sub-segment starts
  bool knot;      // ... and whether that is a knot (else the segment's start)
  bool done;
  int cursor;  // the TF search cursor (tf_interval), carried along the ray by the caller
} Cuts;

inline void cuts_begin(Cuts* c, real da, real db, int cursor) {
  c->cursor = cursor;
  c->da = da;
  c->delta = db - da;
  const bool cut = fabs(c->delta) > IVR_MIN_CUT_DELTA * fmax(fabs(da), fabs(db));
  c->direction = !cut ? 0 : (c->delta > (real)0 ? 1 : -1);
  c->x = da;
  c->phi = (real)0;
  c->knot = false;
  c->done = false;
}

// One sub-segment: densities xs → xe at positions φs → φe, each end a knot or the segment's own,
// and the TF piece it lies in.
typedef struct {
  real xs, xe, phis, phie;
  bool knot_s, knot_e;
  TfPiece piece;
} SubSegment;

inline bool cuts_next(Cuts* c, real db, __global const real* tf, int count, real4 scalars,
                      SubSegment* s) {
  if (c->done) return false;
  s->xs = c->x;
  s->phis = c->phi;
  s->knot_s = c->knot;
  real knot;
  if (c->direction != 0 &&
      tf_next_knot(c->x, tf_interval(c->x, tf, count, scalars, &c->cursor), c->direction, tf, count,
                   scalars, &knot) &&
      (c->direction > 0 ? knot < db : knot > db)) {
    s->xe = knot;
    s->phie = (knot - c->da) / c->delta;
    s->knot_e = true;
  } else {
    s->xe = db;
    s->phie = (real)1;
    s->knot_e = false;
    c->done = true;
  }
  c->x = s->xe;
  c->phi = s->phie;
  c->knot = s->knot_e;
  s->piece = tf_piece(tf_interval((real)0.5 * (s->xs + s->xe), tf, count, scalars, &c->cursor), tf,
                      count, scalars);
  return true;
}

// A segment's opacity and transmittance, each accurate where it is small: the opacity summed from
// the sub-segments' α = p + q, the transmittance multiplied from their e^{−τ} (1 − α below τ = 0.1,
// where that keeps the precision; exp(−τ) above, where 1 − α would lose it to α ≈ 1).
typedef struct {
  real opacity, transmittance;
  real tau;  // the segment's optical depth (absorption sums it along the ray)
} Attenuation;

inline void attenuation_add(Attenuation* at, real tau, real alpha) {
  at->tau += tau;
  at->opacity = fma(at->transmittance, alpha, at->opacity);
  at->transmittance = tau < (real)0.1 ? fma(-at->transmittance, alpha, at->transmittance)
                                      : at->transmittance * exp(-tau);
}

// The ray's transmittance t behind a segment of attenuation at.
inline real attenuation_apply(const Attenuation* at, real t) {
  return at->opacity < (real)0.5 ? fma(-t, at->opacity, t) : t * at->transmittance;
}

// The segment's emission per unit entering transmittance (er, eg, eb) and its attenuation.
inline void preintegrated_segment(const EndSample* a, const EndSample* b, real dt,
                                  __global const real* tf, int count, real4 scalars, int* cursor,
                                  Attenuation* at, real* er, real* eg, real* eb) {
  real r = (real)0, g = (real)0, bl = (real)0;
  at->opacity = at->tau = (real)0;
  at->transmittance = (real)1;
  Cuts c;
  cuts_begin(&c, a->d, b->d, *cursor);
  SubSegment s;
  while (cuts_next(&c, b->d, tf, count, scalars, &s)) {
    const real length = dt * (s.phie - s.phis);
    const real ea = tf_piece_sigma(&s.piece, s.xs) * length,
               eb_ = tf_piece_sigma(&s.piece, s.xe) * length;
    real p, q;
    linear_segment_pq(ea, eb_, &p, &q);
#if IVR_EMISSION
    real csr, csg, csb, cer, ceg, ceb;
    tf_piece_color(&s.piece, s.xs, &csr, &csg, &csb);
    tf_piece_color(&s.piece, s.xe, &cer, &ceg, &ceb);
    r += at->transmittance * (csr * p + cer * q);
    g += at->transmittance * (csg * p + ceg * q);
    bl += at->transmittance * (csb * p + ceb * q);
#endif
    attenuation_add(at, (real)0.5 * (ea + eb_), p + q);  // p + q: the sub-segment's 1 − e^{−τ}
  }
  *cursor = c.cursor;
  *er = r, *eg = g, *eb = bl;
}

#endif  // IVR_RAYS == 1

#endif
