// exact.cl — the `exact` integrator's traversal: a ray cut where it crosses the planes through the
// voxel centres (between two such crossings every trilinear weight is linear along the ray, so the
// density is a cubic there, docs/design.md) and, inside those pieces, where the density crosses a knot
// of the TF (then σ is linear in the density, a cubic along the ray: Simpson's rule is exact).
// Used by the render, both gradient modes and the absorption projector.
#ifndef IVR_EXACT_CL
#define IVR_EXACT_CL
#include "config.cl"
#include "empty_space.cl"
#include "march.cl"
#include "tf.cl"
#include "rays.cl"

// Every function below takes one ray or a packet of rays in vector lanes (kernels/rays.cl): each
// ray of a packet walks its own planes, cells, knots and roots by masked loops, and every lane
// computes what one ray computes.

// --- Pieces: the ray between consecutive centre-plane crossings --------------------------------

// Coordinates are global: u = u0 + t·du is the ray in the whole volume's voxel-centre coordinates,
// in core and out of core alike, so a brick's march computes the in-core march's plane crossings,
// cells and fractions bit for bit. The voxels a march reads are the grid origin … origin + dims − 1
// (in core 0 … N − 1; out of core a brick's, origin = its first voxel: the march's o, kernels/
// march.cl); planes and cells outside it are none, and a cell's index (PieceCell) is in it.

// The march's grid origin (its first voxel read): exact, o holds an integer.
inline int4 march_grid_origin(const March* m) {
  return (int4)((int)m->ox, (int)m->oy, (int)m->oz, 0);
}

// The plane of axis index k (u = k) is crossed at t = (k − u0) / du.
typedef struct {
  vreal t, t1;       // start of the next piece; the ray's end in the box
  vreal tx, ty, tz;  // next crossing per axis (+inf: none left)
  vint kx, ky, kz;   // its plane index
  vint sx, sy, sz;   // direction of travel in u (+1, -1, 0)
  vint axis;         // axis of the plane that ended the last piece, -1: the box (or none)
} Pieces;

// The first plane crossed after u (moving with sign s) on an axis whose grid holds the planes
// o … o + n − 1, its index in *k. (u is clamped to [o − 1, o + n] before its conversion: a plane
// beyond either end is none all the same.)
inline vreal first_plane(vreal u0, vreal du, vreal u, int o, int n, vint* k, vint* s) {
  const vint up = vmask_of(du > (real)0), down = vmask_of(du < (real)0);
  *s = vseli(vseli((vint)0, (vint)-1, down), (vint)1, up);
  const vint k_up = vseli(vto_int(floor(fmin(u, (real)(o + n)))) + 1, (vint)o,
                          vmask_of(u < (real)o));
  const vint k_down = vseli(vto_int(ceil(fmax(u, (real)(o - 1)))) - 1, (vint)(o + n - 1),
                            vmask_of(u > (real)(o + n - 1)));
  *k = vseli(k_down, k_up, up);
  const vint inside = (up && *k <= o + n - 1) || (down && *k >= o);
  return vsel((vreal)(real)INFINITY, (vto_real(*k) - u0) / du, inside);
}

// The plane after *k, where m is true.
inline vreal next_plane(vreal u0, vreal du, int o, int n, vint* k, vint s, vint m) {
  *k = vseli(*k, *k + s, m);
  return vsel((vreal)(real)INFINITY, (vto_real(*k) - u0) / du, *k >= o && *k <= o + n - 1);
}

// Starts the pieces at ray parameter t (t0, a brick window's start, or where a jump over empty
// space lands).
inline void pieces_begin(Pieces* p, const March* m, int4 dims, vreal t) {
  const int4 o = march_grid_origin(m);
  p->t = t;
  p->t1 = m->t1;
  p->axis = (vint)-1;
  p->tx = first_plane(m->u0x, m->dux, m->u0x + t * m->dux, o.x, dims.x, &p->kx, &p->sx);
  p->ty = first_plane(m->u0y, m->duy, m->u0y + t * m->duy, o.y, dims.y, &p->ky, &p->sy);
  p->tz = first_plane(m->u0z, m->duz, m->u0z + t * m->duz, o.z, dims.z, &p->kz, &p->sz);
}

