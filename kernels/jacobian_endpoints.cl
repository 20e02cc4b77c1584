// jacobian_endpoints.cl — the march of the integrators that build each segment from its two end
// samples (trapezoid, preintegrated) carrying the tangent lanes: each end sample's density
// tangent, then each segment's (its sub-segments' for preintegrated) through the compositing.
#ifndef IVR_TANGENT_ENDPOINTS_CL
#define IVR_TANGENT_ENDPOINTS_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (trapezoid)
#define IVR_SCHEME 1
#endif
#include "compositing.cl"
#include "empty_space.cl"
#include "end_sample.cl"
#include "primal.cl"
#include "jacobian_ray.cl"
#include "adjoint_tf.cl"
#include "jacobian_tf.cl"

// An end sample and the tangents of its density (and, trapezoid, of its σ and emission).
typedef struct {
  EndSample s;
  real dd[IVR_LANES];
  real dsig[IVR_LANES], der[IVR_LANES], deg[IVR_LANES], deb[IVR_LANES];
} TangentSample;

inline void tangent_sample(TangentSample* a, __global const real* volume, int4 dims, const March* m,
                           uint i, Ray ray, real4 inv_voxel, __global const real* tf, int tf_count,
                           real4 tf_scalars, int* cursor, int* tf_cursor, const TangentRay* tr) {
  const real t = sample_t(m, i);
  a->s.ux = m->u0x + t * m->dux;
  a->s.uy = m->u0y + t * m->duy;
  a->s.uz = m->u0z + t * m->duz;
  a->s.d = trilinear_at(volume, dims, a->s.ux, a->s.uy, a->s.uz);
  real fx, fy, fz, gx, gy, gz;
  const int ix = cell_axis(a->s.ux, dims.x, &fx), iy = cell_axis(a->s.uy, dims.y, &fy),
            iz = cell_axis(a->s.uz, dims.z, &fz);
  sample_gradient(volume, dims, ix, iy, iz, fx, fy, fz, a->s.ux, a->s.uy, a->s.uz, &gx, &gy, &gz);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
  real dsigma_dd, der_dd, deg_dd, deb_dd;
  a->s.sigma = tf_sample_slope(a->s.d, tf, tf_count, tf_scalars, cursor, &a->s.er, &a->s.eg,
                               &a->s.eb, &dsigma_dd, &der_dd, &deg_dd, &deb_dd);
#if IVR_TANGENT_TF
  const TfPoint point = tf_point(a->s.d, tf, tf_count, tf_scalars, tf_cursor);
#endif
#else
  (void)cursor;
  a->s.sigma = a->s.er = a->s.eg = a->s.eb = (real)0;
#endif
  IVR_FOR_LANES(p) {
    const real ddt = (tr->dt1[p] - tr->dt0[p]) / (real)m->n;
    a->dd[p] = density_tangent(tr, p, ray, t, tr->dt0[p] + (real)i * ddt, gx, gy, gz, ix, iy, iz,
                               fx, fy, fz, dims, inv_voxel);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    a->dsig[p] = dsigma_dd * a->dd[p];
    a->der[p] = der_dd * a->dd[p], a->deg[p] = deg_dd * a->dd[p], a->deb[p] = deb_dd * a->dd[p];
#if IVR_TANGENT_TF
    if (tr->lane[p].x == IVR_LANE_TF) {
      real pr, pg, pb;
      a->dsig[p] += tf_param_partial(a->s.d, a->s.sigma, point, tf, tf_count, tf_scalars,
                                     tr->lane[p].y, tr->lane[p].z, &pr, &pg, &pb);
      a->der[p] += pr, a->deg[p] += pg, a->deb[p] += pb;
    }
#else
    (void)tf_cursor;
#endif
#endif
  }
}

