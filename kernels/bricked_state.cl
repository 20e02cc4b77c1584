// bricked_state.cl — the out-of-core march's per-ray state (kernels/bricked.cl, bricked_packet.cl):
// its layout, and how a brick takes a ray from it.
#ifndef IVR_BRICKED_STATE_CL
#define IVR_BRICKED_STATE_CL
#include "brick_window.cl"
#include "config.cl"
#include "march.cl"
#include "primal.cl"
#include "rays.cl"

// The per-ray state: reals, then uints.
#define IVR_BRICK_REALS 25
#define IVR_BRICK_UINTS 5
// reals: the Radiance sums, the carried end sample (trapezoid, preintegrated), where the march
// stands
#define BS_T 0
#define BS_CR 1
#define BS_CG 2
#define BS_CB 3
#define BS_KR 4
#define BS_KG 5
#define BS_KB 6
#define BS_TAU 7
#define BS_KTAU 8
#define BS_AD 9
#define BS_ASIGMA 10
#define BS_AER 11
#define BS_AEG 12
#define BS_AEB 13
#define BS_TNEXT 14
// the ray's global march, from BEGIN (march_begin: its sample count costs correctly rounded
// divisions, once per ray rather than once per brick)
#define BS_T0 15
#define BS_T1 16
#define BS_DT 17
#define BS_U0 18  // u0x, u0y, u0z, dux, duy, duz
// Where this march ends the ray: its end t1, or (independent segments over slabs,
// IVR_BRICK_SEGMENT_BEGIN) the end of its window in this worker's slab; the ray is done there.
#define BS_TEND 24
// uints
#define BU_SAMPLES 0
#define BU_END 1
#define BU_NEXT 2  // the next sample (midpoint) or segment (endpoint schemes)
#define BU_FLAGS 3
#define BU_N 4
#define IVR_BRICK_DONE 1u
#define IVR_BRICK_STARTED 2u  // the endpoint schemes' sample 0 is taken

// What a brick's march subtracts from its points (IVR_POINT) and the origin of the exact scheme's
// grid (kernels/exact.cl): its first voxel.
inline real4 point_origin(int4 origin) {
  return (real4)((real)origin.x, (real)origin.y, (real)origin.z, (real)0);
}

// The ray's global march from its state, moved to the brick's voxels, and the end *tb1 of its
// window in the brick; false where the ray is done, misses the brick, or its march does not stand
// at the window's start (met out of order: a later sweep takes it).
inline bool brick_enter(__global const real* s, __global const uint* su, real4 brick_lo,
                        real4 brick_hi, int4 origin, RayMarch* m, real* tb1) {
  if (su[BU_FLAGS] & IVR_BRICK_DONE) return false;
  m->t0 = s[BS_T0], m->t1 = s[BS_T1], m->dt = s[BS_DT], m->n = su[BU_N];
  m->u0x = s[BS_U0 + 0], m->u0y = s[BS_U0 + 1], m->u0z = s[BS_U0 + 2];
  m->dux = s[BS_U0 + 3], m->duy = s[BS_U0 + 4], m->duz = s[BS_U0 + 5];
  real tb0 = m->t0;
  *tb1 = m->t1;
  brick_window(m->u0x, m->u0y, m->u0z, m->dux, m->duy, m->duz, brick_lo, brick_hi, &tb0, tb1);
  if (!(*tb1 > tb0) || tb0 != s[BS_TNEXT]) return false;
  const real4 o = point_origin(origin);
  m->ox = o.x, m->oy = o.y, m->oz = o.z;
  return true;
}

// The tile with corner (x0, y0) of `view` (one pixel, or a packet's: kernels/rays.cl), lane by
// lane: each lane's pixel, whether its ray enters this brick where its march stands (brick_enter)
// and, where it does, its global march and its window's start and end. A lane that does not (or lies past
// the image's edge) holds zeros: n = 0, it marches nothing and writes nothing.
typedef struct {
  real t0[IVR_RAYS], t1[IVR_RAYS], dt[IVR_RAYS], tb0[IVR_RAYS], tb1[IVR_RAYS], tend[IVR_RAYS];
  real u0x[IVR_RAYS], u0y[IVR_RAYS], u0z[IVR_RAYS], dux[IVR_RAYS], duy[IVR_RAYS], duz[IVR_RAYS];
  int n[IVR_RAYS], entered[IVR_RAYS];
  size_t pixel[IVR_RAYS];
  real ox, oy, oz;  // (brick_enter's: the brick's, every lane the same)
} LaneWindows;

