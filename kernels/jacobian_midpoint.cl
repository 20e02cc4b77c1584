// jacobian_midpoint.cl — the midpoint rule's march carrying the tangent lanes: each sample's
// density, σ and emission, and their tangents, through the segment's compositing.
#ifndef IVR_TANGENT_MIDPOINT_CL
#define IVR_TANGENT_MIDPOINT_CL
#include "compositing.cl"
#include "empty_space.cl"
#include "primal.cl"
#include "jacobian_ray.cl"
#include "adjoint_tf.cl"
#include "jacobian_tf.cl"

// One ray, or every ray of a packet (kernels/rays.cl) written once as primal.cl's marches are:
// `take` holds the rays that sample in this round (the constant true for one ray). The samples
// from *at on that lie before `window_end` (in core: ∞), with the radiance and the tangents
// carried in *r and *tr; *at is left where the march stopped. Out of core
// (kernels/bricked_tangent.cl) each brick goes on from where the one before left the ray.
__attribute__((always_inline)) inline void tangent_march_midpoint_window(
    __global const real* volume, int4 dims, const March* m, Ray ray, real4 inv_voxel,
    __global const real* tf, int tf_count, real4 tf_scalars, real min_transmittance,
    __global const uchar* occupied, int4 bricks, TangentRay* tr, Radiance* r, vreal window_end,
    vint* at) {
  const vreal dt = m->dt;
  const real threshold = march_threshold(min_transmittance);
  vint segment = (vint)0;
  const vint n = (vint)m->n;
  vint i = *at;
  vint live = i < n;
  while (vany(live)) {
    const vreal t = sample_t(m, i);
    live = live && vmask_of(t < window_end);
    if (!vany(live)) break;
    const vreal mid = vto_real(i) + (real)0.5;
    const vreal ux = IVR_POINT(m, t, x), uy = IVR_POINT(m, t, y), uz = IVR_POINT(m, t, z);
#if IVR_EMPTY_SPACE
    // Only where nothing differentiated can come from (lib/empty_space/empty_space.hpp,
    // gradient_may_skip).
    const vint take = midpoint_skip(&i, n, &live, ux, uy, uz, m, dims, occupied, bricks);
    if (!vany(take)) continue;
#else
    (void)occupied, (void)bricks;
    const vint take = IVR_RAYS == 1 ? vtrue : live;
#endif
    const vreal d = trilinear_at(volume, dims, ux, uy, uz);
    vreal er, eg, eb, dsigma_dd, der_dd, deg_dd, deb_dd;
    TfPoint point;
    const vreal sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb,
                                        &dsigma_dd, &der_dd, &deg_dd, &deb_dd, &point);
    const vreal tau = sigma * dt;
#if IVR_EMISSION
    vreal fraction;
    const vreal decay = decay_and_fraction(tau, &fraction);
    const vreal weight = r->transmittance * dt * fraction;
    const vreal fslope = fraction_slope(tau, decay, fraction);
    const vreal next = attenuate(r->transmittance, tau, fraction, decay);
#endif

    // The sample's cell and weights (as trilinear_at() clamps them), and d density / d u.
    vreal fx, fy, fz, gx, gy, gz;
    const vint ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
               iz = cell_axis(uz, dims.z, &fz);
    sample_gradient(tr, volume, dims, ix, iy, iz, fx, fy, fz, ux, uy, uz, &gx, &gy, &gz);
    IVR_FOR_LANES(p) {
      const real ddt = IVR_DDT(tr, p, m);  // d dt
      const vreal dd = density_tangent(tr, p, ray, t, tr->dt0[p] + mid * ddt, gx, gy, gz, ix, iy,
                                       iz, fx, fy, fz, dims, inv_voxel);
      vreal dsig = dsigma_dd * dd, der = der_dd * dd, deg = deg_dd * dd, deb = deb_dd * dd;
#if IVR_TANGENT_TF
      if (tr->lane[p].x == IVR_LANE_TF) {
        vreal pr, pg, pb;
        dsig += tf_param_partial(d, sigma, &point, dsigma_dd, der_dd, deg_dd, deb_dd, tf,
                                 tf_count, tf_scalars, tr->lane[p].y, tr->lane[p].z, &pr, &pg,
                                 &pb);
        der += pr;
        deg += pg;
        deb += pb;
      }
#endif
      const vreal dtau = dsig * dt + sigma * ddt;
#if IVR_EMISSION
      const vreal dweight = (tr->dT[p] * dt + r->transmittance * ddt) * fraction +
                            r->transmittance * dt * fslope * dtau;
      tr->dcr[p] = vsel(tr->dcr[p], tr->dcr[p] + (dweight * er + weight * der), take);
      tr->dcg[p] = vsel(tr->dcg[p], tr->dcg[p] + (dweight * eg + weight * deg), take);
      tr->dcb[p] = vsel(tr->dcb[p], tr->dcb[p] + (dweight * eb + weight * deb), take);
      tr->dT[p] = vsel(tr->dT[p], tr->dT[p] * decay - next * dtau, take);  // d (T e^-tau)
#else
      (void)der, (void)deg, (void)deb;
      tr->dT[p] = vsel(tr->dT[p], tr->dT[p] + dtau, take);  // absorption: dτ (tangent_finish)
#endif
    }
#if IVR_EMISSION
    radiance_emit_where(r, weight, er, eg, eb, next, take);
#else
    (void)er, (void)eg, (void)eb;
    accumulate_where(&r->tau, &r->ktau, tau, take);
#endif
    r->samples += vcount(take);
    i += vcount(take);
    live = live && (i < n);
#if IVR_EARLY_TERMINATION
    live = live && !march_stopped(r, threshold);
#endif
  }
  *at = i;
}

// The whole ray's march (in core), finished.
inline void tangent_march_midpoint(__global const real* volume, int4 dims, const March* m, Ray ray,
                                   real4 inv_voxel, __global const real* tf, int tf_count,
                                   real4 tf_scalars, real min_transmittance,
                                   __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                   Radiance* r) {
  vint i = (vint)0;
  tangent_march_midpoint_window(volume, dims, m, ray, inv_voxel, tf, tf_count, tf_scalars,
                                min_transmittance, occupied, bricks, tr, r, (vreal)(real)INFINITY,
                                &i);
  tangent_finish(tr, r);
}

#endif
