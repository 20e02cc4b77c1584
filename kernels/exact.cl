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

#if IVR_RAYS == 1  // one ray per work-item (kernels/rays.cl)

// --- Pieces: the ray between consecutive centre-plane crossings --------------------------------

// The plane of axis index k (u = k) is crossed at t = (k − u0) / du.
typedef struct {
  real t, t1;       // start of the next piece; the ray's end in the box
  real tx, ty, tz;  // next crossing per axis (+inf: none left)
  int kx, ky, kz;   // its plane index
  int sx, sy, sz;   // direction of travel in u (+1, -1, 0)
  int axis;         // axis of the plane that ended the last piece, -1: the box (or none)
} Pieces;

// The first plane crossed after u (moving with sign s) on an axis of n voxels, its index in *k.
inline real first_plane(real u0, real du, real u, int n, int* k, int* s) {
  *s = du > (real)0 ? 1 : (du < (real)0 ? -1 : 0);
  if (*s > 0) {
    *k = u < (real)0 ? 0 : (int)floor(u) + 1;
    if (*k <= n - 1) return ((real)*k - u0) / du;
  } else if (*s < 0) {
    *k = u > (real)(n - 1) ? n - 1 : (int)ceil(u) - 1;
    if (*k >= 0) return ((real)*k - u0) / du;
  }
  return (real)INFINITY;
}

inline real next_plane(real u0, real du, int n, int* k, int s) {
  *k += s;
  return *k >= 0 && *k <= n - 1 ? ((real)*k - u0) / du : (real)INFINITY;
}

// Starts the pieces at ray parameter t (t0, or where a jump over empty space lands).
inline void pieces_begin(Pieces* p, const March* m, int4 dims, real t) {
  p->t = t;
  p->t1 = m->t1;
  p->axis = -1;
  p->tx = first_plane(m->u0x, m->dux, m->u0x + t * m->dux, dims.x, &p->kx, &p->sx);
  p->ty = first_plane(m->u0y, m->duy, m->u0y + t * m->duy, dims.y, &p->ky, &p->sy);
  p->tz = first_plane(m->u0z, m->duz, m->u0z + t * m->duz, dims.z, &p->kz, &p->sz);
}

// The next piece [*ta, *tb] (possibly of length 0 where planes meet); false past the ray's end.
inline bool pieces_next(Pieces* p, const March* m, int4 dims, real* ta, real* tb) {
  if (!(p->t < p->t1)) return false;
  const real end = fmin(fmin(p->tx, p->ty), fmin(p->tz, p->t1));
  *ta = p->t;
  *tb = end;
  p->axis = end == p->t1 ? -1 : (end == p->tx ? 0 : (end == p->ty ? 1 : 2));
  // Every plane crossed at `end` (a ray through a line or a node crosses two or three at once).
  while (p->tx <= end) p->tx = next_plane(m->u0x, m->dux, dims.x, &p->kx, p->sx);
  while (p->ty <= end) p->ty = next_plane(m->u0y, m->duy, dims.y, &p->ky, p->sy);
  while (p->tz <= end) p->tz = next_plane(m->u0z, m->duz, dims.z, &p->kz, p->sz);
  p->t = end;
  return true;
}

// Empty-space skipping for the pieces: where piece [ta, tb] lies in an empty brick, restarts the
// walk where the ray leaves that brick (brick faces are centre planes: a piece starts there; or,
// where rounding counts a sliver on the face as the brick's, where this piece ends) and returns
// true. The skipped pieces add nothing: σ = 0 there.
inline bool pieces_skip_empty(Pieces* p, const March* m, int4 dims, real ta, real tb,
                              __global const uchar* occupied, int4 bricks) {
  const real tm = (real)0.5 * (ta + tb);
  const real exit = empty_brick_exit(m->u0x + tm * m->dux, m->u0y + tm * m->duy,
                                     m->u0z + tm * m->duz, m, dims, occupied, bricks);
  if (exit < (real)0) return false;
  pieces_begin(p, m, dims, fmin(fmax(exit, tb), m->t1));
  return true;
}

