// bricked_packet.cl — the out-of-core render's march on CPUs: kernels/bricked.cl's MARCH phase
// (midpoint, trapezoid and preintegrated schemes) for a tile of IVR_RAYS neighbouring pixels in
// vector lanes, as render.cl marches packets in core (PoCL runs a work-item's loop as scalar code).
// Each lane takes its ray's window in the brick exactly as bricked_render does — the same state,
// entry test, samples (the endpoint schemes' carried end sample) and sums, lane by lane — so the
// state it leaves, and the image, are the one-ray kernel's bit for bit.
// BEGIN and FINISH stay bricked_render's (one ray per work-item: once per render or sweep).
#include "bricked_state.cl"
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "primal.cl"
#include "rays.cl"

#if IVR_SCHEME == IVR_SCHEME_EXACT
#error "bricked_packet.cl marches the fixed-step schemes (exact: bricked.cl, one ray a work-item)"
#endif

// The arguments are bricked_render's (the host sets both alike); a work-item is the tile with
// corner (IVR_PACKET_W · x, IVR_PACKET_H · y) of view z.
__kernel void bricked_render_packet(
    __global const real* restrict volume, const int4 dims, const real4 box_min,
    const real4 box_max, const real4 inv_voxel, __global const real* restrict cameras,
    const int width, const int height, __global const real* restrict tf, const int tf_count,
    const real4 tf_scalars, const real4 background, const real step, const real min_transmittance,
    const int phase, const real4 brick_lo, const real4 brick_hi, const int4 origin,
    __global real* restrict state, __global uint* restrict state_u, __global real* restrict image,
    __global uint* restrict samples, __global uint* restrict pending) {
  (void)box_min, (void)box_max, (void)inv_voxel, (void)cameras, (void)background, (void)step;
  (void)phase, (void)image, (void)samples, (void)pending;
  const int x0 = get_global_id(0) * IVR_PACKET_W, y0 = get_global_id(1) * IVR_PACKET_H;
  const int view = get_global_id(2);
  if (x0 >= width || y0 >= height) return;

  // Each lane's ray from its state (bricked_state.cl); lanes that do not enter march nothing.
  LaneWindows w;
  if (!brick_enter_lanes(state, state_u, x0, y0, view, width, height, brick_lo, brick_hi, origin,
                         &w))
    return;
  real T[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS], kr[IVR_RAYS], kg[IVR_RAYS],
      kb[IVR_RAYS], tau[IVR_RAYS], ktau[IVR_RAYS];
  int next[IVR_RAYS], taken[IVR_RAYS], end[IVR_RAYS];
  // The endpoint schemes' carried end sample, and whether the lane's march has taken sample 0.
  real ad[IVR_RAYS], asigma[IVR_RAYS], aer[IVR_RAYS], aeg[IVR_RAYS], aeb[IVR_RAYS];
  int started[IVR_RAYS];
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (w.entered[l]) {
      __global const real* s = state + w.pixel[l] * IVR_BRICK_REALS;
      __global const uint* su = state_u + w.pixel[l] * IVR_BRICK_UINTS;
      T[l] = s[BS_T], cr[l] = s[BS_CR], cg[l] = s[BS_CG], cb[l] = s[BS_CB];
      kr[l] = s[BS_KR], kg[l] = s[BS_KG], kb[l] = s[BS_KB], tau[l] = s[BS_TAU],
      ktau[l] = s[BS_KTAU];
      next[l] = (int)su[BU_NEXT], taken[l] = (int)su[BU_SAMPLES], end[l] = (int)su[BU_END];
      ad[l] = s[BS_AD], asigma[l] = s[BS_ASIGMA];
      aer[l] = s[BS_AER], aeg[l] = s[BS_AEG], aeb[l] = s[BS_AEB];
      started[l] = (su[BU_FLAGS] & IVR_BRICK_STARTED) ? 1 : 0;
    } else {
      T[l] = (real)1;
      cr[l] = cg[l] = cb[l] = kr[l] = kg[l] = kb[l] = tau[l] = ktau[l] = (real)0;
      next[l] = taken[l] = end[l] = 0;
      ad[l] = asigma[l] = aer[l] = aeg[l] = aeb[l] = (real)0;
      started[l] = 1;
    }
  }
  const March m = lanes_march(&w);
  Radiance r;
  r.transmittance = IVR_LOAD_RAYS(T);
  r.cr = IVR_LOAD_RAYS(cr), r.cg = IVR_LOAD_RAYS(cg), r.cb = IVR_LOAD_RAYS(cb);
  r.kr = IVR_LOAD_RAYS(kr), r.kg = IVR_LOAD_RAYS(kg), r.kb = IVR_LOAD_RAYS(kb);
  r.tau = IVR_LOAD_RAYS(tau), r.ktau = IVR_LOAD_RAYS(ktau);
  r.samples = IVR_LOAD_RAYS(taken), r.end = IVR_LOAD_RAYS(end);
  const vreal window_end = IVR_LOAD_RAYS(w.tb1);
  vint i = IVR_LOAD_RAYS(next);
  const real threshold = march_threshold(min_transmittance);
  vint segment = (vint)0;  // the TF's search cursor (tf_sample)
  const vint entered = IVR_LOAD_RAYS(w.entered) != (vint)0;
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
  // bricked.cl's brick_march, lane by lane: sample i while it lies before the window's end and
  // the march has neither ended nor stopped early.
  vint live = entered && (i < m.n);
  while (vany(live)) {
    const vreal t = sample_t(&m, i);
    live = live && vmask_of(t < window_end);
    if (!vany(live)) break;
    const vreal ux = m.u0x + t * m.dux, uy = m.u0y + t * m.duy, uz = m.u0z + t * m.duz;
    const vreal d = trilinear_at(volume, dims, ux, uy, uz);
    vreal er, eg, eb;
    const vreal sigma = tf_sample(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb);
    composite_where(&r, sigma * m.dt, m.dt, er, eg, eb, live);
    r.samples += vcount(live);
    i += vcount(live);
    r.end = vseli(r.end, i, live);
    live = live && (i < m.n);
#if IVR_EARLY_TERMINATION
    live = live && !march_stopped(&r, threshold);
#endif
  }
