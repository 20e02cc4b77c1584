// bricked.cl — the out-of-core render (lib/brick/): the volume in bricks that overlap by one voxel,
// each brick marched on its own for the part of every ray inside it, with the samples on the
// ray's global grid (the unsplit march's t0, dt and n), and each ray's march state carried from
// brick to brick in front-to-back order, so that the composited result is the unsplit march's.
//
// A brick covers [lo, hi) of the global voxel-centre coordinates on each axis (planes through
// voxel centres; ±∞ where it reaches the box face) and holds the voxels lo..hi, so every trilinear
// lookup (and every `exact` piece, which lies between centre planes) inside it reads only its own
// voxels. A ray's window in a brick is its box-clipped interval cut by the brick's planes; the
// planes' crossings are computed from the global march alone, identically in every brick, so the
// windows of one ray partition [t0, t1] exactly and each sample (midpoint), segment (trapezoid,
// preintegrated: the one whose far end lies in the window; its near sample is carried) or piece
// (exact) is taken once. A brick takes a ray only where its window starts where the ray's march
// stands (t_next): a brick met out of order leaves the ray pending for the next sweep
// (lib/brick/bricked_render.cpp), so the order only decides the number of sweeps, never the result.
#include "bricked_state.cl"
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "primal.cl"

// The phases of one render (one kernel, so that every phase takes the same arguments).
#define IVR_BRICK_BEGIN 0
#define IVR_BRICK_MARCH 1
#define IVR_BRICK_FINISH 2

inline Radiance brick_load(__global const real* s, __global const uint* su) {
  Radiance r;
  r.transmittance = s[BS_T];
  r.cr = s[BS_CR], r.cg = s[BS_CG], r.cb = s[BS_CB];
  r.kr = s[BS_KR], r.kg = s[BS_KG], r.kb = s[BS_KB];
  r.tau = s[BS_TAU], r.ktau = s[BS_KTAU];
  r.samples = (int)su[BU_SAMPLES];
  r.end = (int)su[BU_END];
  return r;
}

inline void brick_store(const Radiance* r, __global real* s, __global uint* su) {
  s[BS_T] = r->transmittance;
  s[BS_CR] = r->cr, s[BS_CG] = r->cg, s[BS_CB] = r->cb;
  s[BS_KR] = r->kr, s[BS_KG] = r->kg, s[BS_KB] = r->kb;
  s[BS_TAU] = r->tau, s[BS_KTAU] = r->ktau;
  su[BU_SAMPLES] = (uint)r->samples;
  su[BU_END] = (uint)r->end;
}

// Whether the march has stopped early (the unsplit march's test, on the carried sums).
inline bool brick_stopped(const Radiance* r, real min_transmittance) {
#if IVR_EARLY_TERMINATION
  return march_stopped(r, march_threshold(min_transmittance)) != 0;
#else
  (void)r, (void)min_transmittance;
  return false;
#endif
}