// The next piece [*ta, *tb] (possibly of length 0 where planes meet) of the rays where `live` is
// true and some ray is left; returns those rays. A plane whose crossing rounds before the piece's
// start (u(t) rounded to its near side where a walk begins at t: a brick's window, a jump) ends a
// piece of length 0 there, never one that reaches back.
inline vint pieces_next_where(Pieces* p, const March* m, int4 dims, vint live, vreal* ta,
                              vreal* tb) {
  const vint go = live && vmask_of(p->t < p->t1);
  if (!vany(go)) return go;
  const int4 o = march_grid_origin(m);
  const vreal end = fmax(fmin(fmin(p->tx, p->ty), fmin(p->tz, p->t1)), p->t);
  *ta = p->t;
  *tb = end;
  p->axis = vseli(p->axis,
                  vseli(vseli(vseli((vint)2, (vint)1, vmask_of(end == p->ty)), (vint)0,
                              vmask_of(end == p->tx)),
                        (vint)-1, vmask_of(end == p->t1)),
                  go);
  // Every plane crossed at `end` (a ray through a line or a node crosses two or three at once).
  vint c;
  while (vany(c = go && vmask_of(p->tx <= end)))
    p->tx = vsel(p->tx, next_plane(m->u0x, m->dux, o.x, dims.x, &p->kx, p->sx, c), c);
  while (vany(c = go && vmask_of(p->ty <= end)))
    p->ty = vsel(p->ty, next_plane(m->u0y, m->duy, o.y, dims.y, &p->ky, p->sy, c), c);
  while (vany(c = go && vmask_of(p->tz <= end)))
    p->tz = vsel(p->tz, next_plane(m->u0z, m->duz, o.z, dims.z, &p->kz, p->sz, c), c);
  p->t = vsel(p->t, end, go);
  return go;
}

inline vint pieces_next(Pieces* p, const March* m, int4 dims, vreal* ta, vreal* tb) {
  return pieces_next_where(p, m, dims, vtrue, ta, tb);
}

// Empty-space skipping for the pieces: where piece [ta, tb] of an `active` ray lies in an empty
// brick, restarts the ray's walk where it leaves that brick (brick faces are centre planes: a piece
// starts there; or, where rounding counts a sliver on the face as the brick's, where this piece
// ends); returns those rays. The skipped pieces add nothing: σ = 0 there.
inline vint pieces_skip_empty_where(Pieces* p, const March* m, int4 dims, vint active, vreal ta,
                                    vreal tb, __global const uchar* occupied, int4 bricks) {
  const vreal tm = (real)0.5 * (ta + tb);
  const vreal exit = empty_brick_exit(m->u0x + tm * m->dux, m->u0y + tm * m->duy,
                                      m->u0z + tm * m->duz, m, dims, occupied, bricks);
  const vint skip = active && vmask_of(exit >= (real)0);
  if (!vany(skip)) return skip;
  Pieces q;
  pieces_begin(&q, m, dims, fmin(fmax(exit, tb), m->t1));
  p->t = vsel(p->t, q.t, skip), p->axis = vseli(p->axis, q.axis, skip);
  p->tx = vsel(p->tx, q.tx, skip), p->ty = vsel(p->ty, q.ty, skip), p->tz = vsel(p->tz, q.tz, skip);
  p->kx = vseli(p->kx, q.kx, skip), p->ky = vseli(p->ky, q.ky, skip);
  p->kz = vseli(p->kz, q.kz, skip);
  p->sx = vseli(p->sx, q.sx, skip), p->sy = vseli(p->sy, q.sy, skip);
  p->sz = vseli(p->sz, q.sz, skip);
  return skip;
}

inline vint pieces_skip_empty(Pieces* p, const March* m, int4 dims, vreal ta, vreal tb,
                              __global const uchar* occupied, int4 bricks) {
  return pieces_skip_empty_where(p, m, dims, vtrue, ta, tb, occupied, bricks);
}

