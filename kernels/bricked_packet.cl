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
  // The endpoint schemes' carried end sample, and whether the lane's march has taken sample 0.
  real ad[IVR_RAYS], asigma[IVR_RAYS], aer[IVR_RAYS], aeg[IVR_RAYS], aeb[IVR_RAYS];
  int started[IVR_RAYS];
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (w.entered[l]) {
      __global const real* s = state + w.pixel[l] * IVR_BRICK_REALS;
      ad[l] = s[BS_AD], asigma[l] = s[BS_ASIGMA];
      aer[l] = s[BS_AER], aeg[l] = s[BS_AEG], aeb[l] = s[BS_AEB];
      started[l] = (state_u[w.pixel[l] * IVR_BRICK_UINTS + BU_FLAGS] & IVR_BRICK_STARTED) ? 1 : 0;
    } else {
      ad[l] = asigma[l] = aer[l] = aeg[l] = aeb[l] = (real)0;
      started[l] = 1;
    }
  }
  const March m = lanes_march(&w);
  vint i;
  Radiance r = brick_load_lanes(state, state_u, &w, &i);
  const vreal window_end = IVR_LOAD_RAYS(w.tb1);
  const real threshold = march_threshold(min_transmittance);
  (void)threshold;  // (used where early termination is on)
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
    const vreal ux = IVR_POINT(&m, t, x), uy = IVR_POINT(&m, t, y), uz = IVR_POINT(&m, t, z);
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
  brick_store_lanes(&r, i, min_transmittance, state, state_u, &w);
#if IVR_ENDPOINT_SAMPLES
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (!w.entered[l]) continue;
    __global real* s = state + w.pixel[l] * IVR_BRICK_REALS;
    s[BS_AD] = ad[l], s[BS_ASIGMA] = asigma[l];
    s[BS_AER] = aer[l], s[BS_AEG] = aeg[l], s[BS_AEB] = aeb[l];
    state_u[w.pixel[l] * IVR_BRICK_UINTS + BU_FLAGS] |= IVR_BRICK_STARTED;
  }
#endif
}
