// project.cl — the absorption projector N (line integrals of the trilinear volume along every
// camera ray) and its exact transpose Nᵀ (the same traversal scattering into the voxels). Both walk
// a ray with the `exact` integrator's centre-plane pieces (kernels/exact.cl) and use the same
// per-piece corner weights, so ⟨N x, y⟩ = ⟨x, Nᵀ y⟩ holds to rounding.
#include "atomics.cl"
#include "brick_window.cl"
#include "config.cl"
#include "exact.cl"
#include "geometry.cl"
#include "march.cl"
#include "scatter_cache.cl"

// The voxel index of each of the piece's 8 cell corners (bit 0: +x, bit 1: +y, bit 2: +z; the
// upper neighbour is the voxel itself on a clamped upper edge: the voxels piece_corners() reads).
inline void piece_corner_index(int4 dims, PieceCell c, int* index) {
  const int ox = c.ix + 1 < dims.x ? 1 : 0;
  const int oy = c.iy + 1 < dims.y ? dims.x : 0;
  const int oz = c.iz + 1 < dims.z ? dims.x * dims.y : 0;
  const int b = (c.iz * dims.y + c.iy) * dims.x + c.ix;
  index[0] = b, index[1] = b + ox, index[2] = b + oy, index[3] = b + oy + ox;
  index[4] = b + oz, index[5] = b + oz + ox, index[6] = b + oz + oy, index[7] = b + oz + oy + ox;
}

// ∫ over the piece of each corner's trilinear weight, factored. Along the piece each axis's weight
// is linear in s: m + d·(s − ½), m its value at the piece's middle; the integral of a product of
// three such factors over [0, 1] is m₁m₂m₃ + (m₁d₂d₃ + d₁m₂d₃ + d₁d₂m₃)/12 (odd moments of s − ½
// vanish). Grouped by the (y, z) corner pair j = b + 2e: weight(a, b, e) = L·(mx[a]·p[j] +
// dx[a]·q[j]). Clamped axes have f = g = 0: their upper corners get weight 0.
typedef struct {
  real mx1, gx;     // x: m = (1 − mx1, mx1), d = (−gx, gx)
  real p[4], q[4];  // per (y, z) pair, times the piece length
} PieceWeights;

inline PieceWeights piece_weights(PieceCell c, real L) {
  PieceWeights w;
  w.mx1 = c.fx + (real)0.5 * c.gx;
  w.gx = c.gx;
  const real my1 = c.fy + (real)0.5 * c.gy, mz1 = c.fz + (real)0.5 * c.gz;
  const real my[2] = {(real)1 - my1, my1}, mz[2] = {(real)1 - mz1, mz1};
  const real dy[2] = {-c.gy, c.gy}, dz[2] = {-c.gz, c.gz};
  const real L12 = L / (real)12;
  for (int j = 0; j < 4; ++j) {
    const int b = j & 1, e = j >> 1;
    w.p[j] = L * my[b] * mz[e] + L12 * dy[b] * dz[e];
    w.q[j] = L12 * (my[b] * dz[e] + dy[b] * mz[e]);
  }
  return w;
}

// The weight of corner k (bit 0: +x, bit 1: +y, bit 2: +z).
inline real piece_weight(const PieceWeights* w, int k) {
  const int j = k >> 1;
  return (k & 1) ? w->mx1 * w->p[j] + w->gx * w->q[j]
                 : ((real)1 - w->mx1) * w->p[j] - w->gx * w->q[j];
}

// Starts the ray of pixel (x, y) of `view`; false where it misses the box.
inline bool projector_ray(__global const real* cameras, int x, int y, int view, int width,
                          int height, int4 dims, real4 box_min, real4 box_max, real4 inv_voxel,
                          March* m, Pieces* p) {
  const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
  // The step only sizes the fixed-step schemes' segments; the pieces ignore it.
  if (!march_begin(ray, cameras + view * IVR_CAMERA_STRIDE, x, y, width, height, box_min,
                   box_max, inv_voxel, (real)INFINITY, m)) return false;
  // t from the box entry rather than the eye: piece lengths are differences of t, whose rounding
  // scales with |t| (the eye may be far away; float32 entries of N would lose digits).
  m->u0x += m->t0 * m->dux, m->u0y += m->t0 * m->duy, m->u0z += m->t0 * m->duz;
  m->t1 -= m->t0;
  m->t0 = (real)0;
  pieces_begin(p, m, dims, m->t0);
  return true;
}