// --- The density inside one piece: one cell, fractions linear in s ∈ [0, 1] ---------------------

typedef struct {
  int ix, iy, iz;   // the cell (lower corner voxel), clamped as trilinear_at() clamps
  real fx, fy, fz;  // fractions at s = 0
  real gx, gy, gz;  // their change over the piece (0 along clamped axes)
  bool cx, cy, cz;  // clamped along the axis: the density does not change with u there
} PieceCell;

inline void piece_axis(real ua, real ub, int n, int* i, real* f, real* g, bool* clamped) {
  const real mid = (real)0.5 * (ua + ub);
  *clamped = true;
  if (!(mid > (real)0) || n == 1) {  // the border half-voxel below the first centre
    *i = 0, *f = (real)0, *g = (real)0;
  } else if (mid >= (real)(n - 1)) {  // ... above the last
    *i = n - 1, *f = (real)0, *g = (real)0;
  } else {
    *i = min((int)mid, n - 2);
    *f = ua - (real)*i;
    *g = ub - ua;
    *clamped = false;
  }
}

inline PieceCell piece_cell(const March* m, int4 dims, real ta, real tb) {
  PieceCell c;
  piece_axis(m->u0x + ta * m->dux, m->u0x + tb * m->dux, dims.x, &c.ix, &c.fx, &c.gx, &c.cx);
  piece_axis(m->u0y + ta * m->duy, m->u0y + tb * m->duy, dims.y, &c.iy, &c.fy, &c.gy, &c.cy);
  piece_axis(m->u0z + ta * m->duz, m->u0z + tb * m->duz, dims.z, &c.iz, &c.fz, &c.gz, &c.cz);
  return c;
}

// d density / d u at s inside the piece from the corners v (0 along clamped axes: one-sided at
// the piece's own ends, unlike trilinear_gradient() at a point on a centre plane).
inline void piece_gradient(const real* v, PieceCell c, real s, real* gx, real* gy, real* gz) {
  const real fx = c.fx + s * c.gx, fy = c.fy + s * c.gy, fz = c.fz + s * c.gz;
  *gx = c.cx ? (real)0
             : lerp(lerp(v[1] - v[0], v[3] - v[2], fy), lerp(v[5] - v[4], v[7] - v[6], fy), fz);
  *gy = c.cy ? (real)0
             : lerp(lerp(v[2] - v[0], v[3] - v[1], fx), lerp(v[6] - v[4], v[7] - v[5], fx), fz);
  *gz = c.cz ? (real)0
             : lerp(lerp(v[4] - v[0], v[5] - v[1], fx), lerp(v[6] - v[2], v[7] - v[3], fx), fy);
}

// The cell's 8 corner densities v[k] (bit 0: +x, bit 1: +y, bit 2: +z; the upper neighbour is the
// voxel itself on the clamped upper edge, as in trilinear_at()).
inline void piece_corners(__global const real* volume, int4 dims, PieceCell c, real* v) {
  const int ox = c.ix + 1 < dims.x ? 1 : 0;
  const int oy = c.iy + 1 < dims.y ? dims.x : 0;
  const int oz = c.iz + 1 < dims.z ? dims.x * dims.y : 0;
  __global const real* q = volume + ((c.iz * dims.y + c.iy) * dims.x + c.ix);
  v[0] = q[0], v[1] = q[ox], v[2] = q[oy], v[3] = q[oy + ox];
  v[4] = q[oz], v[5] = q[oz + ox], v[6] = q[oz + oy], v[7] = q[oz + oy + ox];
}

// d(s) = q0 + s·(q1 + s·(q2 + s·q3)) over the piece.
typedef struct {
  real q0, q1, q2, q3;
} Cubic;

inline real cubic_at(const Cubic* c, real s) {
  return c->q0 + s * (c->q1 + s * (c->q2 + s * c->q3));
}