#else
  // bricked.cl's brick_march for the endpoint schemes, lane by lane: the segments whose far end
  // lies in the window (segment_in_window), from the carried end sample (sample `next` where the
  // lane's march starts here).
  EndSample a;
  a.ux = a.uy = a.uz = (vreal)(real)0;
  a.d = IVR_LOAD_RAYS(ad), a.sigma = IVR_LOAD_RAYS(asigma);
  a.er = IVR_LOAD_RAYS(aer), a.eg = IVR_LOAD_RAYS(aeg), a.eb = IVR_LOAD_RAYS(aeb);
  const vint fresh = entered && (IVR_LOAD_RAYS(started) == (vint)0);
  if (vany(fresh)) {
    // (sample `next`: 0, or a segment's start in a worker's slab — IVR_BRICK_SEGMENT_BEGIN)
    const EndSample first = end_sample(volume, dims, &m, i, tf, tf_count, tf_scalars, &segment);
    end_sample_where(&a, &first, fresh);
    r.samples += vcount(fresh);
  }
  vint live = entered && (i < m.n);
  while (vany(live)) {
    live = live && segment_in_window(&m, i, window_end);
    if (!vany(live)) break;
    const EndSample b = end_sample(volume, dims, &m, i + 1, tf, tf_count, tf_scalars, &segment);
    r.samples += vcount(live);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    composite_where(&r, (real)0.5 * (a.sigma + b.sigma) * m.dt, m.dt, (real)0.5 * (a.er + b.er),
                    (real)0.5 * (a.eg + b.eg), (real)0.5 * (a.eb + b.eb), live);
#else
    Attenuation at;
    vreal er, eg, eb;
    preintegrated_segment(&a, &b, m.dt, tf, tf_count, tf_scalars, &segment, live, &at, &er, &eg,
                          &eb);
#if IVR_EMISSION
    radiance_emit_where(&r, r.transmittance, er, eg, eb, attenuation_apply(&at, r.transmittance),
                        live);
#else
    accumulate_where(&r.tau, &r.ktau, at.tau, live);
#endif
#endif
    end_sample_where(&a, &b, live);
    i += vcount(live);
    r.end = vseli(r.end, i, live);
    live = live && (i < m.n);
#if IVR_EARLY_TERMINATION
    live = live && !march_stopped(&r, threshold);
#endif
  }
  IVR_STORE_RAYS(a.d, ad);
  IVR_STORE_RAYS(a.sigma, asigma);
  IVR_STORE_RAYS(a.er, aer);
  IVR_STORE_RAYS(a.eg, aeg);
  IVR_STORE_RAYS(a.eb, aeb);
#endif
#if IVR_EARLY_TERMINATION
  int stopped[IVR_RAYS];
  IVR_STORE_RAYS(march_stopped(&r, threshold), stopped);
#else
  (void)threshold;
#endif
  IVR_STORE_RAYS(r.transmittance, T);
  IVR_STORE_RAYS(r.cr, cr);
  IVR_STORE_RAYS(r.cg, cg);
  IVR_STORE_RAYS(r.cb, cb);
  IVR_STORE_RAYS(r.kr, kr);
  IVR_STORE_RAYS(r.kg, kg);
  IVR_STORE_RAYS(r.kb, kb);
  IVR_STORE_RAYS(r.tau, tau);
  IVR_STORE_RAYS(r.ktau, ktau);
  IVR_STORE_RAYS(r.samples, taken);
  IVR_STORE_RAYS(r.end, end);
  IVR_STORE_RAYS(i, next);
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (!w.entered[l]) continue;
    __global real* s = state + w.pixel[l] * IVR_BRICK_REALS;
    __global uint* su = state_u + w.pixel[l] * IVR_BRICK_UINTS;
    s[BS_T] = T[l];
    s[BS_CR] = cr[l], s[BS_CG] = cg[l], s[BS_CB] = cb[l];
    s[BS_KR] = kr[l], s[BS_KG] = kg[l], s[BS_KB] = kb[l];
    s[BS_TAU] = tau[l], s[BS_KTAU] = ktau[l];
    su[BU_SAMPLES] = (uint)taken[l];
    su[BU_END] = (uint)end[l];
    su[BU_NEXT] = (uint)next[l];
    s[BS_TNEXT] = w.tb1[l];
#if IVR_ENDPOINT_SAMPLES
    s[BS_AD] = ad[l], s[BS_ASIGMA] = asigma[l];
    s[BS_AER] = aer[l], s[BS_AEG] = aeg[l], s[BS_AEB] = aeb[l];
    su[BU_FLAGS] |= IVR_BRICK_STARTED;
#endif
#if IVR_EARLY_TERMINATION
    if (stopped[l] || w.tb1[l] >= w.tend[l]) su[BU_FLAGS] |= IVR_BRICK_DONE;
#else
    if (w.tb1[l] >= w.tend[l]) su[BU_FLAGS] |= IVR_BRICK_DONE;
#endif
  }
}
