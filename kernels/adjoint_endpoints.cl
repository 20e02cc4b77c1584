// adjoint_endpoints.cl — the adjoint march of the integrators that build each segment from its two
// end samples (trapezoid, preintegrated), front to back: each segment's remaining radiance is C
// minus the prefix (no division by 1 − α, no per-sample storage); a sample collects dL/d its
// density from the segments it ends and begins, and is scattered once both are done.
#ifndef IVR_ADJOINT_ENDPOINTS_CL
#define IVR_ADJOINT_ENDPOINTS_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (trapezoid)
#define IVR_SCHEME 1
#endif
#include "adjoint_ray.cl"
#include "compositing.cl"
#include "empty_space.cl"
#include "end_sample.cl"
#include "adjoint_preintegrated.cl"

// One ray, or every ray of a packet (kernels/rays.cl), written once as primal.cl's marches are.

// An end sample with what its scatter needs, and the gradient it has collected so far.
typedef struct {
  EndSample s;
  TfPoint point;  // trapezoid: where its density lies in the TF (the packets' TF gradient)
  vint index;
  vreal t;
  vreal dsigma, der, deg, deb;  // trapezoid: dσ/dd and d(σ·colour)/dd
  vreal gsigma, ger, geg, geb;  // trapezoid: dL/dσ and dL/d(σ·colour) so far
  vreal gd;                     // preintegrated: dL/dd so far
} AdjointSample;

inline AdjointSample adjoint_sample(__global const real* volume, int4 dims, const March* m, vint i,
                                    __global const real* tf, int tf_count, real4 tf_scalars,
                                    vint* cursor) {
  AdjointSample a;
  a.index = i;
  a.t = sample_t(m, i);
  a.gsigma = a.ger = a.geg = a.geb = a.gd = (vreal)(real)0;
  a.dsigma = a.der = a.deg = a.deb = (vreal)(real)0;
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
  // As end_sample(), with the slopes: tf_sample_slope() computes σ and the emission exactly as
  // tf_sample() does, so the march below recovers what the primal march rendered.
  a.s.ux = IVR_POINT(m, a.t, x);
  a.s.uy = IVR_POINT(m, a.t, y);
  a.s.uz = IVR_POINT(m, a.t, z);
  a.s.d = trilinear_at(volume, dims, a.s.ux, a.s.uy, a.s.uz);
  a.s.sigma = tf_sample_slope(a.s.d, tf, tf_count, tf_scalars, cursor, &a.s.er, &a.s.eg, &a.s.eb,
                              &a.dsigma, &a.der, &a.deg, &a.deb, &a.point);
#else
  a.s = end_sample(volume, dims, m, i, tf, tf_count, tf_scalars, cursor);
  a.point.row0 = a.point.row1 = (vint)0;
  a.point.w1 = a.point.cr = a.point.cg = a.point.cb = (vreal)(real)0;
#endif
  return a;
}

// *a = *b for the rays where m is true.
inline void adjoint_sample_where(AdjointSample* a, const AdjointSample* b, vint m) {
#if IVR_RAYS == 1
  if (m) *a = *b;
#else
  end_sample_where(&a->s, &b->s, m);
  a->point.row0 = vseli(a->point.row0, b->point.row0, m);
  a->point.row1 = vseli(a->point.row1, b->point.row1, m);
  a->point.w1 = vsel(a->point.w1, b->point.w1, m);
  a->point.cr = vsel(a->point.cr, b->point.cr, m);
  a->point.cg = vsel(a->point.cg, b->point.cg, m);
  a->point.cb = vsel(a->point.cb, b->point.cb, m);
  a->index = vseli(a->index, b->index, m);
  a->t = vsel(a->t, b->t, m);
  a->dsigma = vsel(a->dsigma, b->dsigma, m), a->der = vsel(a->der, b->der, m);
  a->deg = vsel(a->deg, b->deg, m), a->deb = vsel(a->deb, b->deb, m);
  a->gsigma = vsel(a->gsigma, b->gsigma, m), a->ger = vsel(a->ger, b->ger, m);
  a->geg = vsel(a->geg, b->geg, m), a->geb = vsel(a->geb, b->geb, m);
  a->gd = vsel(a->gd, b->gd, m);
#endif
}