// --- The density inside one piece: one cell, fractions linear in s ∈ [0, 1] ---------------------

typedef struct {
  vint ix, iy, iz;   // the cell (lower corner voxel) among the voxels read (index − the grid's
                     // origin), clamped as trilinear_at() clamps
  vreal fx, fy, fz;  // fractions at s = 0
  vreal gx, gy, gz;  // their change over the piece (0 along clamped axes)
  vint cx, cy, cz;   // clamped along the axis: the density does not change with u there
} PieceCell;

// (The cell index is in range for any u, NaN included: the gathers of a packet's idle rays read
// inside the volume.)
// The grid holds the centre planes o … o + n − 1; `open_lo`, `open_hi`: its first or last plane
// is not the volume's border (out of core: a brick's inner face), so a piece on it is not clamped.
// *i is the cell less o; the fractions are the global u's, so a brick's are the in-core ones.
inline void piece_axis_within(vreal ua, vreal ub, int o, int n, bool open_lo, bool open_hi,
                              vint* i, vreal* f, vreal* g, vint* clamped) {
  const vreal mid = (real)0.5 * (ua + ub);
  // The border half-voxel below the first centre, and above the last.
  const vint below = (open_lo ? (vint)0 : !vmask_of(mid > (real)o)) || n == 1;
  const vint above = !below && (open_hi ? (vint)0 : vmask_of(mid >= (real)(o + n - 1)));
  const vint inner = !below && !above;
  const vint k = min(vto_int(fmin(fmax(mid, (real)o), (real)(o + n - 1))), o + n - 2);
  const vint cell = vseli(vseli(k, (vint)(o + n - 1), above), (vint)o, below);
  *i = cell - o;
  *f = vsel((vreal)(real)0, ua - vto_real(cell), inner);
  *g = vsel((vreal)(real)0, ub - ua, inner);
  *clamped = !inner;
}

// The piece's cell, clamped at the grid's faces except where `lo`, `hi` are ∓∞ on an axis (the
// out-of-core tangents' grid_lo, grid_hi: a brick's inner faces).
inline PieceCell piece_cell_within(const March* m, int4 dims, vreal ta, vreal tb, real4 lo,
                                   real4 hi) {
  const int4 o = march_grid_origin(m);
  PieceCell c;
  piece_axis_within(m->u0x + ta * m->dux, m->u0x + tb * m->dux, o.x, dims.x, isinf(lo.x) != 0,
                    isinf(hi.x) != 0, &c.ix, &c.fx, &c.gx, &c.cx);
  piece_axis_within(m->u0y + ta * m->duy, m->u0y + tb * m->duy, o.y, dims.y, isinf(lo.y) != 0,
                    isinf(hi.y) != 0, &c.iy, &c.fy, &c.gy, &c.cy);
  piece_axis_within(m->u0z + ta * m->duz, m->u0z + tb * m->duz, o.z, dims.z, isinf(lo.z) != 0,
                    isinf(hi.z) != 0, &c.iz, &c.fz, &c.gz, &c.cz);
  return c;
}

inline PieceCell piece_cell(const March* m, int4 dims, vreal ta, vreal tb) {
  const real4 none = (real4)(real)0;  // (finite: every face of the grid clamps)
  return piece_cell_within(m, dims, ta, tb, none, none);
}

// d density / d u at s inside the piece from the corners v (0 along clamped axes: one-sided at
// the piece's own ends, unlike trilinear_gradient() at a point on a centre plane).
inline void piece_gradient(const vreal* v, PieceCell c, vreal s, vreal* gx, vreal* gy, vreal* gz) {
  const vreal fx = c.fx + s * c.gx, fy = c.fy + s * c.gy, fz = c.fz + s * c.gz;
  const vreal zero = (vreal)(real)0;
  *gx = vsel(vlerp(vlerp(v[1] - v[0], v[3] - v[2], fy), vlerp(v[5] - v[4], v[7] - v[6], fy), fz),
             zero, c.cx);
  *gy = vsel(vlerp(vlerp(v[2] - v[0], v[3] - v[1], fx), vlerp(v[6] - v[4], v[7] - v[5], fx), fz),
             zero, c.cy);
  *gz = vsel(vlerp(vlerp(v[4] - v[0], v[5] - v[1], fx), vlerp(v[6] - v[2], v[7] - v[3], fx), fy),
             zero, c.cz);
}