// Marches the ray's window [tb0, tb1] in this brick (m: the global march with u0 moved to the
// brick's voxels); true where the ray stopped early.
inline bool brick_march(__global const real* volume, int4 dims, const RayMarch* m, real tb1,
                        __global const real* tf, int tf_count, real4 tf_scalars,
                        real min_transmittance, Radiance* r, __global real* s,
                        __global uint* su) {
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
  int segment = 0;
  uint i = su[BU_NEXT];
  bool stopped = false;
  while (i < m->n && !stopped) {
    const real t = sample_t(m, (int)i);
    if (!(t < tb1)) break;
    const real ux = m->u0x + t * m->dux, uy = m->u0y + t * m->duy, uz = m->u0z + t * m->duz;
    const real d = trilinear_at(volume, dims, ux, uy, uz);
    real er, eg, eb;
    const real sigma = tf_sample(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb);
    composite(r, sigma * m->dt, m->dt, er, eg, eb);
    r->samples += 1;
    ++i;
    r->end = (int)i;
    stopped = brick_stopped(r, min_transmittance);
  }
  su[BU_NEXT] = i;
  return stopped;
#elif IVR_ENDPOINT_SAMPLES
  int segment = 0;
  uint i = su[BU_NEXT];
  EndSample a;
  if (!(su[BU_FLAGS] & IVR_BRICK_STARTED)) {  // sample 0 lies in the first window
    a = end_sample(volume, dims, m, 0, tf, tf_count, tf_scalars, &segment);
    r->samples += 1;
    su[BU_FLAGS] |= IVR_BRICK_STARTED;
  } else {
    a.ux = a.uy = a.uz = (real)0;
    a.d = s[BS_AD], a.sigma = s[BS_ASIGMA];
    a.er = s[BS_AER], a.eg = s[BS_AEG], a.eb = s[BS_AEB];
  }
  bool stopped = false;
  while (i < m->n && !stopped) {
    // Segment i is this brick's where its far end lies in the window (the last one: where the
    // window reaches the ray's end, whatever t0 + n·dt rounds to).
    const bool mine = i + 1u < m->n ? sample_t(m, (int)i + 1) <= tb1 : tb1 >= m->t1;
    if (!mine) break;
    const EndSample b = end_sample(volume, dims, m, (int)i + 1, tf, tf_count, tf_scalars, &segment);
    r->samples += 1;
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    composite(r, (real)0.5 * (a.sigma + b.sigma) * m->dt, m->dt, (real)0.5 * (a.er + b.er),
              (real)0.5 * (a.eg + b.eg), (real)0.5 * (a.eb + b.eb));
#else
    Attenuation at;
    real er, eg, eb;
    preintegrated_segment(&a, &b, m->dt, tf, tf_count, tf_scalars, &segment, vtrue, &at, &er, &eg,
                          &eb);
#if IVR_EMISSION
    radiance_emit(r, r->transmittance, er, eg, eb, attenuation_apply(&at, r->transmittance));
#else
    accumulate(&r->tau, &r->ktau, at.tau);
#endif
#endif
    a = b;
    ++i;
    r->end = (int)i;
    stopped = brick_stopped(r, min_transmittance);
  }
  s[BS_AD] = a.d, s[BS_ASIGMA] = a.sigma;
  s[BS_AER] = a.er, s[BS_AEG] = a.eg, s[BS_AEB] = a.eb;
  su[BU_NEXT] = i;
  return stopped;
#else  // exact (absorption): the pieces of the window
  const real tau_stop =
      min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
  RayMarch w = *m;
  w.t1 = tb1;
  Pieces p;
  pieces_begin(&p, &w, dims, s[BS_TNEXT]);
  real ta, tb;
  bool stopped = false;
  while (!stopped && pieces_next(&p, &w, dims, &ta, &tb)) {
    r->end += 1;
    if (!(tb > ta)) continue;
    const PieceCell cell = piece_cell(&w, dims, ta, tb);
    real v[8];
    piece_corners(volume, dims, cell, v);
    const Cubic c = piece_cubic(v, cell);
    int nodes = 0;
    accumulate(&r->tau, &r->ktau, piece_optical_depth(&c, tb - ta, tf, tf_count, tf_scalars,
                                                      &nodes));
    r->samples += nodes;
#if IVR_EARLY_TERMINATION
    stopped = r->tau > tau_stop;
#endif
  }
  (void)su;
  return stopped;
#endif
}

