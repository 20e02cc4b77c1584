// primal.cl — the primal march of every integrator: what the render computes for one ray, and
// what the gradient kernels re-run first so that they differentiate exactly what was rendered.
#ifndef IVR_PRIMAL_CL
#define IVR_PRIMAL_CL
#include "compositing.cl"
#include "config.cl"
#include "empty_space.cl"
#include "end_sample.cl"
#include "geometry.cl"
#include "march.cl"
#include "rays.cl"
#include "tf.cl"
#include "exact.cl"
#include "preintegrated.cl"

// What a march hands back, for one ray or every ray of a packet (kernels/rays.cl): the
// transmittance left, the emitted colour, the samples taken, and where it stopped (early
// termination) for the gradient kernels' second march: one past the last segment taken (midpoint,
// trapezoid, preintegrated) or the pieces walked (exact).
// The absorption model needs the transmittance at the end only: its marches sum the optical
// depth instead (compensated, so that 1e5-sample rays keep float32's precision: the product of
// 1e5 factors would not) and take T = e^−τ once (march_finish).
typedef struct {
  vreal transmittance;
  vreal cr, cg, cb;
  vreal kr, kg, kb;  // compensation (accumulate)
  vreal tau, ktau;   // absorption: the optical depth so far, and its compensation
  vint samples;
  vint end;
} Radiance;