// Sample a is complete (in the rays of `done`): its dL/d density into the voxels (and the
// camera's sums), trapezoid's TF gradient into the work-group's accumulator.
inline void finish_sample(AdjointSample* a, vint done, CellCache* cell, __global const real* volume,
                          int4 dims, real4 inv_voxel, real3 dir, __global const real* tf,
                          int tf_count, real4 tf_scalars, vint* cursor,
                          const ScatterSink grad_volume, TfGradCache* tf_cache, __local real* tf_acc,
                          CameraSums* cs, real* along, real* indexed) {
#if IVR_RAYS == 1
  if (!done) return;
#endif
  vreal fx, fy, fz;
  const vint ix = cell_axis(a->s.ux, dims.x, &fx), iy = cell_axis(a->s.uy, dims.y, &fy),
             iz = cell_axis(a->s.uz, dims.z, &fz);
  cell_enter(cell, ix, iy, iz, volume, dims, grad_volume, done);
  const vreal gd = vsel((vreal)(real)0,
                        a->gd + a->gsigma * a->dsigma + a->ger * a->der + a->geg * a->deg +
                            a->geb * a->deb,
                        done);
  const vreal slide = scatter_sample(cell, gd, a->t, fx, fy, fz, a->s.ux, a->s.uy, a->s.uz, dims,
                                     inv_voxel, dir, cs);
#if IVR_GRAD_CAMERA
  *along += slide;
  *indexed += (real)a->index * slide;
#else
  (void)slide, (void)along, (void)indexed;
#endif
#if IVR_GRAD_TF && IVR_SCHEME == IVR_SCHEME_TRAPEZOID
  tf_scatter_sample(a->s.d, a->s.sigma, &a->point, done, tf, tf_count, tf_scalars, cursor,
                    a->gsigma, a->ger, a->geg, a->geb, tf_cache, tf_acc);
#else
  (void)tf, (void)tf_count, (void)tf_scalars, (void)cursor, (void)tf_cache, (void)tf_acc;
#endif
}

