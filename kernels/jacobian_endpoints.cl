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

// An end sample and the tangents of its density (and, trapezoid, of its σ and emission); one ray
// or every ray of a packet (kernels/rays.cl).
typedef struct {
  EndSample s;
  vreal dd[IVR_LANES];
  vreal dsig[IVR_LANES], der[IVR_LANES], deg[IVR_LANES], deb[IVR_LANES];
} TangentSample;

inline void tangent_sample(TangentSample* a, __global const real* volume, int4 dims, const March* m,
                           vint i, Ray ray, real4 inv_voxel, __global const real* tf, int tf_count,
                           real4 tf_scalars, vint* cursor, const TangentRay* tr) {
  const vreal t = sample_t(m, i);
  a->s.ux = IVR_POINT(m, t, x);
  a->s.uy = IVR_POINT(m, t, y);
  a->s.uz = IVR_POINT(m, t, z);
  a->s.d = trilinear_at(volume, dims, a->s.ux, a->s.uy, a->s.uz);
  vreal fx, fy, fz, gx, gy, gz;
  const vint ix = cell_axis(a->s.ux, dims.x, &fx), iy = cell_axis(a->s.uy, dims.y, &fy),
             iz = cell_axis(a->s.uz, dims.z, &fz);
  sample_gradient(tr, volume, dims, ix, iy, iz, fx, fy, fz, a->s.ux, a->s.uy, a->s.uz, &gx, &gy,
                  &gz);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
  vreal dsigma_dd, der_dd, deg_dd, deb_dd;
  TfPoint point;
  a->s.sigma = tf_sample_slope(a->s.d, tf, tf_count, tf_scalars, cursor, &a->s.er, &a->s.eg,
                               &a->s.eb, &dsigma_dd, &der_dd, &deg_dd, &deb_dd, &point);
#else
  (void)cursor;
  a->s.sigma = a->s.er = a->s.eg = a->s.eb = (vreal)(real)0;
#endif
  IVR_FOR_LANES(p) {
    const real ddt = IVR_DDT(tr, p, m);
    a->dd[p] = density_tangent(tr, p, ray, t, tr->dt0[p] + vto_real(i) * ddt, gx, gy, gz, ix, iy,
                               iz, fx, fy, fz, dims, inv_voxel);
#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
    a->dsig[p] = dsigma_dd * a->dd[p];
    a->der[p] = der_dd * a->dd[p], a->deg[p] = deg_dd * a->dd[p], a->deb[p] = deb_dd * a->dd[p];
#if IVR_TANGENT_TF
    if (tr->lane[p].x == IVR_LANE_TF) {
      vreal pr, pg, pb;
      a->dsig[p] += tf_param_partial(a->s.d, a->s.sigma, &point, dsigma_dd, der_dd, deg_dd, deb_dd,
                                     tf, tf_count, tf_scalars, tr->lane[p].y, tr->lane[p].z, &pr,
                                     &pg, &pb);
      a->der[p] += pr, a->deg[p] += pg, a->deb[p] += pb;
    }
#endif
#endif
  }
}

// *a = *b for the rays where m is true.
inline void tangent_sample_where(TangentSample* a, const TangentSample* b, vint m) {
  end_sample_where(&a->s, &b->s, m);
  IVR_FOR_LANES(p) {
    a->dd[p] = vsel(a->dd[p], b->dd[p], m), a->dsig[p] = vsel(a->dsig[p], b->dsig[p], m);
    a->der[p] = vsel(a->der[p], b->der[p], m), a->deg[p] = vsel(a->deg[p], b->deg[p], m);
    a->deb[p] = vsel(a->deb[p], b->deb[p], m);
  }
}

