// adjoint_midpoint.cl — the adjoint march of the midpoint rule, front to back: each sample's
// remaining radiance is C minus the prefix (docs/design.md: no division by 1 − α, no per-sample
// storage); dL/d density goes to the voxels, dL/d TF to the work-group's accumulator.
#ifndef IVR_ADJOINT_MIDPOINT_CL
#define IVR_ADJOINT_MIDPOINT_CL
#include "adjoint_ray.cl"
#include "compositing.cl"
#include "empty_space.cl"
#include "rays.cl"

// One ray, or every ray of a packet (kernels/rays.cl) written once as primal.cl's marches are:
// `take` holds the rays that sample in this round (the constant true for one ray), and each lane
// does its own ray's arithmetic. The samples from `at` on that lie before `window_end` (in core:
// ∞) and before the primal march's end; `at` is left where the march stopped.
__attribute__((always_inline)) inline void adjoint_march_midpoint_window(
    __global const real* volume, int4 dims, const March* m, Ray ray, real4 inv_voxel,
    __global const real* tf, int tf_count, real4 tf_scalars, const AdjointRay* ar,
    __global const uchar* occupied, int4 bricks, const ScatterSink grad_volume,
    TfGradCache* tf_cache, __local real* tf_acc, CameraSums* cs, vreal window_end,
    AdjointPrefix* at) {
  vreal transmittance = at->transmittance;
  vreal pr = at->pr, pg = at->pg, pb = at->pb, kr = at->kr, kg = at->kg, kb = at->kb;
  vint seg_value = (vint)0, seg_scatter = (vint)0;
  CellCache cell;
  cell_init(&cell, grad_volume, at->flushed);
#if IVR_GRAD_CAMERA
  real along = 0, indexed = 0, direct = 0;  // camera: fixed_step_ends()
#endif
  const vint end = ar->end;
  vint i = at->i;
  vint live = i < end;
  while (vany(live)) {
    const vreal t = sample_t(m, i);
    live = live && vmask_of(t < window_end);
    if (!vany(live)) break;
    const vreal ux = IVR_POINT(m, t, x), uy = IVR_POINT(m, t, y), uz = IVR_POINT(m, t, z);
#if IVR_EMPTY_SPACE
    const vint take = midpoint_skip(&i, end, &live, ux, uy, uz, m, dims, occupied, bricks);
    if (!vany(take)) continue;
#else
    (void)occupied, (void)bricks;
    const vint take = IVR_RAYS == 1 ? vtrue : live;
#endif
    // The sample's cell and weights, as trilinear_at() clamps and indexes them.
    vreal fx, fy, fz;
    const vint ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
               iz = cell_axis(uz, dims.z, &fz);
    cell_enter(&cell, ix, iy, iz, volume, dims, grad_volume, take);
    const vreal d = cell_density(&cell, fx, fy, fz);
    vreal er, eg, eb, dsigma, der, deg, deb;
    TfPoint point;
    const vreal sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &seg_value, &er, &eg, &eb,
                                        &dsigma, &der, &deg, &deb, &point);
    const vreal dt = m->dt, tau = sigma * dt;
    vreal fraction;
    const vreal decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
    const vreal weight = transmittance * dt * fraction;
    accumulate_where(&pr, &kr, weight * er, take);
    accumulate_where(&pg, &kg, weight * eg, take);
    accumulate_where(&pb, &kb, weight * eb, take);
    const vreal slope = transmittance * dt * dt * fraction_slope(tau, decay, fraction);
    const vreal gsigma = ar->gr * (slope * er - dt * (ar->total_r - pr)) +
                         ar->gg * (slope * eg - dt * (ar->total_g - pg)) +
                         ar->gb * (slope * eb - dt * (ar->total_b - pb)) + ar->ga * dt * ar->t_end;
    const vreal ger = ar->gr * weight, geg = ar->gg * weight, geb = ar->gb * weight;
#if IVR_GRAD_CAMERA
    // The pixel depends on dt through tau = sigma·dt and through the weight's own factor dt.
    direct += sigma * gsigma + ger * er + geg * eg + geb * eb;
#endif
#else
    const vreal gsigma = -dt * ar->intensity * ar->gi;
    const vreal ger = (vreal)(real)0, geg = ger, geb = ger;
#if IVR_GRAD_CAMERA
    direct += sigma * gsigma;
#endif
    (void)er, (void)eg, (void)eb, (void)pr, (void)pg, (void)pb, (void)kr, (void)kg, (void)kb;
#endif
    transmittance = vsel(transmittance, attenuate(transmittance, tau, fraction, decay), take);
    // dL / d density (0 in the lanes that do not sample).
    const vreal gd = vsel((vreal)(real)0, gsigma * dsigma + ger * der + geg * deg + geb * deb, take);
    const vreal slide =
        scatter_sample(&cell, gd, t, fx, fy, fz, ux, uy, uz, dims, inv_voxel, ray.dir, cs);
#if IVR_GRAD_CAMERA
    along += slide;
    indexed += ((real)i + (real)0.5) * slide;
#else
    (void)slide;
#endif
#if IVR_GRAD_TF
    tf_scatter_sample(d, sigma, &point, take, tf, tf_count, tf_scalars, &seg_scatter, gsigma, ger,
                      geg, geb, tf_cache, tf_acc);
#else
    (void)seg_scatter, (void)tf_cache, (void)tf_acc;
#endif
    i += vcount(take);
    live = live && (i < end);
  }
  at->flushed = cell_flush(&cell, grad_volume);
#if IVR_GRAD_CAMERA
  fixed_step_ends(cs, m, along, indexed, direct);
#endif
  at->transmittance = transmittance;
  at->pr = pr, at->pg = pg, at->pb = pb, at->kr = kr, at->kg = kg, at->kb = kb;
  at->i = i;
}

// The whole ray's adjoint march (in core).
__attribute__((always_inline)) inline void adjoint_march_midpoint(
    __global const real* volume, int4 dims, const March* m, Ray ray, real4 inv_voxel,
    __global const real* tf, int tf_count, real4 tf_scalars, const AdjointRay* ar,
    __global const uchar* occupied, int4 bricks, const ScatterSink grad_volume,
    TfGradCache* tf_cache, __local real* tf_acc, CameraSums* cs) {
  AdjointPrefix at = adjoint_prefix_begin();
  adjoint_march_midpoint_window(volume, dims, m, ray, inv_voxel, tf, tf_count, tf_scalars, ar,
                                occupied, bricks, grad_volume, tf_cache, tf_acc, cs,
                                (vreal)(real)INFINITY, &at);
  adjoint_ray_end(grad_volume, at.flushed);
}

#endif