// The cell's 8 corner densities v[k] (bit 0: +x, bit 1: +y, bit 2: +z; the upper neighbour is the
// voxel itself on the clamped upper edge, as in trilinear_at()).
inline void piece_corners(__global const real* volume, int4 dims, PieceCell c, vreal* v) {
  const vint ox = vseli((vint)0, (vint)1, c.ix + 1 < dims.x);
  const vint oy = vseli((vint)0, (vint)dims.x, c.iy + 1 < dims.y);
  const vint oz = vseli((vint)0, (vint)(dims.x * dims.y), c.iz + 1 < dims.z);
  const vint q = (c.iz * dims.y + c.iy) * dims.x + c.ix;
  v[0] = vgather_off(volume, q, 0), v[1] = vgather_off(volume, q, ox);
  v[2] = vgather_off(volume, q, oy), v[3] = vgather_off(volume, q, oy + ox);
  v[4] = vgather_off(volume, q, oz), v[5] = vgather_off(volume, q, oz + ox);
  v[6] = vgather_off(volume, q, oz + oy), v[7] = vgather_off(volume, q, oz + oy + ox);
}

// d(s) = q0 + s·(q1 + s·(q2 + s·q3)) over the piece.
typedef struct {
  vreal q0, q1, q2, q3;
} Cubic;

inline vreal cubic_at(const Cubic* c, vreal s) {
  return c->q0 + s * (c->q1 + s * (c->q2 + s * c->q3));
}

inline vreal cubic_slope(const Cubic* c, vreal s) {
  return c->q1 + s * ((real)2 * c->q2 + s * (real)3 * c->q3);
}

// The trilinear interpolant along the piece, multiplied out one axis at a time: linear along x,
// quadratic after y, cubic after z.
inline Cubic piece_cubic(const vreal* v, PieceCell c) {
  vreal a0[4], a1[4];
  for (int k = 0; k < 4; ++k) {
    const vreal dv = v[2 * k + 1] - v[2 * k];
    a0[k] = v[2 * k] + dv * c.fx;
    a1[k] = dv * c.gx;
  }
  vreal b0[2], b1[2], b2[2];
  for (int j = 0; j < 2; ++j) {
    const vreal d0 = a0[2 * j + 1] - a0[2 * j], d1 = a1[2 * j + 1] - a1[2 * j];
    b0[j] = a0[2 * j] + d0 * c.fy;
    b1[j] = a1[2 * j] + d0 * c.gy + d1 * c.fy;
    b2[j] = d1 * c.gy;
  }
  const vreal e0 = b0[1] - b0[0], e1 = b1[1] - b1[0], e2 = b2[1] - b2[0];
  Cubic q;
  q.q0 = b0[0] + e0 * c.fz;
  q.q1 = b1[0] + e0 * c.gz + e1 * c.fz;
  q.q2 = b2[0] + e1 * c.gz + e2 * c.fz;
  q.q3 = e2 * c.gz;
  return q;
}

// --- Sub-pieces: where the cubic crosses TF knots
// -------------------------------------------------