#if IVR_SCHEME == IVR_SCHEME_TRAPEZOID
// One segment: τ = dt (σa + σb)/2, emission dt·fraction(τ)·(Ea + Eb)/2 (primal.cl, composite()),
// for the rays where `take` is true.
inline void tangent_segment(const TangentSample* a, const TangentSample* b, const March* m,
                            __global const real* tf, int tf_count, real4 tf_scalars, vint* cursor,
                            TangentRay* tr, Radiance* r, vint take) {
  (void)tf, (void)tf_count, (void)tf_scalars, (void)cursor;
  const vreal dt = m->dt;
  const vreal sigma = (real)0.5 * (a->s.sigma + b->s.sigma), tau = sigma * dt;
  const vreal er = (real)0.5 * (a->s.er + b->s.er), eg = (real)0.5 * (a->s.eg + b->s.eg),
              eb = (real)0.5 * (a->s.eb + b->s.eb);
#if IVR_EMISSION
  vreal fraction;
  const vreal decay = decay_and_fraction(tau, &fraction);
  const vreal weight = r->transmittance * dt * fraction;
  const vreal fslope = fraction_slope(tau, decay, fraction);
  const vreal next = attenuate(r->transmittance, tau, fraction, decay);
#else
  (void)er, (void)eg, (void)eb;
#endif
  IVR_FOR_LANES(p) {
    const real ddt = IVR_DDT(tr, p, m);
    const vreal dtau = (real)0.5 * (a->dsig[p] + b->dsig[p]) * dt + sigma * ddt;
#if IVR_EMISSION
    const vreal dweight = (tr->dT[p] * dt + r->transmittance * ddt) * fraction +
                          r->transmittance * dt * fslope * dtau;
    tr->dcr[p] = vsel(tr->dcr[p],
                      tr->dcr[p] + (dweight * er + weight * (real)0.5 * (a->der[p] + b->der[p])),
                      take);
    tr->dcg[p] = vsel(tr->dcg[p],
                      tr->dcg[p] + (dweight * eg + weight * (real)0.5 * (a->deg[p] + b->deg[p])),
                      take);
    tr->dcb[p] = vsel(tr->dcb[p],
                      tr->dcb[p] + (dweight * eb + weight * (real)0.5 * (a->deb[p] + b->deb[p])),
                      take);
    tr->dT[p] = vsel(tr->dT[p], tr->dT[p] * decay - next * dtau, take);
#else
    tr->dT[p] = vsel(tr->dT[p], tr->dT[p] + dtau, take);  // absorption: dτ (tangent_finish)
#endif
  }
#if IVR_EMISSION
  radiance_emit_where(r, weight, er, eg, eb, next, take);
#else
  accumulate_where(&r->tau, &r->ktau, tau, take);
#endif
}

