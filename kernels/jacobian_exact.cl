// jacobian_exact.cl — the exact (absorption) march carrying the tangent lanes: dτ of each sub-piece
// by its Simpson nodes (exact: the integrand's tangent is a cubic there too), plus the ray's own
// ends, dτ/dt0 = −σ(t0), dτ/dt_end = σ(t_end); then I = I_in·e^−τ.
#ifndef IVR_TANGENT_EXACT_CL
#define IVR_TANGENT_EXACT_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (exact)
#define IVR_SCHEME 2
#endif
#include "empty_space.cl"
#include "exact.cl"
#include "primal.cl"
#include "jacobian_ray.cl"
#include "jacobian_tf.cl"
#include "rays.cl"

// One ray, or a packet of rays in vector lanes (kernels/rays.cl; TF and background lanes only:
// camera lanes take one ray per work-item).
inline void tangent_march_exact(__global const real* volume, int4 dims, const March* m, Ray ray,
                                real4 inv_voxel, __global const real* tf, int tf_count,
                                real4 tf_scalars, real min_transmittance,
                                __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                Radiance* r) {
  vreal tau = (vreal)(real)0, k = tau;
  const real tau_stop = min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
  vreal dtau[IVR_LANES];
  IVR_FOR_LANES(p) dtau[p] = (vreal)(real)0;
  Pieces pieces;
  pieces_begin(&pieces, m, dims, m->t0);
  vreal ta = m->t0, tb = m->t0, t_last = m->t0;
  vint last_axis = (vint)-1, live = vtrue, go;
  while (vany(go = pieces_next_where(&pieces, m, dims, live, &ta, &tb))) {
    t_last = vsel(t_last, tb, go);
    last_axis = vseli(last_axis, pieces.axis, go);
    vint take = go && vmask_of(tb > ta);
#if IVR_EMPTY_SPACE
    if (vany(take))
      take = take && !pieces_skip_empty_where(&pieces, m, dims, take, ta, tb, occupied, bricks);
#else
    (void)occupied, (void)bricks;
#endif
    if (!vany(take)) continue;
    const PieceCell pc = piece_cell(m, dims, ta, tb);
    vreal v[8];
    piece_corners(volume, dims, pc, v);
    const Cubic c = piece_cubic(v, pc);
    const vreal length = tb - ta;
    vint nodes = (vint)0;
    accumulate_where(&tau, &k,
                     piece_optical_depth_where(&c, length, tf, tf_count, tf_scalars, take, &nodes),
                     take);
    r->samples += nodes;
    SubPieces sp;
    sub_pieces_begin(&sp, c);
    sp.s = vsel(sp.s, (vreal)(real)1, !take);  // (idle rays: nothing to cover)
    vint cursor = (vint)0, here;
    SimpsonNodes n;
    while (vany(here = simpson_nodes_next(&sp, length, tf, tf_count, tf_scalars, &cursor, &n))) {
      const vreal* s = n.s;
      const TfPiece tp = n.tf;
      const vreal sub = n.length;
      for (int j = 0; j < 3; ++j) {
        const vreal w = sub * (j == 1 ? (real)4 : (real)1) / (real)6;  // Simpson's weights
        vreal gx, gy, gz;
        piece_gradient(v, pc, s[j], &gx, &gy, &gz);
        const vreal t = ta + s[j] * length;
        const vreal fx = pc.fx + s[j] * pc.gx, fy = pc.fy + s[j] * pc.gy,
                    fz = pc.fz + s[j] * pc.gz;
        // At a fixed t the nodes are quadrature points of ∫σ(d(o + t·dir))dt: they do not slide.
        IVR_FOR_LANES(p)
        dtau[p] = vsel(dtau[p],
                       dtau[p] + w * tp.s1 *
                                     density_tangent(tr, p, ray, t, (vreal)(real)0, gx, gy, gz,
                                                     pc.ix, pc.iy, pc.iz, fx, fy, fz, dims,
                                                     inv_voxel),
                       here);
      }
#if IVR_TANGENT_TF
      const vreal mean = simpson_mean(&n);
      IVR_FOR_LANES(p) {
        if (tr->lane[p].x != IVR_LANE_TF) continue;
        vreal ds, dr, dg, db;
        tf_piece_partial(&tp, mean, tr->lane[p].y, tr->lane[p].z, &ds, &dr, &dg, &db);
        // ∂σ/∂θ is linear in the density inside the piece
        dtau[p] = vsel(dtau[p], dtau[p] + sub * ds, here);
      }
#endif
    }
#if IVR_EARLY_TERMINATION
    live = live && !vmask_of(tau > tau_stop);
#endif
  }
  r->transmittance = vexp(-tau);
#if IVR_TANGENT_CAMERA
  // The ends: the box (or, stopped early, the centre plane that ended the last piece).
  const bool early = pieces.t < m->t1;
  const real t_end = early ? t_last : m->t1;
  int cursor = 0;
  real er, eg, eb;
  const real sigma0 = tf_sample(trilinear_at(volume, dims, m->u0x + m->t0 * m->dux,
                                             m->u0y + m->t0 * m->duy, m->u0z + m->t0 * m->duz),
                                tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb);
  const real sigma1 = tf_sample(trilinear_at(volume, dims, m->u0x + t_end * m->dux,
                                             m->u0y + t_end * m->duy, m->u0z + t_end * m->duz),
                                tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb);
  IVR_FOR_LANES(p) {
    const real dt_end = early ? plane_t_tangent(tr, p, ray, last_axis, t_end) : tr->dt1[p];
    dtau[p] += sigma1 * dt_end - sigma0 * tr->dt0[p];
  }
#else
  (void)t_last, (void)last_axis;
#endif
  IVR_FOR_LANES(p) tr->dT[p] = -r->transmittance * dtau[p];
}

#endif
