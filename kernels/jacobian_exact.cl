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
// camera lanes take one ray per work-item). The pieces of [window_start, window_end] (in core the
// ray's [t0, t1]), their optical depth summed on in r->tau and its tangents in tr->dT (dτ until
// tangent_finish), with the ray's own ends where the window holds them: its entry t0 in the
// window that starts there, its end (the box, or the centre plane where the march stopped early)
// in the window that ends there. Out of core (kernels/bricked_tangent.cl) a window is the ray's
// part in one brick (every piece lies between centre planes, so in one brick), and `end_axis`
// the axis of the brick plane that ends it (in core: -1), where a ray stopped early at the
// window's end ends, as in core at that centre plane.
inline void tangent_march_exact_window(__global const real* volume, int4 dims, const March* m,
                                       Ray ray, real4 inv_voxel, __global const real* tf,
                                       int tf_count, real4 tf_scalars, real min_transmittance,
                                       __global const uchar* occupied, int4 bricks,
                                       TangentRay* tr, Radiance* r, vreal window_start,
                                       vreal window_end, int end_axis) {
  const real tau_stop = min_transmittance > (real)0 ? -log(min_transmittance) : (real)INFINITY;
  March w = *m;
  w.t1 = window_end;
  Pieces pieces;
  pieces_begin(&pieces, &w, dims, window_start);
  vreal ta = window_start, tb = window_start, t_last = window_start;
  vint last_axis = (vint)-1, live = vtrue, go;
  while (vany(go = pieces_next_where(&pieces, &w, dims, live, &ta, &tb))) {
    t_last = vsel(t_last, tb, go);
    last_axis = vseli(last_axis, pieces.axis, go);
    vint take = go && vmask_of(tb > ta);
#if IVR_EMPTY_SPACE
    if (vany(take))
      take = take && !pieces_skip_empty_where(&pieces, &w, dims, take, ta, tb, occupied, bricks);
#else
    (void)occupied, (void)bricks;
#endif
    if (!vany(take)) continue;
    // (Clamped at the volume's border only: out of core not at a brick's inner faces, where a ray
    // lying on the plane still has the one-sided derivative the in-core march takes.)
    const PieceCell pc = piece_cell_within(&w, dims, ta, tb, tr->grid_lo, tr->grid_hi);
    vreal v[8];
    piece_corners(volume, dims, pc, v);
    const Cubic c = piece_cubic(v, pc);
    const vreal length = tb - ta;
    vint nodes = (vint)0;
    accumulate_where(&r->tau, &r->ktau,
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
        const vreal wj = sub * (j == 1 ? (real)4 : (real)1) / (real)6;  // Simpson's weights
        vreal gx, gy, gz;
        piece_gradient(v, pc, s[j], &gx, &gy, &gz);
        const vreal t = ta + s[j] * length;
        const vreal fx = pc.fx + s[j] * pc.gx, fy = pc.fy + s[j] * pc.gy,
                    fz = pc.fz + s[j] * pc.gz;
        // At a fixed t the nodes are quadrature points of ∫σ(d(o + t·dir))dt: they do not slide.
        IVR_FOR_LANES(p)
        tr->dT[p] = vsel(tr->dT[p],
                         tr->dT[p] + wj * tp.s1 *
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
        tr->dT[p] = vsel(tr->dT[p], tr->dT[p] + sub * ds, here);
      }
#endif
    }
#if IVR_EARLY_TERMINATION
    live = live && !vmask_of(r->tau > tau_stop);
#endif
  }
#if IVR_TANGENT_CAMERA
  // The ends this window holds (one ray): the box (or, stopped early, the centre plane that ended
  // the last piece), and where the ray enters.
  // Stopped early: before the window's end, or (out of core) at it, short of the ray's end.
#if IVR_EARLY_TERMINATION
  const bool stopped = r->tau > tau_stop;
#else
  const bool stopped = false;
#endif
  const bool at_window_end = !(pieces.t < w.t1) && window_end < m->t1;
  const bool early = pieces.t < w.t1 || (stopped && at_window_end);
  if (early && at_window_end && last_axis < 0) last_axis = end_axis;
  const bool first = window_start == m->t0, last = early || window_end >= m->t1;
  const real t_end = early ? t_last : m->t1;
  int cursor = 0;
  real er, eg, eb;
  const real sigma0 =
      first ? tf_sample(trilinear_at(volume, dims, IVR_POINT(m, m->t0, x),
                                     IVR_POINT(m, m->t0, y), IVR_POINT(m, m->t0, z)),
                        tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb)
            : (real)0;
  const real sigma1 =
      last ? tf_sample(trilinear_at(volume, dims, IVR_POINT(m, t_end, x),
                                    IVR_POINT(m, t_end, y), IVR_POINT(m, t_end, z)),
                       tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb)
           : (real)0;
  IVR_FOR_LANES(p) {
    const real dt_end = early ? plane_t_tangent(tr, p, ray, last_axis, t_end) : tr->dt1[p];
    if (first && last)
      tr->dT[p] += sigma1 * dt_end - sigma0 * tr->dt0[p];
    else if (first)
      tr->dT[p] -= sigma0 * tr->dt0[p];
    else if (last)
      tr->dT[p] += sigma1 * dt_end;
  }
#else
  (void)t_last, (void)last_axis, (void)end_axis;
#endif
}

// The whole ray (in core), finished: I = I_in·e^−τ.
inline void tangent_march_exact(__global const real* volume, int4 dims, const March* m, Ray ray,
                                real4 inv_voxel, __global const real* tf, int tf_count,
                                real4 tf_scalars, real min_transmittance,
                                __global const uchar* occupied, int4 bricks, TangentRay* tr,
                                Radiance* r) {
  IVR_FOR_LANES(p) tr->dT[p] = (vreal)(real)0;
  tangent_march_exact_window(volume, dims, m, ray, inv_voxel, tf, tf_count, tf_scalars,
                             min_transmittance, occupied, bricks, tr, r, m->t0, m->t1, -1);
  tangent_finish(tr, r);
}

#endif