#else
// One segment through its sub-segments (preintegrated.cl), for the rays where `take` is true. The
// tangents of a sub-segment's ends: a sample end moves with its density, a knot stays at its
// density (unless the lane is that control point's density) but moves along the segment,
// φ = (knot − da)/(db − da).
inline void tangent_segment(const TangentSample* a, const TangentSample* b, const March* m,
                            __global const real* tf, int tf_count, real4 tf_scalars, vint* cursor,
                            TangentRay* tr, Radiance* r, vint take) {
  const vreal dt = m->dt, zero = (vreal)(real)0, one = (vreal)(real)1;
  Attenuation at;
  at.opacity = at.tau = zero;
  at.transmittance = one;
  vreal er = zero, eg = zero, eb = zero;
  vreal dtrans[IVR_LANES], der[IVR_LANES], deg[IVR_LANES], deb[IVR_LANES];
  IVR_FOR_LANES(p) dtrans[p] = der[p] = deg[p] = deb[p] = zero;  // absorption: dτ in dtrans
  Cuts c;
  cuts_begin(&c, a->s.d, b->s.d, *cursor);
  c.done = !take;
  SubSegment s;
  vint go;
  while (vany(go = cuts_next(&c, b->s.d, tf, tf_count, tf_scalars, &s))) {
    const vreal length = dt * (s.phie - s.phis);
    const vreal sig_s = tf_piece_sigma(&s.piece, s.xs), sig_e = tf_piece_sigma(&s.piece, s.xe);
    const LinearSegment ls = linear_segment_where(sig_s * length, sig_e * length, go);
    vreal csr, csg, csb, cer, ceg, ceb;
    tf_piece_color(&s.piece, s.xs, &csr, &csg, &csb);
    tf_piece_color(&s.piece, s.xe, &cer, &ceg, &ceb);
    const vreal trans = at.transmittance, alpha = ls.p + ls.q;
    const vreal tau = (real)0.5 * (sig_s + sig_e) * length;
    // e^{−τ}, as attenuation_add_where takes it
    const vint small = vmask_of(tau < (real)0.1);
    vreal decay = (real)1 - alpha;
    if (!vall(small || !go)) decay = vsel(vexp(-tau), decay, small);
    // The control points at knot ends: the piece's own ends, in the density's direction.
    const vint rising = c.direction > 0;
    const vint row_s = vseli(s.piece.row1, s.piece.row0, rising);
    const vint row_e = vseli(s.piece.row0, s.piece.row1, rising);
    IVR_FOR_LANES(p) {
      const int4 lane = tr->lane[p];
      const real ddt = IVR_DDT(tr, p, m);
      // The ends' densities and positions.
      vreal dxs = vsel(a->dd[p], zero, s.knot_s), dxe = vsel(b->dd[p], zero, s.knot_e);
      vreal dphis = zero, dphie = zero;
      const bool point_lane = lane.x == IVR_LANE_TF && lane.z == 4;
      if (vany(s.knot_s)) {
        const vreal own = point_lane ? vsel(zero, one, row_s == lane.y) : zero;
        dxs = vsel(dxs, own, s.knot_s);
        dphis = vsel(dphis, (own - ((real)1 - s.phis) * a->dd[p] - s.phis * b->dd[p]) / c.delta,
                     s.knot_s);
      }
      if (vany(s.knot_e)) {
        const vreal own = point_lane ? vsel(zero, one, row_e == lane.y) : zero;
        dxe = vsel(dxe, own, s.knot_e);
        dphie = vsel(dphie, (own - ((real)1 - s.phie) * a->dd[p] - s.phie * b->dd[p]) / c.delta,
                     s.knot_e);
      }
      const vreal dlength = ddt * (s.phie - s.phis) + dt * (dphie - dphis);
      vreal dss = s.piece.s1 * dxs, dse = s.piece.s1 * dxe;
      vreal dcsr = s.piece.c1r * dxs, dcsg = s.piece.c1g * dxs, dcsb = s.piece.c1b * dxs;
      vreal dcer = s.piece.c1r * dxe, dceg = s.piece.c1g * dxe, dceb = s.piece.c1b * dxe;
#if IVR_TANGENT_TF
      if (lane.x == IVR_LANE_TF) {
        vreal ds, dr, dg, db;
        tf_piece_partial(&s.piece, s.xs, lane.y, lane.z, &ds, &dr, &dg, &db);
        dss += ds, dcsr += dr, dcsg += dg, dcsb += db;
        tf_piece_partial(&s.piece, s.xe, lane.y, lane.z, &ds, &dr, &dg, &db);
        dse += ds, dcer += dr, dceg += dg, dceb += db;
      }
#endif
      const vreal da = dss * length + sig_s * dlength, db = dse * length + sig_e * dlength;
      const vreal dp = ls.dp_da * da + ls.dp_db * db, dq = ls.dq_da * da + ls.dq_db * db;
#if IVR_EMISSION
      der[p] = vsel(der[p],
                    der[p] + (dtrans[p] * (csr * ls.p + cer * ls.q) +
                              trans * (dcsr * ls.p + csr * dp + dcer * ls.q + cer * dq)),
                    go);
      deg[p] = vsel(deg[p],
                    deg[p] + (dtrans[p] * (csg * ls.p + ceg * ls.q) +
                              trans * (dcsg * ls.p + csg * dp + dceg * ls.q + ceg * dq)),
                    go);
      deb[p] = vsel(deb[p],
                    deb[p] + (dtrans[p] * (csb * ls.p + ceb * ls.q) +
                              trans * (dcsb * ls.p + csb * dp + dceb * ls.q + ceb * dq)),
                    go);
      // dα = e^{−τ} dτ = dp + dq
      dtrans[p] = vsel(dtrans[p], dtrans[p] * decay - trans * (dp + dq), go);
#else
      (void)dcsr, (void)dcsg, (void)dcsb, (void)dcer, (void)dceg, (void)dceb;
      dtrans[p] = vsel(dtrans[p], dtrans[p] + (real)0.5 * (da + db), go);  // absorption: dτ
#endif
    }
#if IVR_EMISSION
    er = vsel(er, er + trans * (csr * ls.p + cer * ls.q), go);
    eg = vsel(eg, eg + trans * (csg * ls.p + ceg * ls.q), go);
    eb = vsel(eb, eb + trans * (csb * ls.p + ceb * ls.q), go);
#endif
    attenuation_add_where(&at, tau, alpha, go);
  }
  *cursor = c.cursor;
  // Into the ray: C += T·e, T = T·(transmittance of the segment) (as primal.cl).
#if IVR_EMISSION
  IVR_FOR_LANES(p) {
    tr->dcr[p] = vsel(tr->dcr[p], tr->dcr[p] + (tr->dT[p] * er + r->transmittance * der[p]), take);
    tr->dcg[p] = vsel(tr->dcg[p], tr->dcg[p] + (tr->dT[p] * eg + r->transmittance * deg[p]), take);
    tr->dcb[p] = vsel(tr->dcb[p], tr->dcb[p] + (tr->dT[p] * eb + r->transmittance * deb[p]), take);
    tr->dT[p] = vsel(tr->dT[p], tr->dT[p] * at.transmittance + r->transmittance * dtrans[p], take);
  }
  radiance_emit_where(r, r->transmittance, er, eg, eb, attenuation_apply(&at, r->transmittance),
                      take);
#else
  IVR_FOR_LANES(p) tr->dT[p] = vsel(tr->dT[p], tr->dT[p] + dtrans[p], take);
  accumulate_where(&r->tau, &r->ktau, at.tau, take);
#endif
}
#endif