// The root of d(s) = target in [lo, hi] for the rays where `live` is true, where d is monotone and
// target lies strictly between d(lo) and d(hi): Newton's method kept inside a shrinking bracket
// (bisection where a step would leave it). σ is continuous at a knot, so the integral is
// insensitive to the root to first order.
#if IVR_F64
#define IVR_EPSILON DBL_EPSILON
#else
#define IVR_EPSILON FLT_EPSILON
#endif
inline vreal cubic_root(const Cubic* c, vreal target, vreal lo, vreal hi, vint live) {
  const vreal flo = cubic_at(c, lo) - target, fhi = cubic_at(c, hi) - target;
  vreal s = lo + (hi - lo) * flo / (flo - fhi);
  const vint lo_negative = vmask_of(flo < (real)0);
  vint run = live;
  for (int it = 0; it < 40; ++it) {
    const vreal f = cubic_at(c, s) - target;
    run = run && vmask_of(f != (real)0);
    if (!vany(run)) break;
    const vint below = vmask_of(f < (real)0) == lo_negative;
    lo = vsel(lo, s, run && below);
    hi = vsel(hi, s, run && !below);
    vreal next = s - f / cubic_slope(c, s);
    next = vsel((real)0.5 * (lo + hi), next, vmask_of(next > lo) && vmask_of(next < hi));
    const vint done = vmask_of(fabs(next - s) <= (real)4 * IVR_EPSILON);
    s = vsel(s, next, run);
    run = run && !done;
  }
  return s;
}

// [s, 1] cut into parts on which d is monotone (by the roots of d' in (0, 1)), then into
// sub-pieces at every knot crossing. A sub-piece may span a turning point: only knots split.
typedef struct {
  Cubic c;
  vreal r[4];  // part boundaries: r[0] = 0 < … < r[parts] = 1 (1 beyond)
  vint parts, part;
  vreal s, ds;  // start of the next sub-piece, and its density (a knot's exact value after a cut)
} SubPieces;

// Part boundary i (0 ≤ i ≤ 3) of every ray.
inline vreal sub_pieces_bound(const SubPieces* sp, vint i) {
  return vsel(vsel(vsel(sp->r[3], sp->r[2], i == 2), sp->r[1], i == 1), sp->r[0], i == 0);
}

inline void sub_pieces_begin(SubPieces* sp, Cubic c) {
  sp->c = c;
  // Roots of d'(s) = 3 q3 s² + 2 q2 s + q1 in (0, 1), by the stable quadratic formula.
  const vreal a = (real)3 * c.q3, b = (real)2 * c.q2, cc = c.q1;
  const vint linear = vmask_of(a == (real)0);
  const vreal disc = b * b - (real)4 * a * cc;
  const vint two = vmask_of(disc > (real)0);
  const vreal q = (real)-0.5 * (b + copysign(sqrt(fmax(disc, (real)0)), b));
  const vreal root0 = vsel(q / a, -cc / b, linear), root1 = cc / q;
  const vint has0 = vseli(two, vmask_of(b != (real)0), linear);
  const vint has1 = !linear && two && vmask_of(q != (real)0);
  const vint swap = has0 && has1 && vmask_of(root1 < root0);
  const vreal lo = vsel(root0, root1, swap), hi = vsel(root1, root0, swap);
  const vint take0 = has0 && vmask_of(lo > (real)0) && vmask_of(lo < (real)1);
  const vint take1 =
      has1 && vmask_of(hi > vsel((vreal)(real)0, lo, take0)) && vmask_of(hi < (real)1);
  const vreal one = (vreal)(real)1;
  sp->r[0] = (vreal)(real)0;
  sp->r[1] = vsel(vsel(one, hi, take1), lo, take0);
  sp->r[2] = vsel(one, hi, take0 && take1);
  sp->r[3] = one;
  sp->parts = (vint)1 + vcount(take0) + vcount(take1);
  sp->part = (vint)0;
  sp->s = (vreal)(real)0;
  sp->ds = c.q0;
}