inline Radiance radiance_begin(void) {
  Radiance r;
  r.transmittance = (vreal)(real)1;
  r.cr = r.cg = r.cb = r.kr = r.kg = r.kb = r.tau = r.ktau = (vreal)(real)0;
  r.samples = r.end = (vint)0;
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

// Where the march has stopped (a mask, kernels/rays.cl).
inline vint march_stopped(const Radiance* r, real threshold) {
#if IVR_EMISSION
  return vmask_of(r->transmittance < threshold);
#else
  return vmask_of(r->tau > threshold);
#endif
}

// The end of a march: absorption's transmittance from its optical depth.
inline void march_finish(Radiance* r) {
#if !IVR_EMISSION
  r->transmittance = vexp(-r->tau);
#else
  (void)r;
#endif
}

#if IVR_EMISSION
// Adds a segment's emitted colour, weighted, to the ray's (compensated) sums; the transmittance
// behind the segment becomes `next`. Only where m is true.
__attribute__((always_inline)) inline void radiance_emit_where(Radiance* r, vreal weight, vreal er,
                                                               vreal eg, vreal eb, vreal next,
                                                               vint m) {
  accumulate_where(&r->cr, &r->kr, weight * er, m);
  accumulate_where(&r->cg, &r->kg, weight * eg, m);
  accumulate_where(&r->cb, &r->kb, weight * eb, m);
  r->transmittance = vsel(r->transmittance, next, m);
}

inline void radiance_emit(Radiance* r, vreal weight, vreal er, vreal eg, vreal eb, vreal next) {
  radiance_emit_where(r, weight, er, eg, eb, next, vtrue);
}
#endif

// Adds one segment of optical depth tau emitting (er, eg, eb)·dt·fraction(tau) per unit
// transmittance: the midpoint and trapezoid rules' compositing. Only where m is true.
__attribute__((always_inline)) inline void composite_where(Radiance* r, vreal tau, vreal dt,
                                                           vreal er, vreal eg, vreal eb, vint m) {
#if IVR_EMISSION
  vreal fraction;
  const vreal decay = decay_and_fraction(tau, &fraction);
  radiance_emit_where(r, r->transmittance * dt * fraction, er, eg, eb,
                      attenuate(r->transmittance, tau, fraction, decay), m);
#else
  (void)dt, (void)er, (void)eg, (void)eb;
  accumulate_where(&r->tau, &r->ktau, tau, m);
#endif
}

inline void composite(Radiance* r, vreal tau, vreal dt, vreal er, vreal eg, vreal eb) {
  composite_where(r, tau, dt, er, eg, eb, vtrue);
}

// The fixed-step marches below are written once for one ray and for a packet: `live` holds the
// rays still marching, `take` those that take a sample in this round (a packet's rays skip empty
// space each on its own). One ray that skips goes round the loop again instead, so its `take` is
// true wherever it is used (the constant true without skipping): the masked updates compile to a
// scalar loop's plain ones.

#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
// One sample at the middle of each segment.
__attribute__((always_inline)) inline void primal_march(__global const real* volume, int4 dims,
                                                        const March* m, __global const real* tf,
                                                        int tf_count, real4 tf_scalars,
                                                        real min_transmittance,
                                                        __global const uchar* occupied, int4 bricks,
                                                        Radiance* r) {
  vint segment = (vint)0;  // the transfer function's search cursor (tf_sample)
  const real threshold = march_threshold(min_transmittance);
  const vint n = (vint)m->n;
  vint i = (vint)0;
  vint live = (vint)0 < n;
  while (vany(live)) {
    const vreal t = sample_t(m, i);
    const vreal ux = IVR_POINT(m, t, x), uy = IVR_POINT(m, t, y), uz = IVR_POINT(m, t, z);
#if IVR_EMPTY_SPACE
    // (Reading the grid at every sample measured faster on PoCL than tracking where the ray
    // leaves each occupied brick.)
    const vint take = midpoint_skip(&i, n, &live, ux, uy, uz, m, dims, occupied, bricks);
    if (!vany(take)) continue;
#else
    (void)occupied, (void)bricks;
    const vint take = IVR_RAYS == 1 ? vtrue : live;
#endif
    const vreal d = trilinear_at(volume, dims, ux, uy, uz);
    vreal er, eg, eb;
    const vreal sigma = tf_sample(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb);
    composite_where(r, sigma * m->dt, m->dt, er, eg, eb, take);
    r->samples += vcount(take);
    i += vcount(take);
    r->end = vseli(r->end, i, take);
    live = live && (i < n);
#if IVR_EARLY_TERMINATION
    live = live && !march_stopped(r, threshold);
#endif
  }
  march_finish(r);
}

#elif IVR_ENDPOINT_SAMPLES
// Samples at the segment ends; each segment from its two ends (trapezoid: their average;
// preintegrated: the density linear between them, through the TF exactly).
__attribute__((always_inline)) inline void primal_march(__global const real* volume, int4 dims,
                                                        const March* m, __global const real* tf,
                                                        int tf_count, real4 tf_scalars,
                                                        real min_transmittance,
                                                        __global const uchar* occupied, int4 bricks,
                                                        Radiance* r) {
  vint segment = (vint)0;
  const real threshold = march_threshold(min_transmittance);
  const vint n = (vint)m->n;
  vint i = (vint)0;
  vint live = (vint)0 < n;
  EndSample a = end_sample(volume, dims, m, i, tf, tf_count, tf_scalars, &segment);
  r->samples += vcount(live);
  while (vany(live)) {
#if IVR_EMPTY_SPACE
    {
      const vint again =
          endpoint_skip_step(&i, n, &live, a.ux, a.uy, a.uz, m, dims, occupied, bricks);
      if (vany(again)) {  // the sample the march goes on from
        const EndSample s = end_sample(volume, dims, m, i, tf, tf_count, tf_scalars, &segment);
        end_sample_where(&a, &s, again);
        r->samples += vcount(again);
      }
      if (!vany(live)) break;
    }
#else
    (void)occupied, (void)bricks;
#endif
    const vint take = IVR_RAYS == 1 ? vtrue : live;  // one ray: it is live in the loop
    const EndSample b = end_sample(volume, dims, m, i + 1, tf, tf_count, tf_scalars, &segment);
    r->samples += vcount(take);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    composite_where(r, (real)0.5 * (a.sigma + b.sigma) * m->dt, m->dt, (real)0.5 * (a.er + b.er),
                    (real)0.5 * (a.eg + b.eg), (real)0.5 * (a.eb + b.eb), take);
#else
    Attenuation at;
    vreal er, eg, eb;
    preintegrated_segment(&a, &b, m->dt, tf, tf_count, tf_scalars, &segment, take, &at, &er, &eg,
                          &eb);
#if IVR_EMISSION
    radiance_emit_where(r, r->transmittance, er, eg, eb, attenuation_apply(&at, r->transmittance),
                        take);
#else
    accumulate_where(&r->tau, &r->ktau, at.tau, take);
#endif
#endif
    a = b;
    i += vcount(take);
    r->end = vseli(r->end, i, take);
    live = live && (i < n);
#if IVR_EARLY_TERMINATION
    live = live && !march_stopped(r, threshold);
#endif
  }
  march_finish(r);
}

#elif IVR_SCHEME == IVR_SCHEME_EXACT
// Absorption only: the optical depth of every piece, exactly.
__attribute__((always_inline)) inline void primal_march(__global const real* volume, int4 dims,
                                                        const March* m, __global const real* tf,
                                                        int tf_count, real4 tf_scalars,
                                                        real min_transmittance,
                                                        __global const uchar* occupied, int4 bricks,
                                                        Radiance* r) {
  vreal tau = (vreal)(real)0, k = tau;
  const real tau_stop = min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
  Pieces p;
  pieces_begin(&p, m, dims, m->t0);
  vreal ta = m->t0, tb = m->t0;
  vint live = vtrue, go;
  while (vany(go = pieces_next_where(&p, m, dims, live, &ta, &tb))) {
    r->end += vcount(go);
    vint take = go && vmask_of(tb > ta);
#if IVR_EMPTY_SPACE
    if (vany(take))
      take = take && !pieces_skip_empty_where(&p, m, dims, take, ta, tb, occupied, bricks);
#else
    (void)occupied, (void)bricks;
#endif
    if (!vany(take)) continue;
    const PieceCell cell = piece_cell(m, dims, ta, tb);
    vreal v[8];
    piece_corners(volume, dims, cell, v);
    const Cubic c = piece_cubic(v, cell);
    vint nodes = (vint)0;
    accumulate_where(&tau, &k,
                     piece_optical_depth_where(&c, tb - ta, tf, tf_count, tf_scalars, take, &nodes),
                     take);
    r->samples += nodes;
#if IVR_EARLY_TERMINATION
    live = live && !vmask_of(tau > tau_stop);
#endif
  }
  r->transmittance = vexp(-tau);
}
#endif

#endif
