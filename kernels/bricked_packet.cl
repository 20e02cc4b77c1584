// bricked_packet.cl — the out-of-core render's march on CPUs: kernels/bricked.cl's MARCH phase
// (midpoint scheme) for a tile of IVR_RAYS neighbouring pixels in vector lanes, as render.cl
// marches packets in core (PoCL runs a work-item's loop as scalar code). Each lane takes its ray's
// window in the brick exactly as bricked_render does — the same state, entry test, samples and
// sums, lane by lane — so the state it leaves, and the image, are the one-ray kernel's bit for bit.
// BEGIN and FINISH stay bricked_render's (one ray per work-item: once per render or sweep).
#include "bricked_state.cl"
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "primal.cl"
#include "rays.cl"

#if IVR_SCHEME != IVR_SCHEME_MIDPOINT
#error "bricked_packet.cl marches the midpoint scheme"
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

  // Each lane's ray from its state (bricked_state.cl's brick_enter); lanes that do not enter
  // march nothing (n = 0) and write nothing.
  real t0[IVR_RAYS], t1[IVR_RAYS], dt[IVR_RAYS], tb1[IVR_RAYS];
  real u0x[IVR_RAYS], u0y[IVR_RAYS], u0z[IVR_RAYS], dux[IVR_RAYS], duy[IVR_RAYS], duz[IVR_RAYS];
  real T[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS], kr[IVR_RAYS], kg[IVR_RAYS],
      kb[IVR_RAYS], tau[IVR_RAYS], ktau[IVR_RAYS];
  int n[IVR_RAYS], next[IVR_RAYS], taken[IVR_RAYS], end[IVR_RAYS], entered[IVR_RAYS];
  int any = 0;
  for (int l = 0; l < IVR_RAYS; ++l) {
    const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
    RayMarch m;
    real b1 = (real)0;
    entered[l] = 0;
    if (x < width && y < height) {
      const size_t pixel = ((size_t)view * height + y) * width + x;
      __global const real* s = state + pixel * IVR_BRICK_REALS;
      __global const uint* su = state_u + pixel * IVR_BRICK_UINTS;
      if (brick_enter(s, su, brick_lo, brick_hi, origin, &m, &b1)) {
        entered[l] = -1;
        t0[l] = m.t0, t1[l] = m.t1, dt[l] = m.dt, tb1[l] = b1, n[l] = (int)m.n;
        u0x[l] = m.u0x, u0y[l] = m.u0y, u0z[l] = m.u0z, dux[l] = m.dux, duy[l] = m.duy,
        duz[l] = m.duz;
        T[l] = s[BS_T], cr[l] = s[BS_CR], cg[l] = s[BS_CG], cb[l] = s[BS_CB];
        kr[l] = s[BS_KR], kg[l] = s[BS_KG], kb[l] = s[BS_KB], tau[l] = s[BS_TAU],
        ktau[l] = s[BS_KTAU];
        next[l] = (int)su[BU_NEXT], taken[l] = (int)su[BU_SAMPLES], end[l] = (int)su[BU_END];
        any = 1;
        continue;
      }
    }
    t0[l] = t1[l] = dt[l] = tb1[l] = u0x[l] = u0y[l] = u0z[l] = dux[l] = duy[l] = duz[l] = (real)0;
    T[l] = (real)1;
    cr[l] = cg[l] = cb[l] = kr[l] = kg[l] = kb[l] = tau[l] = ktau[l] = (real)0;
    n[l] = next[l] = taken[l] = end[l] = 0;
  }
  if (!any) return;

  March m;
  m.t0 = IVR_LOAD_RAYS(t0), m.t1 = IVR_LOAD_RAYS(t1), m.dt = IVR_LOAD_RAYS(dt);
  m.n = IVR_LOAD_RAYS(n);
  m.u0x = IVR_LOAD_RAYS(u0x), m.u0y = IVR_LOAD_RAYS(u0y), m.u0z = IVR_LOAD_RAYS(u0z);
  m.dux = IVR_LOAD_RAYS(dux), m.duy = IVR_LOAD_RAYS(duy), m.duz = IVR_LOAD_RAYS(duz);
  Radiance r;
  r.transmittance = IVR_LOAD_RAYS(T);
  r.cr = IVR_LOAD_RAYS(cr), r.cg = IVR_LOAD_RAYS(cg), r.cb = IVR_LOAD_RAYS(cb);
  r.kr = IVR_LOAD_RAYS(kr), r.kg = IVR_LOAD_RAYS(kg), r.kb = IVR_LOAD_RAYS(kb);
  r.tau = IVR_LOAD_RAYS(tau), r.ktau = IVR_LOAD_RAYS(ktau);
  r.samples = IVR_LOAD_RAYS(taken), r.end = IVR_LOAD_RAYS(end);
  const vreal window_end = IVR_LOAD_RAYS(tb1);
  vint i = IVR_LOAD_RAYS(next);
  const real threshold = march_threshold(min_transmittance);
  vint segment = (vint)0;  // the TF's search cursor (tf_sample)
  // bricked.cl's brick_march, lane by lane: sample i while it lies before the window's end and
  // the march has neither ended nor stopped early.
  vint live = (IVR_LOAD_RAYS(entered) != (vint)0) && (i < m.n);
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
    if (!entered[l]) continue;
    const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
    const size_t pixel = ((size_t)view * height + y) * width + x;
    __global real* s = state + pixel * IVR_BRICK_REALS;
    __global uint* su = state_u + pixel * IVR_BRICK_UINTS;
    s[BS_T] = T[l];
    s[BS_CR] = cr[l], s[BS_CG] = cg[l], s[BS_CB] = cb[l];
    s[BS_KR] = kr[l], s[BS_KG] = kg[l], s[BS_KB] = kb[l];
    s[BS_TAU] = tau[l], s[BS_KTAU] = ktau[l];
    su[BU_SAMPLES] = (uint)taken[l];
    su[BU_END] = (uint)end[l];
    su[BU_NEXT] = (uint)next[l];
    s[BS_TNEXT] = tb1[l];
#if IVR_EARLY_TERMINATION
    if (stopped[l] || tb1[l] >= t1[l]) su[BU_FLAGS] |= IVR_BRICK_DONE;
#else
    if (tb1[l] >= t1[l]) su[BU_FLAGS] |= IVR_BRICK_DONE;
#endif
  }
}
