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

#if IVR_RAYS == 1  // one ray per work-item (kernels/rays.cl)

inline void tangent_march_exact(__global const real* volume, int4 dims, const March* m, Ray ray,
                                real4 inv_voxel, __global const real* tf, int tf_count,
                                real4 tf_scalars, real min_transmittance,
                                __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                Radiance* r) {
  real tau = (real)0, k = (real)0;
  const real tau_stop = min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
  real dtau[IVR_LANES];
  IVR_FOR_LANES(p) dtau[p] = (real)0;
  Pieces pieces;
  pieces_begin(&pieces, m, dims, m->t0);
  real ta, tb, t_last = m->t0;
  int last_axis = -1;
  while (pieces_next(&pieces, m, dims, &ta, &tb)) {
    t_last = tb;
    last_axis = pieces.axis;
    if (!(tb > ta)) continue;
#if IVR_EMPTY_SPACE
    if (pieces_skip_empty(&pieces, m, dims, ta, tb, occupied, bricks)) continue;
#endif
    const PieceCell pc = piece_cell(m, dims, ta, tb);
    real v[8];
    piece_corners(volume, dims, pc, v);
    const Cubic c = piece_cubic(v, pc);
    const real length = tb - ta;
    uint nodes = 0;
    accumulate(&tau, &k, piece_optical_depth(&c, length, tf, tf_count, tf_scalars, &nodes));
    r->samples += nodes;
    SubPieces sp;
    sub_pieces_begin(&sp, c);
    int cursor = 0;
    SimpsonNodes n;
    while (simpson_nodes_next(&sp, length, tf, tf_count, tf_scalars, &cursor, &n)) {
      const real* s = n.s;
      const TfPiece tp = n.tf;
      const real sub = n.length;
      for (int j = 0; j < 3; ++j) {
        const real w = sub * (j == 1 ? (real)4 : (real)1) / (real)6;  // Simpson's weights
        real gx, gy, gz;
        piece_gradient(v, pc, s[j], &gx, &gy, &gz);
        const real t = ta + s[j] * length;
        const real fx = pc.fx + s[j] * pc.gx, fy = pc.fy + s[j] * pc.gy, fz = pc.fz + s[j] * pc.gz;
        // At a fixed t the nodes are quadrature points of ∫σ(d(o + t·dir))dt: they do not slide.
        IVR_FOR_LANES(p)
        dtau[p] += w * tp.s1 *
                   density_tangent(tr, p, ray, t, (real)0, gx, gy, gz, pc.ix, pc.iy, pc.iz, fx, fy,
                                   fz, dims, inv_voxel);
      }
#if IVR_TANGENT_TF
      const real mean = simpson_mean(&n);
      IVR_FOR_LANES(p) {
        if (tr->lane[p].x != IVR_LANE_TF) continue;
        real ds, dr, dg, db;
        tf_piece_partial(&tp, mean, tr->lane[p].y, tr->lane[p].z, &ds, &dr, &dg, &db);
        dtau[p] += sub * ds;  // ∂σ/∂θ is linear in the density inside the piece
      }
#endif
    }
#if IVR_EARLY_TERMINATION
    if (tau > tau_stop) break;
#endif
  }
  r->transmittance = exp(-tau);
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

#endif  // IVR_RAYS == 1

#endif