// ∫ v(t) dt over the pieces left of a ray (its whole march, or its window in a brick).
inline real pieces_integral(__global const real* volume, int4 dims, March* m, Pieces* p) {
  real sum = (real)0, ta, tb;
  while (pieces_next(p, m, dims, &ta, &tb)) {
    if (!(tb > ta)) continue;
    const PieceCell c = piece_cell(m, dims, ta, tb);
    real v[8];
    piece_corners(volume, dims, c, v);
    const PieceWeights w = piece_weights(c, tb - ta);
    // Σ_k weight_k·v_k, the x pairs first: v0·(mx0·p + dx0·q) + v1·(mx1·p + dx1·q).
    for (int j = 0; j < 4; ++j) {
      const real v0 = v[2 * j], v1 = v[2 * j + 1];
      sum += w.p[j] * (v0 + w.mx1 * (v1 - v0)) + w.q[j] * w.gx * (v1 - v0);
    }
  }
  return sum;
}

// N: one work-item per ray; line[ray] = ∫ v(t) dt over the ray's part in the box.
__kernel void project(__global const real* restrict volume, const int4 dims, const real4 box_min,
                      const real4 box_max, const real4 inv_voxel,
                      __global const real* restrict cameras, const int width, const int height,
                      __global real* restrict line) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;
  March m;
  Pieces p;
  real sum = (real)0;
  if (projector_ray(cameras, x, y, view, width, height, dims, box_min, box_max, inv_voxel, &m,
                    &p))
    sum = pieces_integral(volume, dims, &m, &p);
  line[((size_t)view * height + y) * width + x] = sum;
}

// Nᵀ of one ray: line[ray] × (each corner's weight) into the voxels. Consecutive pieces share the
// corners on the plane between their cells: a corner's weight is held while the ray stays at it
// and added once when the ray leaves it, halving the adds.
inline void backproject_ray(__global const real* line, int4 dims, real4 box_min, real4 box_max,
                            real4 inv_voxel, __global const real* cameras, int width, int height,
                            int x, int y, int view, const ScatterSink volume) {
  const real value = line[((size_t)view * height + y) * width + x];
  March m;
  Pieces p;
  if (value == (real)0 ||
      !projector_ray(cameras, x, y, view, width, height, dims, box_min, box_max, inv_voxel, &m, &p))
    return;
  int held_index[8];
  real held[8];
  int hx = 0, hy = 0, hz = 0;
  bool holding = false;
  real ta, tb;
  while (pieces_next(&p, &m, dims, &ta, &tb)) {
    if (!(tb > ta)) continue;
    const PieceCell c = piece_cell(&m, dims, ta, tb);
    int index[8];
    piece_corner_index(dims, c, index);
    const PieceWeights w = piece_weights(c, tb - ta);
    real wk[8];
    for (int k = 0; k < 8; ++k) wk[k] = piece_weight(&w, k);
    if (holding) {
      // Held corner j (bits a, b, e) is corner (a − Δx, b − Δy, e − Δz) of this cell, if any.
      const int sx = c.ix - hx, sy = c.iy - hy, sz = c.iz - hz;
      for (int j = 0; j < 8; ++j) {
        const int a = (j & 1) - sx, b = ((j >> 1) & 1) - sy, e = (j >> 2) - sz;
        const int k = a | (b << 1) | (e << 2);
        if (a >= 0 && a <= 1 && b >= 0 && b <= 1 && e >= 0 && e <= 1 && held_index[j] == index[k])
          wk[k] += held[j];
        else if (held[j] != (real)0)
          scatter_add(volume, held_index[j], value * held[j]);
      }
    }
    for (int k = 0; k < 8; ++k) held_index[k] = index[k], held[k] = wk[k];
    hx = c.ix, hy = c.iy, hz = c.iz;
    holding = true;
  }
  if (holding)
    for (int k = 0; k < 8; ++k)
      if (held[k] != (real)0) scatter_add(volume, held_index[k], value * held[k]);
}

