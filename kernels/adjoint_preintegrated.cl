// adjoint_preintegrated.cl — the adjoint of a preintegrated segment (kernels/preintegrated.cl)
// inside the adjoint march: the same sub-segments, each one's closed form differentiated
// (linear_segment), carried to the two end densities — directly where a sub-segment ends at a
// sample, through the knot's position φ = (knot − da)/(db − da) where it ends at a knot — and to
// the TF rows of its piece.
#ifndef IVR_PREINTEGRATED_ADJOINT_CL
#define IVR_PREINTEGRATED_ADJOINT_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (preintegrated)
#define IVR_SCHEME 3
#endif
#include "adjoint_ray.cl"
#include "preintegrated.cl"
#include "adjoint_tf.cl"

// The adjoint of one segment inside the adjoint march, in the rays where `live` is true (one ray,
// or every ray of a packet: kernels/rays.cl): *transmittance and the prefix (pr, pg, pb;
// compensations k*) advance exactly as the primal march advanced them; dL/d da and dL/d db are
// added to *gd_a, *gd_b, (camera, one ray) dt · dL/d dt at fixed densities to *direct, and dL/d TF
// goes to the cache. Each lane's sums are selected whole, so that they contract as one ray's do.
inline void preintegrated_segment_adjoint(const EndSample* a, const EndSample* b, vreal dt,
                                          __global const real* tf, int count, real4 scalars,
                                          const AdjointRay* ar, vint live, vreal* transmittance,
                                          vreal* pr, vreal* pg, vreal* pb, vreal* kr, vreal* kg,
                                          vreal* kb, vreal* gd_a, vreal* gd_b, real* direct,
                                          vint* cursor, TfGradCache* tf_cache,
                                          __local real* tf_acc) {
  const vreal t_in = *transmittance;
#if IVR_EMISSION
  // Remaining radiance at the segment's start, grouped as the primal summed it.
  const vreal rem_r = ar->total_r - *pr, rem_g = ar->total_g - *pg, rem_b = ar->total_b - *pb;
#endif
  Attenuation at;
  at.opacity = at.tau = (vreal)(real)0;
  at.transmittance = (vreal)(real)1;
  vreal er = (vreal)(real)0, eg = er, eb = er;
  Cuts c;
  cuts_begin(&c, a->d, b->d, *cursor);
  c.done = !live;
  SubSegment s;
  vint go;
  while (vany(go = cuts_next(&c, b->d, tf, count, scalars, &s))) {
    const vreal length = dt * (s.phie - s.phis);
    const vreal sig_s = tf_piece_sigma(&s.piece, s.xs), sig_e = tf_piece_sigma(&s.piece, s.xe);
    const LinearSegment ls = linear_segment_where(sig_s * length, sig_e * length, go);
    const vreal t_k = t_in * at.transmittance;  // transmittance entering the sub-segment
    vreal g_a, g_b;                              // dL / d (σs·L), dL / d (σe·L)
    vreal gcs_r = (vreal)(real)0, gcs_g = gcs_r, gcs_b = gcs_r;  // dL / d colours
    vreal gce_r = gcs_r, gce_g = gcs_r, gce_b = gcs_r;
#if IVR_EMISSION
    vreal csr, csg, csb, cer, ceg, ceb;
    tf_piece_color(&s.piece, s.xs, &csr, &csg, &csb);
    tf_piece_color(&s.piece, s.xe, &cer, &ceg, &ceb);
    er = vsel(er, er + at.transmittance * (csr * ls.p + cer * ls.q), go);
    eg = vsel(eg, eg + at.transmittance * (csg * ls.p + ceg * ls.q), go);
    eb = vsel(eb, eb + at.transmittance * (csb * ls.p + ceb * ls.q), go);
    // dL/dτ of the sub-segment through the attenuation of everything behind it.
    const vreal gtau = -(ar->gr * (rem_r - t_in * er) + ar->gg * (rem_g - t_in * eg) +
                         ar->gb * (rem_b - t_in * eb)) +
                       ar->ga * ar->t_end;
    const vreal wr = ar->gr * t_k, wg = ar->gg * t_k, wb = ar->gb * t_k;
    g_a = wr * (csr * ls.dp_da + cer * ls.dq_da) + wg * (csg * ls.dp_da + ceg * ls.dq_da) +
          wb * (csb * ls.dp_da + ceb * ls.dq_da) + (real)0.5 * gtau;
    g_b = wr * (csr * ls.dp_db + cer * ls.dq_db) + wg * (csg * ls.dp_db + ceg * ls.dq_db) +
          wb * (csb * ls.dp_db + ceb * ls.dq_db) + (real)0.5 * gtau;
    gcs_r = wr * ls.p, gcs_g = wg * ls.p, gcs_b = wb * ls.p;
    gce_r = wr * ls.q, gce_g = wg * ls.q, gce_b = wb * ls.q;
#else
    (void)t_k;
    const vreal gtau = -ar->intensity * ar->gi;
    g_a = g_b = (real)0.5 * gtau;
#endif
    attenuation_add_where(&at, (real)0.5 * (sig_s + sig_e) * length, ls.p + ls.q, go);
    const vreal g_sig_s = g_a * length, g_sig_e = g_b * length;  // dL/dσ at the two ends
    const vreal g_len = g_a * sig_s + g_b * sig_e;               // dL/d length
#if IVR_GRAD_CAMERA
    *direct += g_len * length;
#else
    (void)direct;
#endif
    // The ends: a segment end moves with its sample's density; a knot stays at its density but
    // moves along the segment, φ = (knot − da)/(db − da).
    const vreal inv_delta = (real)1 / c.delta;  // cut segments only: |db − da| above the minimum
    {
      const vreal g_phi = -dt * g_len;
      const vreal na = vsel(*gd_a + (g_sig_s * s.piece.s1 + gcs_r * s.piece.c1r +
                                     gcs_g * s.piece.c1g + gcs_b * s.piece.c1b),
                            *gd_a - g_phi * ((real)1 - s.phis) * inv_delta, s.knot_s);
      const vreal nb = vsel(*gd_b, *gd_b - g_phi * s.phis * inv_delta, s.knot_s);
      *gd_a = vsel(*gd_a, na, go);
      *gd_b = vsel(*gd_b, nb, go);
    }
    {
      const vreal g_phi = dt * g_len;
      const vreal na = vsel(*gd_a, *gd_a - g_phi * ((real)1 - s.phie) * inv_delta, s.knot_e);
      const vreal nb = vsel(*gd_b + (g_sig_e * s.piece.s1 + gce_r * s.piece.c1r +
                                     gce_g * s.piece.c1g + gce_b * s.piece.c1b),
                            *gd_b - g_phi * s.phie * inv_delta, s.knot_e);
      *gd_a = vsel(*gd_a, na, go);
      *gd_b = vsel(*gd_b, nb, go);
    }
#if IVR_GRAD_TF
    tf_scatter_piece_where(&s.piece, s.xs, g_sig_s, gcs_r, gcs_g, gcs_b, go, tf_cache, tf_acc);
    tf_scatter_piece_where(&s.piece, s.xe, g_sig_e, gce_r, gce_g, gce_b, go, tf_cache, tf_acc);
#else
    (void)tf_cache, (void)tf_acc;
#endif
  }
  *cursor = c.cursor;
#if IVR_EMISSION
  accumulate_where(pr, kr, t_in * er, live);
  accumulate_where(pg, kg, t_in * eg, live);
  accumulate_where(pb, kb, t_in * eb, live);
#else
  (void)pr, (void)pg, (void)pb, (void)kr, (void)kg, (void)kb;
#endif
  *transmittance = vsel(*transmittance, attenuation_apply(&at, t_in), live);
}

#endif
