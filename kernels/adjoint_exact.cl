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

// One ray per work-item: the adjoint marches packets for the midpoint rule only
// (lib/adjoint/adjoint.cpp, use_packet_adjoint).
#if IVR_RAYS == 1

inline void adjoint_march_exact(__global const real* volume, int4 dims, const March* m, Ray ray,
                                real4 inv_voxel, __global const real* tf, int tf_count,
                                real4 tf_scalars, const AdjointRay* ar,
                                __global const uchar* occupied, int4 bricks,
                                const ScatterSink grad_volume, TfGradCache* tf_cache,
                                __local real* tf_acc, CameraSums* cs) {
  const real gtau = -ar->intensity * ar->gi;  // dL/dτ, the same for every piece
  CellCache cell;
  cell_init(&cell);
  Pieces p;
  pieces_begin(&p, m, dims, m->t0);
  real ta, tb, t_last = m->t0;
  int last_axis = -1;
  for (uint count = 0; count < ar->end && pieces_next(&p, m, dims, &ta, &tb); ++count) {
    t_last = tb;
    last_axis = p.axis;
    if (!(tb > ta)) continue;
#if IVR_EMPTY_SPACE
    if (pieces_skip_empty(&p, m, dims, ta, tb, occupied, bricks)) continue;
#endif
    const PieceCell pc = piece_cell(m, dims, ta, tb);
    cell_enter(&cell, pc.ix, pc.iy, pc.iz, volume, dims, grad_volume, 1);
    const Cubic c = piece_cubic(IVR_CELL_CORNERS(&cell), pc);
    const real length = tb - ta;
    SubPieces sp;
    sub_pieces_begin(&sp, c);
    int cursor = 0;
    SimpsonNodes n;
    while (simpson_nodes_next(&sp, length, tf, tf_count, tf_scalars, &cursor, &n)) {
      const real* s = n.s;
      const TfPiece tp = n.tf;
      const real sub = n.length;
      for (int k = 0; k < 3; ++k) {
        // Simpson's weights (1, 4, 1)/6 of dL/dτ · dσ/dd at the node.
        const real gd = gtau * tp.s1 * sub * (k == 1 ? (real)4 : (real)1) / (real)6;
        cell_add(&cell, gd, pc.fx + s[k] * pc.gx, pc.fy + s[k] * pc.gy, pc.fz + s[k] * pc.gz);
#if IVR_GRAD_CAMERA
        real ngx, ngy, ngz;
        piece_gradient(IVR_CELL_CORNERS(&cell), pc, s[k], &ngx, &ngy, &ngz);
        const real t = ta + s[k] * length;
        const real px = gd * ngx * inv_voxel.x, py = gd * ngy * inv_voxel.y,
                   pz = gd * ngz * inv_voxel.z;
        cs->gpx += px, cs->gpy += py, cs->gpz += pz;
        cs->gtx += t * px, cs->gty += t * py, cs->gtz += t * pz;
#endif
      }
#if IVR_GRAD_TF
      tf_scatter_piece(&tp, simpson_mean(&n), gtau * sub, (real)0, (real)0,
                       (real)0, tf_cache, tf_acc);
#else
      (void)tf_cache, (void)tf_acc;
#endif
    }
  }
  cell_flush(&cell, grad_volume);
#if IVR_GRAD_CAMERA
  // The ray's ends: dτ/dt0 = −σ(t0), dτ/dt_end = σ(t_end); t_end is the box (or, stopped early,
  // the centre plane that ended the last piece).
  int cursor = 0;
  real er, eg, eb;
  const real t0 = m->t0;
  const real sigma0 = tf_sample(
      trilinear_at(volume, dims, m->u0x + t0 * m->dux, m->u0y + t0 * m->duy, m->u0z + t0 * m->duz),
      tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb);
  // Stopped early where the walk has ray left (a jump over empty space to the end leaves none).
  const bool early = p.t < m->t1;
  const real t_end = early ? t_last : m->t1;
  const real sigma1 = tf_sample(trilinear_at(volume, dims, m->u0x + t_end * m->dux,
                                             m->u0y + t_end * m->duy, m->u0z + t_end * m->duz),
                                tf, tf_count, tf_scalars, &cursor, &er, &eg, &eb);
  cs->dldt0 = -gtau * sigma0;
  cs->dldt1 = gtau * sigma1;
  cs->t_end = t_end;
  cs->end_axis = early ? last_axis : -1;
#else
  (void)ray, (void)inv_voxel, (void)t_last, (void)last_axis;
#endif
}

#endif  // IVR_RAYS == 1
#endif
