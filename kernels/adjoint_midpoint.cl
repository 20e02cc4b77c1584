// adjoint_midpoint.cl — the adjoint march of the midpoint rule, front to back: each sample's
// remaining radiance is C minus the prefix (docs/design.md: no division by 1 − α, no per-sample
// storage); dL/d density goes to the voxels, dL/d TF to the work-group's accumulator.
#ifndef IVR_ADJOINT_MIDPOINT_CL
#define IVR_ADJOINT_MIDPOINT_CL
#include "adjoint_ray.cl"
#include "compositing.cl"
#include "empty_space.cl"

inline void adjoint_march_midpoint(__global const real* volume, int4 dims, const March* m, Ray ray,
                                   real4 inv_voxel, __global const real* tf, int tf_count,
                                   real4 tf_scalars, const AdjointRay* ar,
                                   __global const uchar* occupied, int4 bricks,
                                   const ScatterSink grad_volume, TfGradCache* tf_cache,
                                   __local real* tf_acc, CameraSums* cs) {
  real transmittance = (real)1;
  real pr = 0, pg = 0, pb = 0;  // emission prefix, summed exactly as the primal march summed C
  real kr = 0, kg = 0, kb = 0;
  int seg_value = 0, seg_scatter = 0;
  CellCache cell;
  cell_init(&cell);
  real along = 0, indexed = 0, direct = 0;  // camera: fixed_step_ends()
  for (uint i = 0; i < ar->end;) {
    const real t = sample_t(m, i);
    const real ux = m->u0x + t * m->dux, uy = m->u0y + t * m->duy, uz = m->u0z + t * m->duz;
#if IVR_EMPTY_SPACE
    const real exit = empty_brick_exit(ux, uy, uz, m, dims, occupied, bricks);
    if (exit >= (real)0) {
      i = skip_to(i, ar->end, m->t0, m->dt, exit);
      continue;
    }
#endif
    // The sample's cell and weights, as trilinear_at() clamps and indexes them.
    real fx, fy, fz;
    const int ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
              iz = cell_axis(uz, dims.z, &fz);
    cell_enter(&cell, ix, iy, iz, volume, dims, grad_volume);
    const real d = cell_density(&cell, fx, fy, fz);
    real er, eg, eb, dsigma, der, deg, deb;
    TfPoint unused;
    const real sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &seg_value, &er, &eg, &eb,
                                       &dsigma, &der, &deg, &deb, &unused);
    const real dt = m->dt, tau = sigma * dt;
    real fraction;
    const real decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
    const real weight = transmittance * dt * fraction;
    accumulate(&pr, &kr, weight * er);
    accumulate(&pg, &kg, weight * eg);
    accumulate(&pb, &kb, weight * eb);
    const real slope = transmittance * dt * dt * fraction_slope(tau, decay, fraction);
    const real gsigma = ar->gr * (slope * er - dt * (ar->total_r - pr)) +
                        ar->gg * (slope * eg - dt * (ar->total_g - pg)) +
                        ar->gb * (slope * eb - dt * (ar->total_b - pb)) + ar->ga * dt * ar->t_end;
    const real ger = ar->gr * weight, geg = ar->gg * weight, geb = ar->gb * weight;
    // The pixel depends on dt through tau = sigma·dt and through the weight's own factor dt.
    direct += sigma * gsigma + ger * er + geg * eg + geb * eb;
#else
    const real gsigma = -dt * ar->intensity * ar->gi;
    const real ger = (real)0, geg = (real)0, geb = (real)0;
    direct += sigma * gsigma;
    (void)er, (void)eg, (void)eb, (void)pr, (void)pg, (void)pb, (void)kr, (void)kg, (void)kb;
#endif
    transmittance = attenuate(transmittance, tau, fraction, decay);
    const real gd = gsigma * dsigma + ger * der + geg * deg + geb * deb;  // dL / d density
    const real slide =
        scatter_sample(&cell, gd, t, fx, fy, fz, ux, uy, uz, dims, inv_voxel, ray.dir, cs);
    along += slide;
    indexed += ((real)i + (real)0.5) * slide;
#if IVR_GRAD_TF
    tf_scatter(d, tf, tf_count, tf_scalars, &seg_scatter, gsigma, ger, geg, geb, tf_cache, tf_acc);
#else
    (void)seg_scatter, (void)tf_cache, (void)tf_acc;
#endif
    ++i;
  }
  cell_flush(&cell, grad_volume);
  fixed_step_ends(cs, m, along, indexed, direct);
}

#endif