// phase BEGIN: every ray's state (a ray that misses the box, or whose interval is empty, is done);
// MARCH: the rays whose march stands at their window's start in this brick (`volume`, `dims`: its
// voxels; `brick_lo`, `brick_hi`: its planes; `origin`: its first voxel); FINISH: each pixel
// from its state (as render.cl writes it), and the rays not done yet counted into `pending`.
__kernel void bricked_render(__global const real* restrict volume, const int4 dims,
                             const real4 box_min, const real4 box_max, const real4 inv_voxel,
                             __global const real* restrict cameras, const int width,
                             const int height, __global const real* restrict tf,
                             const int tf_count, const real4 tf_scalars, const real4 background,
                             const real step, const real min_transmittance, const int phase,
                             const real4 brick_lo, const real4 brick_hi, const int4 origin,
                             __global real* restrict state, __global uint* restrict state_u,
                             __global real* restrict image, __global uint* restrict samples,
                             __global uint* restrict pending) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;
  const size_t pixel = ((size_t)view * height + y) * width + x;
  __global real* s = state + pixel * IVR_BRICK_REALS;
  __global uint* su = state_u + pixel * IVR_BRICK_UINTS;
  __global const real* cam = cameras + view * IVR_CAMERA_STRIDE;

  if (phase == IVR_BRICK_FINISH) {
    Radiance r = brick_load(s, su);
    march_finish(&r);
    if (!(su[BU_FLAGS] & IVR_BRICK_DONE)) atomic_inc(pending);
    samples[pixel] = (uint)r.samples;
#if IVR_EMISSION
    __global real* out = image + pixel * 4;
    out[0] = r.cr + r.transmittance * background.x;
    out[1] = r.cg + r.transmittance * background.y;
    out[2] = r.cb + r.transmittance * background.z;
    out[3] = (real)1 - r.transmittance;
#else
    image[pixel] = background.x * r.transmittance;
#endif
    return;
  }

  RayMarch m;
  if (phase == IVR_BRICK_BEGIN) {
    const bool hit = march_begin(camera_ray(cam, x, y, width, height), cam, x, y, width, height,
                                 box_min, box_max, inv_voxel, step, &m);
    for (int k = 0; k < IVR_BRICK_REALS; ++k) s[k] = (real)0;
    s[BS_T] = (real)1;
    su[BU_SAMPLES] = su[BU_END] = su[BU_NEXT] = su[BU_N] = 0u;
    // An empty interval: the unsplit march's samples there add nothing (dt = 0).
    su[BU_FLAGS] = hit && m.t1 > m.t0 ? 0u : IVR_BRICK_DONE;
    if (!hit) return;
    s[BS_TNEXT] = s[BS_T0] = m.t0;
    s[BS_T1] = m.t1, s[BS_DT] = m.dt;
    s[BS_U0 + 0] = m.u0x, s[BS_U0 + 1] = m.u0y, s[BS_U0 + 2] = m.u0z;
    s[BS_U0 + 3] = m.dux, s[BS_U0 + 4] = m.duy, s[BS_U0 + 5] = m.duz;
    su[BU_N] = m.n;
    return;
  }
  real tb1;
  if (!brick_enter(s, su, brick_lo, brick_hi, origin, &m, &tb1)) return;
  Radiance r = brick_load(s, su);
  const bool stopped =
      brick_march(volume, dims, &m, tb1, tf, tf_count, tf_scalars, min_transmittance, &r, s, su);
  brick_store(&r, s, su);
  s[BS_TNEXT] = tb1;
  if (stopped || tb1 >= m.t1) su[BU_FLAGS] |= IVR_BRICK_DONE;
}

// --- The density gradient brick by brick (midpoint; lib/brick/bricked_gradient.cpp) -------------
// After the forward sweeps, ADJOINT_BEGIN turns each ray's composited state into its loss terms
// and dL/dpixel (as adjoint.cl's pixel_adjoint) and restarts its march; ADJOINT_MARCH then walks
// the bricks front to back again, the carried prefix (transmittance and emission, summed as the
// in-core adjoint sums them) giving each sample's remaining radiance as C minus the prefix
// (docs/design.md), and scatters dL/d density into the brick's voxels (`grad`, zeroed per visit;
// the host adds it into the volume's gradient).
#include "adjoint_tf.cl"
#include "loss.cl"

#define IVR_BRICK_ADJOINT_BEGIN 3
#define IVR_BRICK_ADJOINT_MARCH 4
// Per ray, beside the march state: dL/d(r, g, b, alpha) (absorption: dL/dI in 0), the pixel's
// radiance (r, g, b) and transmittance (absorption: its intensity in 4, unused 5–6).
#define IVR_BRICK_ADJOINT_REALS 8

