// linear_segment.cl — PROVISIONAL (replaced by the helper's version): emission–absorption over a
// sub-segment with σ and the colour linear along it. a = σs·L, b = σe·L, E(x) = a x + (b − a)x²/2,
// P = ∫(1 − e^{−E}), Q = ∫(e^{−E} − e^{−τ}), τ = (a + b)/2.
#ifndef IVR_LINEAR_SEGMENT_CL
#define IVR_LINEAR_SEGMENT_CL
#include "config.cl"

typedef struct {
  real p, q;
  real dp_da, dp_db, dq_da, dq_db;
} LinearSegment;

inline LinearSegment linear_segment(real a, real b) {
  const real xs[8] = {0.0198550717512319, 0.1016667612931866, 0.2372337950418355,
                      0.4082826787521751, 0.5917173212478249, 0.7627662049581645,
                      0.8983332387068134, 0.9801449282487681};
  const real ws[8] = {0.0506142681451881, 0.1111905172266872, 0.1568533229389436,
                      0.1813418916891810, 0.1813418916891810, 0.1568533229389436,
                      0.1111905172266872, 0.0506142681451881};
  const real tau = (real)0.5 * (a + b);
  const int pieces = (int)clamp(ceil(tau), (real)1, (real)64);
  LinearSegment r;
  r.p = r.q = r.dp_da = r.dp_db = (real)0;
  for (int k = 0; k < pieces; ++k)
    for (int i = 0; i < 8; ++i) {
      const real x = ((real)k + xs[i]) / (real)pieces, w = ws[i] / (real)pieces;
      const real e_x = x * (a + (real)0.5 * (b - a) * x);
      const real rest = (real)0.5 * ((real)1 - x) * (a * ((real)1 - x) + b * ((real)1 + x));
      const real e = exp(-e_x);
      r.p += w * -expm1(-e_x);
      r.q += w * e * -expm1(-rest);
      r.dp_da += w * e * (x - (real)0.5 * x * x);
      r.dp_db += w * e * (real)0.5 * x * x;
    }
  const real e_half = (real)0.5 * exp(-tau);
  r.dq_da = e_half - r.dp_da;
  r.dq_db = e_half - r.dp_db;
  return r;
}

inline void linear_segment_pq(real a, real b, real* p, real* q) {
  const LinearSegment r = linear_segment(a, b);
  *p = r.p;
  *q = r.q;
}

#endif