// Fills *w; true where some lane enters.
inline bool brick_enter_lanes(__global const real* state, __global const uint* state_u, int x0,
                              int y0, int view, int width, int height, real4 brick_lo,
                              real4 brick_hi, int4 origin, LaneWindows* w) {
  bool any = false;
  const real4 o = point_origin(origin);
  w->ox = o.x, w->oy = o.y, w->oz = o.z;
  for (int l = 0; l < IVR_RAYS; ++l) {
    const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
    RayMarch m;
    real b1 = (real)0;
    w->entered[l] = 0;
    w->pixel[l] = 0;
    if (x < width && y < height) {
      const size_t pixel = ((size_t)view * height + y) * width + x;
      w->pixel[l] = pixel;
      if (brick_enter(state + pixel * IVR_BRICK_REALS, state_u + pixel * IVR_BRICK_UINTS,
                      brick_lo, brick_hi, origin, &m, &b1)) {
        w->entered[l] = 1;
        w->t0[l] = m.t0, w->t1[l] = m.t1, w->dt[l] = m.dt, w->tb1[l] = b1, w->n[l] = (int)m.n;
        w->tb0[l] = state[pixel * IVR_BRICK_REALS + BS_TNEXT];  // (where the window starts)
        w->tend[l] = state[pixel * IVR_BRICK_REALS + BS_TEND];
        w->u0x[l] = m.u0x, w->u0y[l] = m.u0y, w->u0z[l] = m.u0z;
        w->dux[l] = m.dux, w->duy[l] = m.duy, w->duz[l] = m.duz;
        any = true;
        continue;
      }
    }
    w->t0[l] = w->t1[l] = w->dt[l] = w->tb0[l] = w->tb1[l] = w->tend[l] = (real)0;
    w->u0x[l] = w->u0y[l] = w->u0z[l] = w->dux[l] = w->duy[l] = w->duz[l] = (real)0;
    w->n[l] = 0;
  }
  return any;
}

// The lanes' global marches as one March (a packet's: vectors).
inline March lanes_march(const LaneWindows* w) {
  March m;
  m.t0 = IVR_LOAD_RAYS(w->t0), m.t1 = IVR_LOAD_RAYS(w->t1), m.dt = IVR_LOAD_RAYS(w->dt);
  m.n = IVR_LOAD_RAYS(w->n);
  m.u0x = IVR_LOAD_RAYS(w->u0x), m.u0y = IVR_LOAD_RAYS(w->u0y), m.u0z = IVR_LOAD_RAYS(w->u0z);
  m.dux = IVR_LOAD_RAYS(w->dux), m.duy = IVR_LOAD_RAYS(w->duy), m.duz = IVR_LOAD_RAYS(w->duz);
  m.ox = w->ox, m.oy = w->oy, m.oz = w->oz;
  return m;
}