inline real cubic_slope(const Cubic* c, real s) {
  return c->q1 + s * ((real)2 * c->q2 + s * (real)3 * c->q3);
}

// The trilinear interpolant along the piece, multiplied out one axis at a time: linear along x,
// quadratic after y, cubic after z.
inline Cubic piece_cubic(const real* v, PieceCell c) {
  real a0[4], a1[4];
  for (int k = 0; k < 4; ++k) {
    const real dv = v[2 * k + 1] - v[2 * k];
    a0[k] = v[2 * k] + dv * c.fx;
    a1[k] = dv * c.gx;
  }
  real b0[2], b1[2], b2[2];
  for (int j = 0; j < 2; ++j) {
    const real d0 = a0[2 * j + 1] - a0[2 * j], d1 = a1[2 * j + 1] - a1[2 * j];
    b0[j] = a0[2 * j] + d0 * c.fy;
    b1[j] = a1[2 * j] + d0 * c.gy + d1 * c.fy;
    b2[j] = d1 * c.gy;
  }
  const real e0 = b0[1] - b0[0], e1 = b1[1] - b1[0], e2 = b2[1] - b2[0];
  Cubic q;
  q.q0 = b0[0] + e0 * c.fz;
  q.q1 = b1[0] + e0 * c.gz + e1 * c.fz;
  q.q2 = b2[0] + e1 * c.gz + e2 * c.fz;
  q.q3 = e2 * c.gz;
  return q;
}

// --- Sub-pieces: where the cubic crosses TF knots
// -------------------------------------------------

// The root of d(s) = target in [lo, hi], where d is monotone and target lies strictly between
// d(lo) and d(hi): Newton's method kept inside a shrinking bracket (bisection where a step would
// leave it). σ is continuous at a knot, so the integral is insensitive to the root to first order.
inline real cubic_root(const Cubic* c, real target, real lo, real hi) {
  const real flo = cubic_at(c, lo) - target, fhi = cubic_at(c, hi) - target;
  real s = lo + (hi - lo) * flo / (flo - fhi);
  for (int it = 0; it < 40; ++it) {
    const real f = cubic_at(c, s) - target;
    if (f == (real)0) break;
    if ((f < (real)0) == (flo < (real)0))
      lo = s;
    else
      hi = s;
    real next = s - f / cubic_slope(c, s);
    if (!(next > lo && next < hi)) next = (real)0.5 * (lo + hi);
    const bool done = fabs(next - s) <= (real)4 * (IVR_F64 ? DBL_EPSILON : FLT_EPSILON);
    s = next;
    if (done) break;
  }
  return s;
}

// [s, 1] cut into parts on which d is monotone (by the roots of d' in (0, 1)), then into
// sub-pieces at every knot crossing. A sub-piece may span a turning point: only knots split.
typedef struct {
  Cubic c;
  real r[4];  // part boundaries: r[0] = 0 < … < r[parts] = 1
  int parts, part;
  real s, ds;  // start of the next sub-piece, and its density (a knot's exact value after a cut)
} SubPieces;

inline void sub_pieces_begin(SubPieces* sp, Cubic c) {
  sp->c = c;
  sp->parts = 1;
  sp->r[0] = (real)0;
  // Roots of d'(s) = 3 q3 s² + 2 q2 s + q1 in (0, 1), by the stable quadratic formula.
  const real a = (real)3 * c.q3, b = (real)2 * c.q2, cc = c.q1;
  real roots[2];
  int found = 0;
  if (a == (real)0) {
    if (b != (real)0) roots[found++] = -cc / b;
  } else {
    const real disc = b * b - (real)4 * a * cc;
    if (disc > (real)0) {
      const real q = (real)-0.5 * (b + copysign(sqrt(disc), b));
      roots[found++] = q / a;
      if (q != (real)0) roots[found++] = cc / q;
    }
  }
  if (found == 2 && roots[1] < roots[0]) {
    const real t = roots[0];
    roots[0] = roots[1], roots[1] = t;
  }
  for (int i = 0; i < found; ++i)
    if (roots[i] > sp->r[sp->parts - 1] && roots[i] < (real)1) sp->r[sp->parts++] = roots[i];
  sp->r[sp->parts] = (real)1;
  sp->part = 0;
  sp->s = (real)0;
  sp->ds = c.q0;
}