__kernel void bricked_adjoint(__global const real* restrict volume, const int4 dims,
                              const real4 box_min, const real4 box_max, const real4 inv_voxel,
                              __global const real* restrict cameras, const int width,
                              const int height, __global const real* restrict tf,
                              const int tf_count, const real4 tf_scalars, const real4 background,
                              const real step, const real min_transmittance, const int phase,
                              const real4 brick_lo, const real4 brick_hi, const int4 origin,
                              __global real* restrict state, __global uint* restrict state_u,
                              __global real* restrict adj, __global const real* restrict target,
                              const real norm, __global real* restrict pixel_loss,
                              __global real* grad) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;
  (void)cameras, (void)box_min, (void)box_max, (void)inv_voxel, (void)step, (void)min_transmittance;
  const size_t pixel = ((size_t)view * height + y) * width + x;
  __global real* s = state + pixel * IVR_BRICK_REALS;
  __global uint* su = state_u + pixel * IVR_BRICK_UINTS;
  __global real* a = adj + pixel * IVR_BRICK_ADJOINT_REALS;

  if (phase == IVR_BRICK_ADJOINT_BEGIN) {
    Radiance r = brick_load(s, su);
    march_finish(&r);
    __global const real* tgt = target + pixel * IVR_CHANNELS;
    real loss = (real)0;
    const real t = r.transmittance;
#if IVR_EMISSION
    const real total_r = r.cr + t * background.x, total_g = r.cg + t * background.y,
               total_b = r.cb + t * background.z;
    a[0] = loss_term(total_r, tgt[0], norm, &loss);
    a[1] = loss_term(total_g, tgt[1], norm, &loss);
    a[2] = loss_term(total_b, tgt[2], norm, &loss);
    a[3] = loss_term((real)1 - t, tgt[3], norm, &loss);
    a[4] = total_r, a[5] = total_g, a[6] = total_b, a[7] = t;
#else
    const real intensity = background.x * t;
    a[0] = loss_term(intensity, tgt[0], norm, &loss);
    a[1] = a[2] = a[3] = a[5] = a[6] = a[7] = (real)0;
    a[4] = intensity;
#endif
    pixel_loss[pixel] = loss;
    // The march again from its start, as far as the forward march went (its `end`).
    const uint end = su[BU_END];
    for (int k = 0; k <= BS_KTAU; ++k) s[k] = (real)0;
    s[BS_T] = (real)1;
    s[BS_TNEXT] = s[BS_T0];
    su[BU_SAMPLES] = end;
    su[BU_NEXT] = 0u;
    su[BU_FLAGS] = end > 0u && su[BU_N] > 0u ? 0u : IVR_BRICK_DONE;
    return;
  }
  RayMarch m;
  real tb1;
  if (!brick_enter(s, su, brick_lo, brick_hi, origin, &m, &tb1)) return;
  const uint end = su[BU_SAMPLES];
  real transmittance = s[BS_T];
  real pr = s[BS_CR], pg = s[BS_CG], pb = s[BS_CB], kr = s[BS_KR], kg = s[BS_KG], kb = s[BS_KB];
  const real gr = a[0], gg = a[1], gb = a[2], ga = a[3];
  int seg = 0;
  uint i = su[BU_NEXT];
  while (i < end) {
    const real t = sample_t(&m, (int)i);
    if (!(t < tb1)) break;
    const real ux = m.u0x + t * m.dux, uy = m.u0y + t * m.duy, uz = m.u0z + t * m.duz;
    real fx, fy, fz;
    const int ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
              iz = cell_axis(uz, dims.z, &fz);
    const real d = trilinear_at(volume, dims, ux, uy, uz);
    real er, eg, eb, dsigma, der, deg, deb;
    TfPoint point;
    const real sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &seg, &er, &eg, &eb, &dsigma,
                                       &der, &deg, &deb, &point);
    const real dt = m.dt, tau = sigma * dt;
    real fraction;
    const real decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
    const real weight = transmittance * dt * fraction;
    accumulate(&pr, &kr, weight * er);
    accumulate(&pg, &kg, weight * eg);
    accumulate(&pb, &kb, weight * eb);
    const real slope = transmittance * dt * dt * fraction_slope(tau, decay, fraction);
    const real gsigma = gr * (slope * er - dt * (a[4] - pr)) + gg * (slope * eg - dt * (a[5] - pg)) +
                        gb * (slope * eb - dt * (a[6] - pb)) + ga * dt * a[7];
    const real ger = gr * weight, geg = gg * weight, geb = gb * weight;
#else
    const real gsigma = -dt * a[4] * gr;
    const real ger = (real)0, geg = ger, geb = ger;
    (void)gg, (void)gb, (void)ga;
#endif
    transmittance = attenuate(transmittance, tau, fraction, decay);
    const real gd = gsigma * dsigma + ger * der + geg * deg + geb * deb;
    if (gd != (real)0) {
      const int ox = ix + 1 < dims.x ? 1 : 0, oy = iy + 1 < dims.y ? dims.x : 0,
                oz = iz + 1 < dims.z ? dims.x * dims.y : 0;
      const int b = (iz * dims.y + iy) * dims.x + ix;
      const real wx[2] = {(real)1 - fx, fx}, wy[2] = {(real)1 - fy, fy}, wz[2] = {(real)1 - fz, fz};
      for (int c = 0; c < 8; ++c) {
        const real w = wx[c & 1] * wy[(c >> 1) & 1] * wz[c >> 2];
        if (w != (real)0)
          atomic_add_global(grad + b + ((c & 1) ? ox : 0) + ((c & 2) ? oy : 0) + ((c & 4) ? oz : 0),
                            gd * w);
      }
    }
    ++i;
  }
  s[BS_T] = transmittance;
  s[BS_CR] = pr, s[BS_CG] = pg, s[BS_CB] = pb, s[BS_KR] = kr, s[BS_KG] = kg, s[BS_KB] = kb;
  su[BU_NEXT] = i;
  s[BS_TNEXT] = tb1;
  if (i >= end || tb1 >= m.t1) su[BU_FLAGS] |= IVR_BRICK_DONE;
}
