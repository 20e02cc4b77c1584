// primal.cl — the primal march of every integrator: what the render computes for one ray, and
// what the gradient kernels re-run first so that they differentiate exactly what was rendered.
#ifndef IVR_PRIMAL_CL
#define IVR_PRIMAL_CL
#include "compositing.cl"
#include "config.cl"
#include "empty_space.cl"
#include "end_sample.cl"
#include "exact.cl"
#include "geometry.cl"
#include "march.cl"
#include "preintegrated.cl"
#include "tf.cl"

// What a march hands back: the transmittance left, the emitted colour, the samples taken, and
// where it stopped (early termination) for the gradient kernels' second march: one past the last
// segment taken (midpoint, trapezoid, preintegrated) or the pieces walked (exact).
// The absorption model needs the transmittance at the end only: its marches sum the optical
// depth instead (compensated, so that 1e5-sample rays keep float32's precision: the product of
// 1e5 factors would not) and take T = e^−τ once (march_finish).
typedef struct {
  real transmittance;
  real cr, cg, cb;
  real kr, kg, kb;  // compensation (accumulate)
  real tau, ktau;   // absorption: the optical depth so far, and its compensation
  uint samples;
  uint end;
} Radiance;

inline Radiance radiance_begin(void) {
  Radiance r;
  r.transmittance = (real)1;
  r.cr = r.cg = r.cb = r.kr = r.kg = r.kb = r.tau = r.ktau = (real)0;
  r.samples = r.end = 0;
  return r;
}

// What early termination compares: the transmittance with min_transmittance (emission–
// absorption), or the optical depth with −log(min_transmittance) (absorption).
inline real march_threshold(real min_transmittance) {
#if IVR_EMISSION
  return min_transmittance;
#else
  return min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
#endif
}

inline bool march_stopped(const Radiance* r, real threshold) {
#if IVR_EMISSION
  return r->transmittance < threshold;
#else
  return r->tau > threshold;
#endif
}

// The end of a march: absorption's transmittance from its optical depth.
inline void march_finish(Radiance* r) {
#if !IVR_EMISSION
  r->transmittance = exp(-r->tau);
#else
  (void)r;
#endif
}

#if IVR_EMISSION
// Adds a segment's emitted colour, weighted, to the ray's (compensated) sums; the transmittance
// behind the segment becomes `next`.
inline void radiance_emit(Radiance* r, real weight, real er, real eg, real eb, real next) {
  accumulate(&r->cr, &r->kr, weight * er);
  accumulate(&r->cg, &r->kg, weight * eg);
  accumulate(&r->cb, &r->kb, weight * eb);
  r->transmittance = next;
}
#endif

// Adds one segment of optical depth tau emitting (er, eg, eb)·dt·fraction(tau) per unit
// transmittance: the midpoint and trapezoid rules' compositing.
inline void composite(Radiance* r, real tau, real dt, real er, real eg, real eb) {
#if IVR_EMISSION
  real fraction;
  const real decay = decay_and_fraction(tau, &fraction);
  radiance_emit(r, r->transmittance * dt * fraction, er, eg, eb,
                attenuate(r->transmittance, tau, fraction, decay));
#else
  (void)dt, (void)er, (void)eg, (void)eb;
  accumulate(&r->tau, &r->ktau, tau);
#endif
}

#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
// One sample at the middle of each segment.
inline void primal_march(__global const real* volume, int4 dims, const March* m,
                         __global const real* tf, int tf_count, real4 tf_scalars,
                         real min_transmittance, __global const uchar* occupied, int4 bricks,
                         Radiance* r) {
  int segment = 0;  // the transfer function's search cursor (tf_sample)
  const real threshold = march_threshold(min_transmittance);
  for (uint i = 0; i < m->n;) {
    const real t = sample_t(m, i);
    const real ux = m->u0x + t * m->dux, uy = m->u0y + t * m->duy, uz = m->u0z + t * m->duz;
#if IVR_EMPTY_SPACE
    // (Reading the grid at every sample measured faster on PoCL than tracking where the ray
    // leaves each occupied brick: bench/empty_space_bench.cpp.)
    const real exit = empty_brick_exit(ux, uy, uz, m, dims, occupied, bricks);
    if (exit >= (real)0) {
      i = skip_to(i, m->n, m->t0, m->dt, exit);
      continue;
    }
#endif
    const real d = trilinear_at(volume, dims, ux, uy, uz);
    real er, eg, eb;
    const real sigma = tf_sample(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb);
    composite(r, sigma * m->dt, m->dt, er, eg, eb);
    ++r->samples;
    r->end = ++i;
#if IVR_EARLY_TERMINATION
    if (march_stopped(r, threshold)) break;
#endif
  }
  march_finish(r);
}