// Nᵀ: one work-item per ray, adding atomically (rays share voxels); `volume` must be zeroed
// first. With the host's IVR_SCATTER_CACHE the group's rays (a tile of one view) sum their adds
// in local memory first (kernels/scatter_cache.cl), and every item, padding and rays that miss
// the box included, meets the table's barriers.
__kernel void backproject(__global const real* restrict line, const int4 dims, const real4 box_min,
                          const real4 box_max, const real4 inv_voxel,
                          __global const real* restrict cameras, const int width, const int height,
                          __global real* volume) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  IVR_SCATTER_SINK(sink, volume);
  if (x < width && y < height)
    backproject_ray(line, dims, box_min, box_max, inv_voxel, cameras, width, height, x, y, view,
                    sink);
  scatter_flush(sink);
}

// --- One brick of a bricked volume (docs/scaling.md; lib/brick/bricked_project.cpp) ------------
// `volume` holds the brick's voxels (dims: their extent; origin: its first voxel); brick_lo and
// brick_hi are its planes. A ray's pieces inside the brick are the unsplit ray's (the brick's
// faces are centre planes), so N = Σ_bricks N_brick and Nᵀ is each brick's Nᵀ added into the
// volume (the host adds the shared planes from both sides).

// The ray's window in the brick, its march reading the brick's voxels (the grid's origin, kernels/
// exact.cl) and its pieces begun at the window's start; false where the ray misses the brick.
inline bool projector_brick_ray(__global const real* cameras, int x, int y, int view, int width,
                                int height, int4 dims, real4 box_min, real4 box_max,
                                real4 inv_voxel, real4 brick_lo, real4 brick_hi, int4 origin,
                                March* m, Pieces* p) {
  if (!projector_ray(cameras, x, y, view, width, height, dims, box_min, box_max, inv_voxel, m, p))
    return false;
  real ta = m->t0, tb = m->t1;
  brick_window(m->u0x, m->u0y, m->u0z, m->dux, m->duy, m->duz, brick_lo, brick_hi, &ta, &tb);
  if (!(tb > ta)) return false;
  m->ox = (real)origin.x, m->oy = (real)origin.y, m->oz = (real)origin.z;
  m->t1 = tb;
  pieces_begin(p, m, dims, ta);
  return true;
}

// N of one brick, added to `line`.
__kernel void project_brick(__global const real* restrict volume, const int4 dims,
                            const real4 box_min, const real4 box_max, const real4 inv_voxel,
                            __global const real* restrict cameras, const int width,
                            const int height, __global real* restrict line, const real4 brick_lo,
                            const real4 brick_hi, const int4 origin) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;
  March m;
  Pieces p;
  if (!projector_brick_ray(cameras, x, y, view, width, height, dims, box_min, box_max, inv_voxel,
                           brick_lo, brick_hi, origin, &m, &p))
    return;
  line[((size_t)view * height + y) * width + x] += pieces_integral(volume, dims, &m, &p);
}

// Nᵀ of one brick into its voxels (`volume`, zeroed first), atomically.
__kernel void backproject_brick(__global const real* restrict line, const int4 dims,
                                const real4 box_min, const real4 box_max, const real4 inv_voxel,
                                __global const real* restrict cameras, const int width,
                                const int height, __global real* volume, const real4 brick_lo,
                                const real4 brick_hi, const int4 origin) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;
  const real value = line[((size_t)view * height + y) * width + x];
  March m;
  Pieces p;
  if (value == (real)0 ||
      !projector_brick_ray(cameras, x, y, view, width, height, dims, box_min, box_max, inv_voxel,
                           brick_lo, brick_hi, origin, &m, &p))
    return;
  real ta, tb;
  while (pieces_next(&p, &m, dims, &ta, &tb)) {
    if (!(tb > ta)) continue;
    const PieceCell c = piece_cell(&m, dims, ta, tb);
    int index[8];
    piece_corner_index(dims, c, index);
    const PieceWeights w = piece_weights(c, tb - ta);
    for (int k = 0; k < 8; ++k) {
      const real wk = piece_weight(&w, k);
      if (wk != (real)0) atomic_add_global(volume + index[k], value * wk);
    }
  }
}