// The segments from at->i on that belong to the window ending at `window_end` (segment_in_window;
// in core: ∞) and lie before the primal march's end, from the prefix in *at; *at is left where the
// march stopped. Each sample collects dL/d its density from the segments it ends and begins and is
// scattered once both are done. A sample on a window's border: in the rays of `carry` (out of
// core, kernels/bricked_adjoint.cl: a ray whose march the next brick goes on with) what it has
// collected is left in *at and the next window, which starts on it, adds its other segment and
// scatters it — the in-core sums exactly; elsewhere (a slab's independent segment) it is scattered
// at the window's end, a part by each window, into the voxels around it that both bricks hold (the
// halo, lib/brick/brick_layout.hpp).
__attribute__((always_inline)) inline void adjoint_march_endpoints_window(
    __global const real* volume, int4 dims, const March* m, Ray ray, real4 inv_voxel,
    __global const real* tf, int tf_count, real4 tf_scalars, const AdjointRay* ar,
    __global const uchar* occupied, int4 bricks, const ScatterSink grad_volume,
    TfGradCache* tf_cache, __local real* tf_acc, CameraSums* cs, vreal window_end, vint carry,
    AdjointPrefix* at) {
  vreal transmittance = at->transmittance;
  // The emission prefix, summed exactly as the primal march summed C.
  vreal pr = at->pr, pg = at->pg, pb = at->pb, kr = at->kr, kg = at->kg, kb = at->kb;
  vint seg_value = (vint)0, seg_scatter = (vint)0;
  CellCache cell;
  cell_init(&cell, grad_volume, at->flushed);
  real along = 0, indexed = 0, direct = 0;  // camera (one ray): fixed_step_ends()
  const vreal dt = m->dt;
  const vint end = ar->end;
  vint i = at->i;
  vint live = i < end;
  AdjointSample a = adjoint_sample(volume, dims, m, i, tf, tf_count, tf_scalars, &seg_value);
  // (what the window before collected for it: 0 where none did)
  a.gsigma = at->gsigma, a.ger = at->ger, a.geg = at->geg, a.geb = at->geb, a.gd = at->gd;
  vint open = live;  // a still waits for its scatter
  while (vany(live)) {
    live = live && segment_in_window(m, i, window_end);
    if (!vany(live)) break;
#if IVR_EMPTY_SPACE
    {
      const vint k = endpoint_skip(i, end, a.s.ux, a.s.uy, a.s.uz, m, dims, occupied, bricks, live);
      const vint moved = live && (k > i);
      if (vany(moved)) {  // the segments in between add nothing, nor does their gradient
        finish_sample(&a, moved, &cell, volume, dims, inv_voxel, ray.dir, tf, tf_count, tf_scalars,
                      &seg_scatter, grad_volume, tf_cache, tf_acc, cs, &along, &indexed);
        open = open && !moved;
        i = vseli(i, k, moved);
        live = live && (i < end);
        if (!vany(live)) break;
        const vint again = moved && live;
        const AdjointSample n = adjoint_sample(volume, dims, m, i, tf, tf_count, tf_scalars,
                                               &seg_value);
        adjoint_sample_where(&a, &n, again);
        open = open || again;
      }
    }
#else
    (void)occupied, (void)bricks;
#endif
    const vint take = IVR_RAYS == 1 ? vtrue : live;
    AdjointSample b = adjoint_sample(volume, dims, m, i + 1, tf, tf_count, tf_scalars, &seg_value);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    // τ = dt (σa + σb)/2, emission dt·fraction(τ)·(Ea + Eb)/2: as the primal's composite().
    const vreal tau = (real)0.5 * (a.s.sigma + b.s.sigma) * dt;
    vreal fraction;
    const vreal decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
    const vreal er = (real)0.5 * (a.s.er + b.s.er), eg = (real)0.5 * (a.s.eg + b.s.eg),
                eb = (real)0.5 * (a.s.eb + b.s.eb);
    const vreal weight = transmittance * dt * fraction;
    accumulate_where(&pr, &kr, weight * er, take);
    accumulate_where(&pg, &kg, weight * eg, take);
    accumulate_where(&pb, &kb, weight * eb, take);
    const vreal slope = transmittance * dt * fraction_slope(tau, decay, fraction);  // dweight/dτ
    const vreal gtau = ar->gr * (slope * er - (ar->total_r - pr)) +
                       ar->gg * (slope * eg - (ar->total_g - pg)) +
                       ar->gb * (slope * eb - (ar->total_b - pb)) + ar->ga * ar->t_end;
    const vreal ger = ar->gr * weight, geg = ar->gg * weight, geb = ar->gb * weight;
#if IVR_GRAD_CAMERA
    direct += gtau * tau + ger * er + geg * eg + geb * eb;
#endif
    // (a's sums only in the rays that take the segment: a finished ray's a waits for its scatter.)
    // (Selected whole, so that each add contracts as the one-ray kernel's does.)
    a.ger = vsel(a.ger, a.ger + (real)0.5 * ger, take);
    a.geg = vsel(a.geg, a.geg + (real)0.5 * geg, take);
    a.geb = vsel(a.geb, a.geb + (real)0.5 * geb, take);
    b.ger += (real)0.5 * ger, b.geg += (real)0.5 * geg, b.geb += (real)0.5 * geb;
#else
    const vreal gtau = -ar->intensity * ar->gi;
#if IVR_GRAD_CAMERA
    direct += gtau * tau;
#endif
    (void)pr, (void)pg, (void)pb, (void)kr, (void)kg, (void)kb;
#endif
    transmittance = vsel(transmittance, attenuate(transmittance, tau, fraction, decay), take);
    a.gsigma = vsel(a.gsigma, a.gsigma + (real)0.5 * dt * gtau, take);
    b.gsigma += (real)0.5 * dt * gtau;
#else
    preintegrated_segment_adjoint(&a.s, &b.s, dt, tf, tf_count, tf_scalars, ar, take,
                                  &transmittance, &pr, &pg, &pb, &kr, &kg, &kb, &a.gd, &b.gd,
                                  &direct, &seg_value, tf_cache, tf_acc);
#endif
    finish_sample(&a, take, &cell, volume, dims, inv_voxel, ray.dir, tf, tf_count, tf_scalars,
                  &seg_scatter, grad_volume, tf_cache, tf_acc, cs, &along, &indexed);
    adjoint_sample_where(&a, &b, take);
    open = vseli(open, vtrue, take);
    i += vcount(take);
    live = live && (i < end);
  }
  // (A ray that has segments left goes on with this sample in the next window.)
  const vint kept = open && carry && (i < end);
  finish_sample(&a, open && !kept, &cell, volume, dims, inv_voxel, ray.dir, tf, tf_count,
                tf_scalars, &seg_scatter, grad_volume, tf_cache, tf_acc, cs, &along, &indexed);
  const vreal none = (vreal)(real)0;
  at->gsigma = vsel(none, a.gsigma, kept), at->ger = vsel(none, a.ger, kept);
  at->geg = vsel(none, a.geg, kept), at->geb = vsel(none, a.geb, kept);
  at->gd = vsel(none, a.gd, kept);
  at->flushed = cell_flush(&cell, grad_volume);
#if IVR_GRAD_CAMERA
  fixed_step_ends(cs, m, along, indexed, direct);
#else
  (void)direct;
#endif
  at->transmittance = transmittance;
  at->pr = pr, at->pg = pg, at->pb = pb, at->kr = kr, at->kg = kg, at->kb = kb;
  at->i = i;
}

// The whole ray's adjoint march (in core).
__attribute__((always_inline)) inline void adjoint_march_endpoints(
    __global const real* volume, int4 dims, const March* m, Ray ray, real4 inv_voxel,
    __global const real* tf, int tf_count, real4 tf_scalars, const AdjointRay* ar,
    __global const uchar* occupied, int4 bricks, const ScatterSink grad_volume,
    TfGradCache* tf_cache, __local real* tf_acc, CameraSums* cs) {
  AdjointPrefix at = adjoint_prefix_begin();
  adjoint_march_endpoints_window(volume, dims, m, ray, inv_voxel, tf, tf_count, tf_scalars, ar,
                                 occupied, bricks, grad_volume, tf_cache, tf_acc, cs,
                                 (vreal)(real)INFINITY, (vint)0, &at);
  adjoint_ray_end(grad_volume, at.flushed);
}

#endif
