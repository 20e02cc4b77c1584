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

inline void tangent_march_midpoint(__global const real* volume, int4 dims, const March* m, Ray ray,
                                   real4 inv_voxel, __global const real* tf, int tf_count,
                                   real4 tf_scalars, real min_transmittance,
                                   __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                   Radiance* r) {
  const real dt = m->dt;
  const real threshold = march_threshold(min_transmittance);
  int segment = 0, cursor = 0;
  for (uint i = 0; i < m->n;) {
    const real mid = (real)i + (real)0.5;
    const real t = sample_t(m, i);
    const real ux = m->u0x + t * m->dux, uy = m->u0y + t * m->duy, uz = m->u0z + t * m->duz;
#if IVR_EMPTY_SPACE
    // Only where nothing differentiated can come from (lib/empty_space/empty_space.hpp, gradient_may_skip).
    const real exit = empty_brick_exit(ux, uy, uz, m, dims, occupied, bricks);
    if (exit >= (real)0) {
      i = skip_to(i, m->n, m->t0, dt, exit);
      continue;
    }
#endif
    const real d = trilinear_at(volume, dims, ux, uy, uz);
    real er, eg, eb, dsigma_dd, der_dd, deg_dd, deb_dd;
    const real sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb,
                                       &dsigma_dd, &der_dd, &deg_dd, &deb_dd);
    const real tau = sigma * dt;
#if IVR_EMISSION
    real fraction;
    const real decay = decay_and_fraction(tau, &fraction);
    const real weight = r->transmittance * dt * fraction;
    const real fslope = fraction_slope(tau, decay, fraction);
    const real next = attenuate(r->transmittance, tau, fraction, decay);
#endif

    // The sample's cell and weights (as trilinear_at() clamps them), and d density / d u.
    real fx, fy, fz, gx, gy, gz;
    const int ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
              iz = cell_axis(uz, dims.z, &fz);
    sample_gradient(volume, dims, ix, iy, iz, fx, fy, fz, ux, uy, uz, &gx, &gy, &gz);
#if IVR_TANGENT_TF
    const TfPoint point = tf_point(d, tf, tf_count, tf_scalars, &cursor);
#else
    (void)cursor;
#endif
    IVR_FOR_LANES(p) {
      const real ddt = (tr->dt1[p] - tr->dt0[p]) / (real)m->n;  // d dt
      const real dd = density_tangent(tr, p, ray, t, tr->dt0[p] + mid * ddt, gx, gy, gz, ix, iy, iz,
                                      fx, fy, fz, dims, inv_voxel);
      real dsig = dsigma_dd * dd, der = der_dd * dd, deg = deg_dd * dd, deb = deb_dd * dd;
#if IVR_TANGENT_TF
      if (tr->lane[p].x == IVR_LANE_TF) {
        real pr, pg, pb;
        dsig += tf_param_partial(d, sigma, point, tf, tf_count, tf_scalars, tr->lane[p].y,
                                 tr->lane[p].z, &pr, &pg, &pb);
        der += pr;
        deg += pg;
        deb += pb;
      }
#endif
      const real dtau = dsig * dt + sigma * ddt;
#if IVR_EMISSION
      const real dweight = (tr->dT[p] * dt + r->transmittance * ddt) * fraction +
                           r->transmittance * dt * fslope * dtau;
      tr->dcr[p] += dweight * er + weight * der;
      tr->dcg[p] += dweight * eg + weight * deg;
      tr->dcb[p] += dweight * eb + weight * deb;
      tr->dT[p] = tr->dT[p] * decay - next * dtau;  // d (T e^-tau)
#else
      (void)der, (void)deg, (void)deb;
      tr->dT[p] += dtau;  // absorption: dτ (tangent_finish)
#endif
    }
#if IVR_EMISSION
    radiance_emit(r, weight, er, eg, eb, next);
#else
    (void)er, (void)eg, (void)eb;
    accumulate(&r->tau, &r->ktau, tau);
#endif
    ++r->samples;
    ++i;
#if IVR_EARLY_TERMINATION
    if (march_stopped(r, threshold)) break;
#endif
  }
  tangent_finish(tr, r);
}

#endif