// The next sub-piece [*sa, *sb]; false once [0, 1] is covered.
inline bool sub_pieces_next(SubPieces* sp, __global const real* tf, int count, real4 scalars,
                            real* sa, real* sb) {
  if (!(sp->s < (real)1)) return false;
  *sa = sp->s;
  real x = sp->ds;  // density where the search stands
  for (; sp->part < sp->parts; ++sp->part) {
    const real end = sp->r[sp->part + 1], dend = cubic_at(&sp->c, end);
    const int direction = dend > x ? 1 : (dend < x ? -1 : 0);
    int cursor = 0;
    real knot;
    if (direction != 0 &&
        tf_next_knot(x, tf_interval(x, tf, count, scalars, &cursor), direction, tf, count, scalars,
                     &knot) &&
        (direction > 0 ? knot < dend : knot > dend)) {
      *sb = cubic_root(&sp->c, knot, fmax(sp->s, sp->r[sp->part]), end);
      sp->s = *sb;
      sp->ds = knot;
      return true;
    }
    x = dend;  // no knot in this part: the search moves on, the sub-piece goes on
  }
  *sb = (real)1;
  sp->s = (real)1;
  return true;
}

// One sub-piece as Simpson's nodes: their positions s in the piece, densities, the TF piece that
// holds them (σ linear in the density there) and the sub-piece's length along the ray.
typedef struct {
  real s[3], d[3];
  real length;
  TfPiece tf;
} SimpsonNodes;

// The next sub-piece of a piece of length L as Simpson's nodes; false once [0, 1] is covered.
inline bool simpson_nodes_next(SubPieces* sp, real L, __global const real* tf, int count,
                               real4 scalars, int* cursor, SimpsonNodes* n) {
  real sa, sb;
  if (!sub_pieces_next(sp, tf, count, scalars, &sa, &sb)) return false;
  n->s[0] = sa, n->s[1] = (real)0.5 * (sa + sb), n->s[2] = sb;
  for (int k = 0; k < 3; ++k) n->d[k] = cubic_at(&sp->c, n->s[k]);
  n->tf = tf_piece(tf_interval(n->d[1], tf, count, scalars, cursor), tf, count, scalars);
  n->length = L * (sb - sa);
  return true;
}

// Simpson's mean of the density over the sub-piece (exact for the cubic).
inline real simpson_mean(const SimpsonNodes* n) {
  return (n->d[0] + (real)4 * n->d[1] + n->d[2]) / (real)6;
}

// ∫ σ(d) along a piece of length L with density cubic c: Simpson's rule on each sub-piece, where
// σ is linear in the density (exact). *subpieces counts the sub-pieces (the sample statistic).
inline real piece_optical_depth(const Cubic* c, real L, __global const real* tf, int count,
                                real4 scalars, uint* subpieces) {
#if IVR_TF == IVR_TF_IDENTITY
  ++*subpieces;
  return L * scalars.x * (c->q0 + c->q1 / (real)2 + c->q2 / (real)3 + c->q3 / (real)4);
#else
  SubPieces sp;
  sub_pieces_begin(&sp, *c);
  real tau = (real)0;
  int cursor = 0;
  SimpsonNodes n;
  while (simpson_nodes_next(&sp, L, tf, count, scalars, &cursor, &n)) {
    tau += n.length * tf_piece_sigma(&n.tf, simpson_mean(&n));
    ++*subpieces;
  }
  return tau;
#endif
}

#endif  // IVR_RAYS == 1

#endif