#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
// One segment: τ = dt (σa + σb)/2, emission dt·fraction(τ)·(Ea + Eb)/2 (primal.cl, composite()).
inline void tangent_segment(const TangentSample* a, const TangentSample* b, const March* m,
                            __global const real* tf, int tf_count, real4 tf_scalars, int* cursor,
                            TangentRay* tr, Radiance* r) {
  (void)tf, (void)tf_count, (void)tf_scalars, (void)cursor;
  const real dt = m->dt;
  const real sigma = (real)0.5 * (a->s.sigma + b->s.sigma), tau = sigma * dt;
  const real er = (real)0.5 * (a->s.er + b->s.er), eg = (real)0.5 * (a->s.eg + b->s.eg),
             eb = (real)0.5 * (a->s.eb + b->s.eb);
#if IVR_EMISSION
  real fraction;
  const real decay = decay_and_fraction(tau, &fraction);
  const real weight = r->transmittance * dt * fraction;
  const real fslope = fraction_slope(tau, decay, fraction);
  const real next = attenuate(r->transmittance, tau, fraction, decay);
#else
  (void)er, (void)eg, (void)eb;
#endif
  IVR_FOR_LANES(p) {
    const real ddt = (tr->dt1[p] - tr->dt0[p]) / (real)m->n;
    const real dtau = (real)0.5 * (a->dsig[p] + b->dsig[p]) * dt + sigma * ddt;
#if IVR_EMISSION
    const real dweight = (tr->dT[p] * dt + r->transmittance * ddt) * fraction +
                         r->transmittance * dt * fslope * dtau;
    tr->dcr[p] += dweight * er + weight * (real)0.5 * (a->der[p] + b->der[p]);
    tr->dcg[p] += dweight * eg + weight * (real)0.5 * (a->deg[p] + b->deg[p]);
    tr->dcb[p] += dweight * eb + weight * (real)0.5 * (a->deb[p] + b->deb[p]);
    tr->dT[p] = tr->dT[p] * decay - next * dtau;
#else
    tr->dT[p] += dtau;  // absorption: dτ (tangent_finish)
#endif
  }
#if IVR_EMISSION
  radiance_emit(r, weight, er, eg, eb, next);
#else
  accumulate(&r->tau, &r->ktau, tau);
#endif
}

#else
// One segment through its sub-segments (preintegrated.cl). The tangents of a sub-segment's ends:
// a sample end moves with its density, a knot stays at its density (unless the lane is that
// control point's density) but moves along the segment, φ = (knot − da)/(db − da).
inline void tangent_segment(const TangentSample* a, const TangentSample* b, const March* m,
                            __global const real* tf, int tf_count, real4 tf_scalars, int* cursor,
                            TangentRay* tr, Radiance* r) {
  const real dt = m->dt;
  Attenuation at = {(real)0, (real)1, (real)0};
  real er = (real)0, eg = (real)0, eb = (real)0;
  real dtrans[IVR_LANES], der[IVR_LANES], deg[IVR_LANES], deb[IVR_LANES];
  IVR_FOR_LANES(p) dtrans[p] = der[p] = deg[p] = deb[p] = (real)0;  // absorption: dτ in dtrans
  Cuts c;
  cuts_begin(&c, a->s.d, b->s.d, *cursor);
  SubSegment s;
  while (cuts_next(&c, b->s.d, tf, tf_count, tf_scalars, &s)) {
    const real length = dt * (s.phie - s.phis);
    const real sig_s = tf_piece_sigma(&s.piece, s.xs), sig_e = tf_piece_sigma(&s.piece, s.xe);
    const LinearSegment ls = linear_segment(sig_s * length, sig_e * length);
    real csr, csg, csb, cer, ceg, ceb;
    tf_piece_color(&s.piece, s.xs, &csr, &csg, &csb);
    tf_piece_color(&s.piece, s.xe, &cer, &ceg, &ceb);
    const real trans = at.transmittance, alpha = ls.p + ls.q;
    const real tau = (real)0.5 * (sig_s + sig_e) * length;
    const real decay = tau < (real)0.1 ? (real)1 - alpha : exp(-tau);  // e^{−τ}, as attenuation_add
    // The control points at knot ends: the piece's own ends, in the density's direction.
    const int row_s = c.direction > 0 ? s.piece.row0 : s.piece.row1;
    const int row_e = c.direction > 0 ? s.piece.row1 : s.piece.row0;
    IVR_FOR_LANES(p) {
      const int4 lane = tr->lane[p];
      const real ddt = (tr->dt1[p] - tr->dt0[p]) / (real)m->n;
      // The ends' densities and positions.
      real dxs = s.knot_s ? (real)0 : a->dd[p], dxe = s.knot_e ? (real)0 : b->dd[p];
      real dphis = (real)0, dphie = (real)0;
      const bool point_lane = lane.x == IVR_LANE_TF && lane.z == 4;
      if (s.knot_s) {
        const real own = point_lane && lane.y == row_s ? (real)1 : (real)0;
        dxs = own;
        dphis = (own - ((real)1 - s.phis) * a->dd[p] - s.phis * b->dd[p]) / c.delta;
      }
      if (s.knot_e) {
        const real own = point_lane && lane.y == row_e ? (real)1 : (real)0;
        dxe = own;
        dphie = (own - ((real)1 - s.phie) * a->dd[p] - s.phie * b->dd[p]) / c.delta;
      }
      const real dlength = ddt * (s.phie - s.phis) + dt * (dphie - dphis);
      real dss = s.piece.s1 * dxs, dse = s.piece.s1 * dxe;
      real dcsr = s.piece.c1r * dxs, dcsg = s.piece.c1g * dxs, dcsb = s.piece.c1b * dxs;
      real dcer = s.piece.c1r * dxe, dceg = s.piece.c1g * dxe, dceb = s.piece.c1b * dxe;
#if IVR_TANGENT_TF
      if (lane.x == IVR_LANE_TF) {
        real ds, dr, dg, db;
        tf_piece_partial(&s.piece, s.xs, lane.y, lane.z, &ds, &dr, &dg, &db);
        dss += ds, dcsr += dr, dcsg += dg, dcsb += db;
        tf_piece_partial(&s.piece, s.xe, lane.y, lane.z, &ds, &dr, &dg, &db);
        dse += ds, dcer += dr, dceg += dg, dceb += db;
      }
#endif
      const real da = dss * length + sig_s * dlength, db = dse * length + sig_e * dlength;
      const real dp = ls.dp_da * da + ls.dp_db * db, dq = ls.dq_da * da + ls.dq_db * db;
#if IVR_EMISSION
      der[p] += dtrans[p] * (csr * ls.p + cer * ls.q) +
                trans * (dcsr * ls.p + csr * dp + dcer * ls.q + cer * dq);
      deg[p] += dtrans[p] * (csg * ls.p + ceg * ls.q) +
                trans * (dcsg * ls.p + csg * dp + dceg * ls.q + ceg * dq);
      deb[p] += dtrans[p] * (csb * ls.p + ceb * ls.q) +
                trans * (dcsb * ls.p + csb * dp + dceb * ls.q + ceb * dq);
#else
      (void)dcsr, (void)dcsg, (void)dcsb, (void)dcer, (void)dceg, (void)dceb;
#endif
#if IVR_EMISSION
      dtrans[p] = dtrans[p] * decay - trans * (dp + dq);  // dα = e^{−τ} dτ = dp + dq
#else
      dtrans[p] += (real)0.5 * (da + db);  // absorption: dτ (tangent_finish)
#endif
    }
#if IVR_EMISSION
    er += trans * (csr * ls.p + cer * ls.q);
    eg += trans * (csg * ls.p + ceg * ls.q);
    eb += trans * (csb * ls.p + ceb * ls.q);
#endif
    attenuation_add(&at, tau, alpha);
  }
  *cursor = c.cursor;
  // Into the ray: C += T·e, T = T·(transmittance of the segment) (as primal.cl).
#if IVR_EMISSION
  IVR_FOR_LANES(p) {
    tr->dcr[p] += tr->dT[p] * er + r->transmittance * der[p];
    tr->dcg[p] += tr->dT[p] * eg + r->transmittance * deg[p];
    tr->dcb[p] += tr->dT[p] * eb + r->transmittance * deb[p];
    tr->dT[p] = tr->dT[p] * at.transmittance + r->transmittance * dtrans[p];
  }
  radiance_emit(r, r->transmittance, er, eg, eb, attenuation_apply(&at, r->transmittance));
#else
  IVR_FOR_LANES(p) tr->dT[p] += dtrans[p];
  accumulate(&r->tau, &r->ktau, at.tau);
#endif
}
#endif

