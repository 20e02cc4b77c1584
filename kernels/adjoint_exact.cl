// adjoint_exact.cl — the adjoint of the exact (absorption) integrator: I = I_in·exp(−τ) with τ the
// exact integral, so dL/dτ is one number for the whole ray, and each sub-piece's Simpson nodes
// (exact for σ linear in the density) carry it to the voxels, the TF rows and the camera. Moving
// a piece boundary changes nothing (σ is continuous across it); only the ray's own ends do.
#ifndef IVR_ADJOINT_EXACT_CL
#define IVR_ADJOINT_EXACT_CL
#ifndef IVR_SCHEME  // compiled on its own: this file's scheme (exact)
#define IVR_SCHEME 2
#endif
#include "adjoint_ray.cl"
#include "empty_space.cl"
#include "exact.cl"

// One ray, or every ray of a packet (kernels/rays.cl; no camera gradient), written once as
// primal.cl's marches are: the pieces of [window_start, window_end] (in core the ray's [t0, t1])
// from the at->i-th piece on (the primal march's count, ar->end, stops it where it stopped), dL/dτ
// being one number for the whole ray; at->i is left counting the pieces taken. Out of core
// (kernels/bricked_adjoint.cl) a window is the ray's part in a brick: every piece lies between
// voxel-centre planes, so in one brick.
inline void adjoint_march_exact_window(__global const real* volume, int4 dims, const March* m,
                                       Ray ray, real4 inv_voxel, __global const real* tf,
                                       int tf_count, real4 tf_scalars, const AdjointRay* ar,
                                       __global const uchar* occupied, int4 bricks,
                                       const ScatterSink grad_volume, TfGradCache* tf_cache,
                                       __local real* tf_acc, CameraSums* cs, vreal window_start,
                                       vreal window_end, AdjointPrefix* at) {
  const vreal gtau = -ar->intensity * ar->gi;  // dL/dτ, the same for every piece
  CellCache cell;
  cell_init(&cell, grad_volume, at->flushed);
  March w = *m;
  w.t1 = window_end;
  Pieces p;
  pieces_begin(&p, &w, dims, window_start);
  vreal ta = window_start, tb = window_start;
#if IVR_GRAD_CAMERA
  real t_last = m->t0;
  int last_axis = -1;
#endif
  vint count = at->i;
  vint live = count < ar->end, go;
  while (vany(go = pieces_next_where(&p, &w, dims, live, &ta, &tb))) {
    count += vcount(go);
    live = live && (count < ar->end);
#if IVR_GRAD_CAMERA
    t_last = tb;
    last_axis = p.axis;
#endif
    vint take = go && vmask_of(tb > ta);
#if IVR_EMPTY_SPACE
    if (vany(take))
      take = take && !pieces_skip_empty_where(&p, &w, dims, take, ta, tb, occupied, bricks);
#else
    (void)occupied, (void)bricks;
#endif
    if (!vany(take)) continue;
    const PieceCell pc = piece_cell(&w, dims, ta, tb);
    cell_enter(&cell, pc.ix, pc.iy, pc.iz, volume, dims, grad_volume, take);
    vreal v[8];
    for (int k = 0; k < 8; ++k) v[k] = IVR_CORNER_LANES(cell.v[k]);
    const Cubic c = piece_cubic(v, pc);
    const vreal length = tb - ta;
    SubPieces sp;
    sub_pieces_begin(&sp, c);
    sp.s = vsel(sp.s, (vreal)(real)1, !take);  // (idle rays: nothing to cover)
    vint cursor = (vint)0, sub;
    SimpsonNodes n;
    while (vany(sub = simpson_nodes_next(&sp, length, tf, tf_count, tf_scalars, &cursor, &n))) {
      for (int k = 0; k < 3; ++k) {
        // Simpson's weights (1, 4, 1)/6 of dL/dτ · dσ/dd at the node.
        const vreal gd = vsel((vreal)(real)0,
                              gtau * n.tf.s1 * n.length * (k == 1 ? (real)4 : (real)1) / (real)6,
                              sub);
        cell_add(&cell, gd, pc.fx + n.s[k] * pc.gx, pc.fy + n.s[k] * pc.gy,
                 pc.fz + n.s[k] * pc.gz);
#if IVR_GRAD_CAMERA
        real ngx, ngy, ngz;
        piece_gradient(v, pc, n.s[k], &ngx, &ngy, &ngz);
        const real t = ta + n.s[k] * length;
        const real px = gd * ngx * inv_voxel.x, py = gd * ngy * inv_voxel.y,
                   pz = gd * ngz * inv_voxel.z;
        cs->gpx += px, cs->gpy += py, cs->gpz += pz;
        cs->gtx += t * px, cs->gty += t * py, cs->gtz += t * pz;
#endif
      }
#if IVR_GRAD_TF
      tf_scatter_piece_where(&n.tf, simpson_mean(&n), gtau * n.length, (vreal)(real)0,
                             (vreal)(real)0, (vreal)(real)0, sub, tf_cache, tf_acc);
#else
      (void)tf_cache, (void)tf_acc;
#endif
    }
  }
  at->flushed = cell_flush(&cell, grad_volume);
#if IVR_GRAD_CAMERA
  // The ray's ends: dτ/dt0 = −σ(t0), dτ/dt_end = σ(t_end); t_end is the box (or, stopped early,
  // the centre plane that ended the last piece).
  int cursor = 0;
  real er, eg, eb;
  const real t0 = m->t0;
  const real sigma0 = tf_sample(
      trilinear_at(volume, dims, IVR_POINT(m, t0, x), IVR_POINT(m, t0, y), IVR_POINT(m, t0, z)),
      tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb);
  // Stopped early where the walk has ray left (a jump over empty space to the end leaves none).
  const bool early = p.t < m->t1;
  const real t_end = early ? t_last : m->t1;
  const real sigma1 = tf_sample(trilinear_at(volume, dims, IVR_POINT(m, t_end, x),
                                             IVR_POINT(m, t_end, y), IVR_POINT(m, t_end, z)),
                                tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb);
  cs->dldt0 = -gtau * sigma0;
  cs->dldt1 = gtau * sigma1;
  cs->t_end = t_end;
  cs->end_axis = early ? last_axis : -1;
#else
  (void)ray, (void)inv_voxel, (void)cs;
#endif
  at->i = count;
}

// The whole ray's adjoint march (in core).
inline void adjoint_march_exact(__global const real* volume, int4 dims, const March* m, Ray ray,
                                real4 inv_voxel, __global const real* tf, int tf_count,
                                real4 tf_scalars, const AdjointRay* ar,
                                __global const uchar* occupied, int4 bricks,
                                const ScatterSink grad_volume, TfGradCache* tf_cache,
                                __local real* tf_acc, CameraSums* cs) {
  AdjointPrefix at = adjoint_prefix_begin();
  adjoint_march_exact_window(volume, dims, m, ray, inv_voxel, tf, tf_count, tf_scalars, ar,
                             occupied, bricks, grad_volume, tf_cache, tf_acc, cs, m->t0, m->t1,
                             &at);
  adjoint_ray_end(grad_volume, at.flushed);
}

#endif
