// geometry.cl — camera rays, exact ray–box clipping and trilinear density with docs/design.md's
// conventions (values at cell centres, clamped to the edge centres inside the box).
#ifndef IVR_GEOMETRY_CL
#define IVR_GEOMETRY_CL
#include "config.cl"
#include "rays.cl"
#include "rounded.cl"

typedef struct {
  real3 origin;
  real3 dir;  // unit length
} Ray;

// Division and square root of the per-ray geometry, correctly rounded in both precisions (float64's
// are by the OpenCL specification, float32's through rounded.cl), so that no device's division
// moves a ray.
#if IVR_F64
#define geometry_divide(a, b) ((a) / (b))
#define geometry_sqrt(a) sqrt(a)
#else
#define geometry_divide(a, b) rounded_divide(a, b)
#define geometry_sqrt(a) rounded_sqrt(a)
#endif

// Ray through the centre of pixel (x, y), row 0 at the top. The screen coordinates are the exact
// fractions (2x + 1 − W)/W and (H − 2y − 1)/H rounded once, and every sum of products is an
// explicit fma, so that no compiler's contraction changes the ray either (sample_count.cl builds
// the float32 ray the same way).
inline Ray camera_ray(__global const real* cam, int x, int y, int width, int height) {
#if IVR_RAY_LIST
  // A ray list (docs/design.md, ray lists): `cam` is the list, pixel x of the one-row "image" is
  // ray x; its interval is ray_interval()'s.
  (void)y, (void)width, (void)height;
  __global const real* row = cam + (size_t)x * IVR_RAY_STRIDE;
  Ray listed;
  listed.origin = (real3)(row[0], row[1], row[2]);
  listed.dir = (real3)(row[3], row[4], row[5]);
  return listed;
#else
  const real sx = geometry_divide((real)(2 * x + 1 - width), (real)width);
  const real sy = geometry_divide((real)(height - 2 * y - 1), (real)height);
  Ray r;
  if (cam[12] != (real)0) {  // orthographic
    r.origin =
        (real3)(fma(sy, cam[9], fma(sx, cam[6], cam[0])), fma(sy, cam[10], fma(sx, cam[7], cam[1])),
                fma(sy, cam[11], fma(sx, cam[8], cam[2])));
    r.dir = (real3)(cam[3], cam[4], cam[5]);
  } else {
    const real dx = fma(sy, cam[9], fma(sx, cam[6], cam[3]));
    const real dy = fma(sy, cam[10], fma(sx, cam[7], cam[4]));
    const real dz = fma(sy, cam[11], fma(sx, cam[8], cam[5]));
    const real dz2 = dz * dz;
    const real norm = geometry_sqrt(fma(dx, dx, fma(dy, dy, dz2)));
    r.origin = (real3)(cam[0], cam[1], cam[2]);
    r.dir =
        (real3)(geometry_divide(dx, norm), geometry_divide(dy, norm), geometry_divide(dz, norm));
  }
  return r;
#endif
}

// Slab test for one axis; shrinks [*t0, *t1]. A ray parallel to the slab keeps its interval when
// its origin lies within the (closed) slab and empties it otherwise.
inline void clip_slab(real o, real d, real lo, real hi, real* t0, real* t1) {
  if (d != (real)0) {
    const real ta = geometry_divide(lo - o, d), tb = geometry_divide(hi - o, d);
    *t0 = fmax(*t0, fmin(ta, tb));
    *t1 = fmin(*t1, fmax(ta, tb));
  } else if (o < lo || o > hi) {
    *t1 = (real)-1;
  }
}

// The interval a ray is marched over before clipping to the box: from its origin on for a camera's
// rays; a ray list's own [t_start, t_end] (pixel x of the list's row, ray_list in camera_ray()).
inline void ray_interval(__global const real* cam, int x, real* t0, real* t1) {
#if IVR_RAY_LIST
  *t0 = cam[(size_t)x * IVR_RAY_STRIDE + 6];
  *t1 = cam[(size_t)x * IVR_RAY_STRIDE + 7];
#else
  (void)cam, (void)x;
  *t0 = (real)0;
  *t1 = INFINITY;
#endif
}

// Parameter interval of the ray inside the box, within [*t0, *t1] as given.
inline bool clip_box(Ray r, real3 bmin, real3 bmax, real* t0, real* t1) {
  clip_slab(r.origin.x, r.dir.x, bmin.x, bmax.x, t0, t1);
  clip_slab(r.origin.y, r.dir.y, bmin.y, bmax.y, t0, t1);
  clip_slab(r.origin.z, r.dir.z, bmin.z, bmax.z, t0, t1);
  return *t0 < *t1;
}