// The packet kernels' (bricked_packet.cl, bricked_tangent.cl): the lanes' radiance sums and sample
// counters from their states — a lane that does not enter an empty march (T = 1) — and in *next
// the sample each lane's march goes on from.
inline Radiance brick_load_lanes(__global const real* state, __global const uint* state_u,
                                 const LaneWindows* w, vint* next) {
  real T[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS], kr[IVR_RAYS], kg[IVR_RAYS],
      kb[IVR_RAYS], tau[IVR_RAYS], ktau[IVR_RAYS];
  int at[IVR_RAYS], taken[IVR_RAYS], end[IVR_RAYS];
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (w->entered[l]) {
      __global const real* s = state + w->pixel[l] * IVR_BRICK_REALS;
      __global const uint* su = state_u + w->pixel[l] * IVR_BRICK_UINTS;
      T[l] = s[BS_T], cr[l] = s[BS_CR], cg[l] = s[BS_CG], cb[l] = s[BS_CB];
      kr[l] = s[BS_KR], kg[l] = s[BS_KG], kb[l] = s[BS_KB], tau[l] = s[BS_TAU],
      ktau[l] = s[BS_KTAU];
      at[l] = (int)su[BU_NEXT], taken[l] = (int)su[BU_SAMPLES], end[l] = (int)su[BU_END];
    } else {
      T[l] = (real)1;
      cr[l] = cg[l] = cb[l] = kr[l] = kg[l] = kb[l] = tau[l] = ktau[l] = (real)0;
      at[l] = taken[l] = end[l] = 0;
    }
  }
  Radiance r;
  r.transmittance = IVR_LOAD_RAYS(T);
  r.cr = IVR_LOAD_RAYS(cr), r.cg = IVR_LOAD_RAYS(cg), r.cb = IVR_LOAD_RAYS(cb);
  r.kr = IVR_LOAD_RAYS(kr), r.kg = IVR_LOAD_RAYS(kg), r.kb = IVR_LOAD_RAYS(kb);
  r.tau = IVR_LOAD_RAYS(tau), r.ktau = IVR_LOAD_RAYS(ktau);
  r.samples = IVR_LOAD_RAYS(taken), r.end = IVR_LOAD_RAYS(end);
  *next = IVR_LOAD_RAYS(at);
  return r;
}

// Back into the states of the lanes that entered: the sums, the counters, the next sample, and
// where the next brick's window starts (this one's end); a lane whose march stopped early or
// reached its end is done.
inline void brick_store_lanes(const Radiance* r, vint next, real min_transmittance,
                              __global real* state, __global uint* state_u, const LaneWindows* w) {
  real T[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS], kr[IVR_RAYS], kg[IVR_RAYS],
      kb[IVR_RAYS], tau[IVR_RAYS], ktau[IVR_RAYS];
  int at[IVR_RAYS], taken[IVR_RAYS], end[IVR_RAYS];
#if IVR_EARLY_TERMINATION
  int stopped[IVR_RAYS];
  IVR_STORE_RAYS(march_stopped(r, march_threshold(min_transmittance)), stopped);
#else
  (void)min_transmittance;
#endif
  IVR_STORE_RAYS(r->transmittance, T);
  IVR_STORE_RAYS(r->cr, cr);
  IVR_STORE_RAYS(r->cg, cg);
  IVR_STORE_RAYS(r->cb, cb);
  IVR_STORE_RAYS(r->kr, kr);
  IVR_STORE_RAYS(r->kg, kg);
  IVR_STORE_RAYS(r->kb, kb);
  IVR_STORE_RAYS(r->tau, tau);
  IVR_STORE_RAYS(r->ktau, ktau);
  IVR_STORE_RAYS(r->samples, taken);
  IVR_STORE_RAYS(r->end, end);
  IVR_STORE_RAYS(next, at);
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (!w->entered[l]) continue;
    __global real* s = state + w->pixel[l] * IVR_BRICK_REALS;
    __global uint* su = state_u + w->pixel[l] * IVR_BRICK_UINTS;
    s[BS_T] = T[l];
    s[BS_CR] = cr[l], s[BS_CG] = cg[l], s[BS_CB] = cb[l];
    s[BS_KR] = kr[l], s[BS_KG] = kg[l], s[BS_KB] = kb[l];
    s[BS_TAU] = tau[l], s[BS_KTAU] = ktau[l];
    su[BU_SAMPLES] = (uint)taken[l];
    su[BU_END] = (uint)end[l];
    su[BU_NEXT] = (uint)at[l];
    s[BS_TNEXT] = w->tb1[l];
#if IVR_EARLY_TERMINATION
    if (stopped[l] || w->tb1[l] >= w->tend[l]) su[BU_FLAGS] |= IVR_BRICK_DONE;
#else
    if (w->tb1[l] >= w->tend[l]) su[BU_FLAGS] |= IVR_BRICK_DONE;
#endif
  }
}

// One ray's Radiance sums from its state, and back (the one-ray kernels').
#if IVR_RAYS == 1
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
#endif

#endif