// The segments from *at on that belong to the window ending at `window_end` (segment_in_window;
// in core: ∞), with the radiance and the tangents carried in *r and *tr; *at is left where the
// march stopped. A window's first sample is taken afresh (out of core, kernels/bricked_tangent.cl:
// from the brick's halo, lib/brick/brick_layout.hpp), counted once, where the ray starts.
__attribute__((always_inline)) inline void tangent_march_endpoints_window(
    __global const real* volume, int4 dims, const March* m, Ray ray, real4 inv_voxel,
    __global const real* tf, int tf_count, real4 tf_scalars, real min_transmittance,
    __global const uchar* occupied, int4 bricks, TangentRay* tr, Radiance* r, vreal window_end,
    vint* at) {
  vint cursor = (vint)0;
  const real threshold = march_threshold(min_transmittance);
  const vint n = (vint)m->n;
  vint i = *at;
  vint live = i < n;
  TangentSample a, b;
  tangent_sample(&a, volume, dims, m, i, ray, inv_voxel, tf, tf_count, tf_scalars, &cursor, tr);
  r->samples += vcount(live && i == 0);
  while (vany(live)) {
    live = live && segment_in_window(m, i, window_end);
    if (!vany(live)) break;
#if IVR_EMPTY_SPACE
    {
      const vint again = endpoint_skip_step(&i, n, &live, a.s.ux, a.s.uy, a.s.uz, m, dims,
                                            occupied, bricks);
      if (vany(again)) {  // the sample the march goes on from
        tangent_sample(&b, volume, dims, m, i, ray, inv_voxel, tf, tf_count, tf_scalars, &cursor,
                       tr);
        tangent_sample_where(&a, &b, again);
        r->samples += vcount(again);
      }
      if (!vany(live)) break;
    }
#else
    (void)occupied, (void)bricks;
#endif
    const vint take = IVR_RAYS == 1 ? vtrue : live;  // one ray: it is live in the loop
    tangent_sample(&b, volume, dims, m, i + 1, ray, inv_voxel, tf, tf_count, tf_scalars, &cursor,
                   tr);
    r->samples += vcount(take);
    tangent_segment(&a, &b, m, tf, tf_count, tf_scalars, &cursor, tr, r, take);
    a = b;
    i += vcount(take);
    live = live && (i < n);
#if IVR_EARLY_TERMINATION
    live = live && !march_stopped(r, threshold);
#endif
  }
  *at = i;
}

// The whole ray's march (in core), finished.
inline void tangent_march_endpoints(__global const real* volume, int4 dims, const March* m, Ray ray,
                                    real4 inv_voxel, __global const real* tf, int tf_count,
                                    real4 tf_scalars, real min_transmittance,
                                    __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                    Radiance* r) {
  vint i = (vint)0;
  tangent_march_endpoints_window(volume, dims, m, ray, inv_voxel, tf, tf_count, tf_scalars,
                                 min_transmittance, occupied, bricks, tr, r,
                                 (vreal)(real)INFINITY, &i);
  tangent_finish(tr, r);
}
#endif