inline void tangent_march_endpoints(__global const real* volume, int4 dims, const March* m, Ray ray,
                                    real4 inv_voxel, __global const real* tf, int tf_count,
                                    real4 tf_scalars, real min_transmittance,
                                    __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                    Radiance* r) {
  int cursor = 0, tf_cursor = 0;
  const real threshold = march_threshold(min_transmittance);
  TangentSample a, b;
  tangent_sample(&a, volume, dims, m, 0, ray, inv_voxel, tf, tf_count, tf_scalars, &cursor,
                 &tf_cursor, tr);
  ++r->samples;
  for (uint i = 0; i < m->n;) {
#if IVR_EMPTY_SPACE
    {
      const uint k = endpoint_skip(i, m->n, a.s.ux, a.s.uy, a.s.uz, m, dims, occupied, bricks);
      if (k > i) {
        i = k;
        if (i >= m->n) break;
        tangent_sample(&a, volume, dims, m, i, ray, inv_voxel, tf, tf_count, tf_scalars, &cursor,
                       &tf_cursor, tr);
        ++r->samples;
      }
    }
#endif
    tangent_sample(&b, volume, dims, m, i + 1, ray, inv_voxel, tf, tf_count, tf_scalars, &cursor,
                   &tf_cursor, tr);
    ++r->samples;
    tangent_segment(&a, &b, m, tf, tf_count, tf_scalars, &cursor, tr, r);
    a = b;
    ++i;
#if IVR_EARLY_TERMINATION
    if (march_stopped(r, threshold)) break;
#endif
  }
  tangent_finish(tr, r);
}

#endif