// The cell of continuous voxel coordinate u along an axis of n voxels, clamped to the edge centres
// as trilinear_at() clamps it: returns the index i, and the fraction in [0, 1] in *f (every ray of
// a packet: kernels/rays.cl).
__attribute__((always_inline)) inline vint cell_axis(vreal u, int n, vreal* f) {
  const vreal c = vclamp(u, (real)0, (real)(n - 1));
  const vint i = vto_int(c);  // c >= 0, so truncation is floor
  *f = c - vto_real(i);
  return i;
}

// Trilinear density at continuous voxel coordinates (ux, uy, uz) (voxel centre i at u = i),
// clamped to the edge centres: the value is constant in the outer half-voxel. Scalar (or one value
// per ray of a packet) on purpose: PoCL compiles float3 arithmetic into 4-wide vectors plus lane
// shuffles.
__attribute__((always_inline)) inline vreal trilinear_at(__global const real* vol, int4 dims,
                                                         vreal ux, vreal uy, vreal uz) {
  vreal fx, fy, fz;
  const vint ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
             iz = cell_axis(uz, dims.z, &fz);
  const int sx = dims.x, sxy = dims.x * dims.y;
  // One base index and the neighbours' offsets (0 on the clamped upper edge).
  const vint ox = vseli((vint)0, (vint)1, ix + 1 < dims.x);
  const vint oy = vseli((vint)0, (vint)sx, iy + 1 < dims.y);
  const vint oz = vseli((vint)0, (vint)sxy, iz + 1 < dims.z);
  const vint p = iz * sxy + iy * sx + ix;
#ifdef IVR_GATHER_PAIRS
  // A packet in float32: the ±x neighbours as pairs (kernels/rays.cl); on the upper x edge of a
  // grid at least 2 wide, the pair before (ix − 1 >= 0).
  if (dims.x >= 2) {
    const vint edge = ox == (vint)0;
    vreal a0, a1, b0, b1, c0, c1, d0, d1;
    vgather_pair(vol, p, edge, &a0, &a1);
    vgather_pair(vol, p + oy, edge, &b0, &b1);
    vgather_pair(vol, p + oz, edge, &c0, &c1);
    vgather_pair(vol, p + oz + oy, edge, &d0, &d1);
    return vlerp(vlerp(vlerp(a0, a1, fx), vlerp(b0, b1, fx), fy),
                 vlerp(vlerp(c0, c1, fx), vlerp(d0, d1, fx), fy), fz);
  }
#endif
  const vreal c00 = vlerp(vgather_off(vol, p, 0), vgather_off(vol, p, ox), fx);
  const vreal c10 = vlerp(vgather_off(vol, p, oy), vgather_off(vol, p, oy + ox), fx);
  const vreal c01 = vlerp(vgather_off(vol, p, oz), vgather_off(vol, p, oz + ox), fx);
  const vreal c11 = vlerp(vgather_off(vol, p, oz + oy), vgather_off(vol, p, oz + oy + ox), fx);
  return vlerp(vlerp(c00, c10, fy), vlerp(c01, c11, fy), fz);
}

// d density / d u of the trilinear interpolant in a cell with corner values v[k] (bit 0: +x,
// bit 1: +y, bit 2: +z) at fractions (fx, fy, fz); 0 along an axis where u lies outside (lo, hi),
// the volume's first and last voxel centres in the coordinates u is given in, where trilinear_at()
// clamps it (one-sided on the boundary of a cell). trilinear_gradient: the whole volume's
// [0, n − 1].
inline void trilinear_gradient_within(const real* v, real fx, real fy, real fz, real ux, real uy,
                                      real uz, real4 lo, real4 hi, real* gx, real* gy, real* gz) {
  *gx = ux > lo.x && ux < hi.x
            ? lerp(lerp(v[1] - v[0], v[3] - v[2], fy), lerp(v[5] - v[4], v[7] - v[6], fy), fz)
            : (real)0;
  *gy = uy > lo.y && uy < hi.y
            ? lerp(lerp(v[2] - v[0], v[3] - v[1], fx), lerp(v[6] - v[4], v[7] - v[5], fx), fz)
            : (real)0;
  *gz = uz > lo.z && uz < hi.z
            ? lerp(lerp(v[4] - v[0], v[5] - v[1], fx), lerp(v[6] - v[2], v[7] - v[3], fx), fy)
            : (real)0;
}

inline void trilinear_gradient(const real* v, real fx, real fy, real fz, real ux, real uy, real uz,
                               int4 dims, real* gx, real* gy, real* gz) {
  trilinear_gradient_within(v, fx, fy, fz, ux, uy, uz, (real4)(real)0,
                            (real4)((real)(dims.x - 1), (real)(dims.y - 1), (real)(dims.z - 1), 0),
                            gx, gy, gz);
}

#if IVR_RAYS == 1
// Trilinear density at continuous voxel coordinates u.
inline real trilinear(__global const real* vol, int4 dims, real3 u) {
  return trilinear_at(vol, dims, u.x, u.y, u.z);
}
#endif

#endif