// The next sub-piece [*sa, *sb] of every ray with [0, 1] not yet covered; returns those rays.
inline vint sub_pieces_next(SubPieces* sp, __global const real* tf, int count, real4 scalars,
                            vreal* sa, vreal* sb) {
  const vint go = vmask_of(sp->s < (real)1);
  if (!vany(go)) return go;
  *sa = sp->s;
  *sb = (vreal)(real)1;
  vreal x = sp->ds;  // density where the search stands
  vint found = (vint)0;
  vint search = go && sp->part < sp->parts;
  while (vany(search)) {
    const vreal end = sub_pieces_bound(sp, sp->part + 1), dend = cubic_at(&sp->c, end);
    const vint direction = vseli(vseli((vint)0, (vint)-1, vmask_of(dend < x)), (vint)1,
                                 vmask_of(dend > x));
    vint cursor = (vint)0;
    vreal knot = x;
    vint cut = search && direction != 0;
    if (vany(cut))
      cut = cut &&
            tf_next_knot(x, tf_interval(x, tf, count, scalars, &cursor), direction, tf, count,
                         scalars, &knot) &&
            vseli(vmask_of(knot > dend), vmask_of(knot < dend), direction > 0);
    if (vany(cut)) {
      const vreal root =
          cubic_root(&sp->c, knot, fmax(sp->s, sub_pieces_bound(sp, sp->part)), end, cut);
      *sb = vsel(*sb, root, cut);
      sp->s = vsel(sp->s, root, cut);
      sp->ds = vsel(sp->ds, knot, cut);
      found = found || cut;
    }
    // No knot in this part: the search moves on, the sub-piece goes on.
    const vint on = search && !cut;
    x = vsel(x, dend, on);
    sp->part += vcount(on);
    search = on && sp->part < sp->parts;
  }
  sp->s = vsel(sp->s, (vreal)(real)1, go && !found);
  return go;
}

// One sub-piece as Simpson's nodes: their positions s in the piece, densities, the TF piece that
// holds them (σ linear in the density there) and the sub-piece's length along the ray.
typedef struct {
  vreal s[3], d[3];
  vreal length;
  TfPiece tf;
} SimpsonNodes;

// The next sub-piece of a piece of length L as Simpson's nodes, for every ray with [0, 1] not
// yet covered; returns those rays.
inline vint simpson_nodes_next(SubPieces* sp, vreal L, __global const real* tf, int count,
                               real4 scalars, vint* cursor, SimpsonNodes* n) {
  vreal sa, sb;
  const vint go = sub_pieces_next(sp, tf, count, scalars, &sa, &sb);
  if (!vany(go)) return go;
  n->s[0] = sa, n->s[1] = (real)0.5 * (sa + sb), n->s[2] = sb;
  for (int k = 0; k < 3; ++k) n->d[k] = cubic_at(&sp->c, n->s[k]);
  n->tf = tf_piece(tf_interval(n->d[1], tf, count, scalars, cursor), tf, count, scalars);
  n->length = L * (sb - sa);
  return go;
}

// Simpson's mean of the density over the sub-piece (exact for the cubic).
inline vreal simpson_mean(const SimpsonNodes* n) {
  return (n->d[0] + (real)4 * n->d[1] + n->d[2]) / (real)6;
}

// ∫ σ(d) along a piece of length L with density cubic c, for the rays where `live` is true:
// Simpson's rule on each sub-piece, where σ is linear in the density (exact). *subpieces counts
// the sub-pieces (the sample statistic).
inline vreal piece_optical_depth_where(const Cubic* c, vreal L, __global const real* tf, int count,
                                       real4 scalars, vint live, vint* subpieces) {
#if IVR_TF == IVR_TF_IDENTITY
  (void)tf, (void)count;
  *subpieces += vcount(live);
  return L * scalars.x * (c->q0 + c->q1 / (real)2 + c->q2 / (real)3 + c->q3 / (real)4);
#else
  SubPieces sp;
  sub_pieces_begin(&sp, *c);
  sp.s = vsel(sp.s, (vreal)(real)1, !live);  // (idle rays: nothing to cover)
  vreal tau = (vreal)(real)0;
  vint cursor = (vint)0, go;
  SimpsonNodes n;
  while (vany(go = simpson_nodes_next(&sp, L, tf, count, scalars, &cursor, &n))) {
    tau = vsel(tau, tau + n.length * tf_piece_sigma(&n.tf, simpson_mean(&n)), go);
    *subpieces += vcount(go);
  }
  return tau;
#endif
}

inline vreal piece_optical_depth(const Cubic* c, vreal L, __global const real* tf, int count,
                                 real4 scalars, vint* subpieces) {
  return piece_optical_depth_where(c, L, tf, count, scalars, vtrue, subpieces);
}

#endif
