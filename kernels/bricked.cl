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
// BEGIN for independent segments over slabs (lib/brick/domain_segments.cpp): each ray's march
// starts where its window in the planes [brick_lo, brick_hi) starts, from transmittance 1, and ends
// where that window ends (BS_TEND); a ray that misses them is done.
#define IVR_BRICK_SEGMENT_BEGIN 5

// The first sample (midpoint) or segment (endpoint schemes: the one whose far end lies past `ta`)
// of a march whose window starts at `ta`: what the windows before it leave (brick_march's tests).
// The division only guesses; the same comparisons as brick_march's then decide, so the result
// does not depend on how a device rounds it. (exact: its pieces start at ta; the count is 0.)
inline uint window_first(const RayMarch* m, real ta) {
#if IVR_SCHEME == IVR_SCHEME_EXACT
  (void)m, (void)ta;
  return 0u;
#else
  const int n = (int)m->n;
#if IVR_ENDPOINT_SAMPLES
  const int last = max(n - 1, 0);  // the last segment lies in the window that reaches t1
#define IVR_BEFORE(k) ((k) + 1 < n && sample_t(m, (k) + 1) <= ta)
#else
  const int last = n;
#define IVR_BEFORE(k) (sample_t(m, (k)) < ta)
#endif
  const real guess = floor((ta - m->t0) / m->dt);
  int i = (int)clamp(guess, (real)0, (real)last);
  while (i > 0 && !IVR_BEFORE(i - 1)) --i;
  while (i < last && IVR_BEFORE(i)) ++i;
#undef IVR_BEFORE
  return (uint)i;
#endif
}

// Marches the ray's window [tb0, tb1] in this brick (m: the global march, reading the brick's
// voxels from its origin o); true where the ray stopped early.
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
    const real ux = IVR_POINT(m, t, x), uy = IVR_POINT(m, t, y), uz = IVR_POINT(m, t, z);
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
  if (!(su[BU_FLAGS] & IVR_BRICK_STARTED)) {  // the march's first window: sample `next`, 0 but
    // where a worker's segment starts inside the ray (IVR_BRICK_SEGMENT_BEGIN; the brick's halo
    // holds it)
    a = end_sample(volume, dims, m, (int)i, tf, tf_count, tf_scalars, &segment);
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
  if (phase == IVR_BRICK_BEGIN || phase == IVR_BRICK_SEGMENT_BEGIN) {
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
    s[BS_TEND] = m.t1;
    if (phase == IVR_BRICK_SEGMENT_BEGIN && !(su[BU_FLAGS] & IVR_BRICK_DONE)) {
      // (brick_window with the slab's planes: the same expressions as its bricks', so the window
      // starts where the brick that takes the ray first has its window start)
      real ta = m.t0, tb = m.t1;
      brick_window(m.u0x, m.u0y, m.u0z, m.dux, m.duy, m.duz, brick_lo, brick_hi, &ta, &tb);
      if (!(tb > ta)) {
        su[BU_FLAGS] = IVR_BRICK_DONE;
        return;
      }
      s[BS_TNEXT] = ta, s[BS_TEND] = tb;
      su[BU_NEXT] = window_first(&m, ta);
    }
    return;
  }
  real tb1;
  if (!brick_enter(s, su, brick_lo, brick_hi, origin, &m, &tb1)) return;
  Radiance r = brick_load(s, su);
  const bool stopped =
      brick_march(volume, dims, &m, tb1, tf, tf_count, tf_scalars, min_transmittance, &r, s, su);
  brick_store(&r, s, su);
  s[BS_TNEXT] = tb1;
  if (stopped || tb1 >= s[BS_TEND]) su[BU_FLAGS] |= IVR_BRICK_DONE;
}