#elif IVR_ENDPOINT_SAMPLES
// Samples at the segment ends; each segment from its two ends (trapezoid: their average;
// preintegrated: the density linear between them, through the TF exactly).
inline void primal_march(__global const real* volume, int4 dims, const March* m,
                         __global const real* tf, int tf_count, real4 tf_scalars,
                         real min_transmittance, __global const uchar* occupied, int4 bricks,
                         Radiance* r) {
  int segment = 0;
  const real threshold = march_threshold(min_transmittance);
  EndSample a = end_sample(volume, dims, m, 0, tf, tf_count, tf_scalars, &segment);
  ++r->samples;
  for (uint i = 0; i < m->n;) {
#if IVR_EMPTY_SPACE
    {
      const uint k = endpoint_skip(i, m->n, a.ux, a.uy, a.uz, m, dims, occupied, bricks);
      if (k > i) {
        i = k;
        if (i >= m->n) break;
        a = end_sample(volume, dims, m, i, tf, tf_count, tf_scalars, &segment);
        ++r->samples;
      }
    }
#endif
    const EndSample b = end_sample(volume, dims, m, i + 1, tf, tf_count, tf_scalars, &segment);
    ++r->samples;
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    composite(r, (real)0.5 * (a.sigma + b.sigma) * m->dt, m->dt, (real)0.5 * (a.er + b.er),
              (real)0.5 * (a.eg + b.eg), (real)0.5 * (a.eb + b.eb));
#else
    Attenuation at;
    real er, eg, eb;
    preintegrated_segment(&a, &b, m->dt, tf, tf_count, tf_scalars, &segment, &at, &er, &eg, &eb);
#if IVR_EMISSION
    radiance_emit(r, r->transmittance, er, eg, eb, attenuation_apply(&at, r->transmittance));
#else
    accumulate(&r->tau, &r->ktau, at.tau);
#endif
#endif
    a = b;
    r->end = ++i;
#if IVR_EARLY_TERMINATION
    if (march_stopped(r, threshold)) break;
#endif
  }
  march_finish(r);
}

#elif IVR_SCHEME == IVR_SCHEME_EXACT
// Absorption only: the optical depth of every piece, exactly.
inline void primal_march(__global const real* volume, int4 dims, const March* m,
                         __global const real* tf, int tf_count, real4 tf_scalars,
                         real min_transmittance, __global const uchar* occupied, int4 bricks,
                         Radiance* r) {
  real tau = (real)0, k = (real)0;
  const real tau_stop = min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
  Pieces p;
  pieces_begin(&p, m, dims, m->t0);
  real ta, tb;
  while (pieces_next(&p, m, dims, &ta, &tb)) {
    ++r->end;
    if (!(tb > ta)) continue;
#if IVR_EMPTY_SPACE
    if (pieces_skip_empty(&p, m, dims, ta, tb, occupied, bricks)) continue;
#endif
    const PieceCell cell = piece_cell(m, dims, ta, tb);
    real v[8];
    piece_corners(volume, dims, cell, v);
    const Cubic c = piece_cubic(v, cell);
    uint nodes = 0;
    accumulate(&tau, &k, piece_optical_depth(&c, tb - ta, tf, tf_count, tf_scalars, &nodes));
    r->samples += nodes;
#if IVR_EARLY_TERMINATION
    if (tau > tau_stop) break;
#endif
  }
  r->transmittance = exp(-tau);
}
#endif

#endif
