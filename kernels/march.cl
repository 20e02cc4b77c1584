// march.cl — where a ray meets the box and how the fixed-step integrators cut it: n equal
// segments of at most `step` (n from sample_count.cl) covering the clipped interval exactly, and
// the ray in continuous voxel coordinates u(t) = u0 + t·du (voxel centre i at u = i).
#ifndef IVR_MARCH_CL
#define IVR_MARCH_CL
#include "config.cl"
#include "geometry.cl"
#include "rays.cl"
#include "sample_count.cl"

// One ray's march. Scalars rather than real3: PoCL compiles real3 into padded 4-wide vectors and
// lane shuffles.
typedef struct {
  real t0, t1;  // the ray inside the box, t0 >= 0
  real dt;      // segment length
  uint n;       // segments
  real u0x, u0y, u0z, dux, duy, duz;
  // The first voxel of the brick whose voxels the march reads (0 in core): a sample's point is the
  // global u0 + t·du less o (IVR_POINT), exact for an integer o, so a brick's march reads the
  // in-core march's points bit for bit (the exact scheme's pieces: o is their grid's origin).
  real ox, oy, oz;
} RayMarch;

// The march the integrators take: one ray's, or every ray's of a packet (kernels/rays.cl) in
// vector lanes, a ray that misses (or lies past the image's edge) with n = 0.
#if IVR_RAYS == 1
typedef RayMarch March;
#else
typedef struct {
  vreal t0, t1, dt;
  vint n;
  vreal u0x, u0y, u0z, dux, duy, duz;
  real ox, oy, oz;  // (as RayMarch's: one brick for every lane)
} March;
#endif

// Axis a's coordinate of the point at t of march m (a pointer), in the voxels it reads.
#define IVR_POINT(m, t, a) ((m)->u0##a + (t) * (m)->du##a - (m)->o##a)

// Sets *m for `ray`, the ray of pixel (x, y) of camera `cam`; false where it misses the box
// (then *m is unset). Whether it meets the box and its segment count n come from
// sample_count.cl's definition, which no precision, device or compiler moves; the interval and
// positions are this precision's. Where the two disagree on a grazing ray (a hit here, an empty
// interval in this precision), the n samples lie at t0 with dt = 0 and add nothing.
inline bool march_begin(Ray ray, __global const real* cam, int x, int y, int width, int height,
                        real4 box_min, real4 box_max, real4 inv_voxel, real step, RayMarch* m) {
  m->n = sample_count(cam, x, y, width, height, box_min, box_max, step);
  if (m->n == 0u) return false;
  ray_interval(cam, x, &m->t0, &m->t1);
  clip_box(ray, box_min.xyz, box_max.xyz, &m->t0, &m->t1);
  if (!(m->t1 > m->t0)) m->t1 = m->t0;  // also a parallel ray's t1 = −1 outside a slab
  const real length = m->t1 - m->t0;
  m->dt = geometry_divide(length, (real)m->n);
  m->u0x = (ray.origin.x - box_min.x) * inv_voxel.x - (real)0.5;
  m->u0y = (ray.origin.y - box_min.y) * inv_voxel.y - (real)0.5;
  m->u0z = (ray.origin.z - box_min.z) * inv_voxel.z - (real)0.5;
  m->dux = ray.dir.x * inv_voxel.x;
  m->duy = ray.dir.y * inv_voxel.y;
  m->duz = ray.dir.z * inv_voxel.z;
  m->ox = m->oy = m->oz = (real)0;
  return true;
}

#if IVR_RAYS > 1
// The marches of the IVR_RAYS pixels of the tile with corner (x0, y0) (kernels/rays.cl) of camera
// `cam`, each as march_begin() sets it; false where none meets the box.
inline bool march_begin_rays(__global const real* cam, int x0, int y0, int width, int height,
                             real4 box_min, real4 box_max, real4 inv_voxel, real step, March* m) {
  real t0[IVR_RAYS], t1[IVR_RAYS], dt[IVR_RAYS], u0x[IVR_RAYS], u0y[IVR_RAYS], u0z[IVR_RAYS],
      dux[IVR_RAYS], duy[IVR_RAYS], duz[IVR_RAYS];
  int n[IVR_RAYS];
  bool any_hit = false;
  for (int l = 0; l < IVR_RAYS; ++l) {
    RayMarch r;
    const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
    if (x < width && y < height &&
        march_begin(camera_ray(cam, x, y, width, height), cam, x, y, width, height, box_min,
                    box_max, inv_voxel, step, &r)) {
      t0[l] = r.t0, t1[l] = r.t1, dt[l] = r.dt, n[l] = (int)r.n;
      u0x[l] = r.u0x, u0y[l] = r.u0y, u0z[l] = r.u0z, dux[l] = r.dux, duy[l] = r.duy,
      duz[l] = r.duz;
      any_hit = true;
    } else {
      t0[l] = t1[l] = dt[l] = u0x[l] = u0y[l] = u0z[l] = dux[l] = duy[l] = duz[l] = (real)0;
      n[l] = 0;
    }
  }
  m->t0 = IVR_VLOAD(0, t0), m->t1 = IVR_VLOAD(0, t1), m->dt = IVR_VLOAD(0, dt);
  m->n = IVR_VLOAD(0, n);
  m->u0x = IVR_VLOAD(0, u0x), m->u0y = IVR_VLOAD(0, u0y), m->u0z = IVR_VLOAD(0, u0z);
  m->dux = IVR_VLOAD(0, dux), m->duy = IVR_VLOAD(0, duy), m->duz = IVR_VLOAD(0, duz);
  m->ox = m->oy = m->oz = (real)0;
  return any_hit;
}
#endif

// Ray parameter of sample i: segment midpoints (midpoint) or segment ends (i = 0..n).
inline vreal sample_t(const March* m, vint i) {
#if IVR_ENDPOINT_SAMPLES
  return m->t0 + vto_real(i) * m->dt;
#else
  return m->t0 + (vto_real(i) + (real)0.5) * m->dt;
#endif
}

// Whether segment i (samples i, i + 1) belongs to the window that ends at `window_end`: its far
// end lies in it, or, the ray's last segment, the window reaches the ray's end (whatever
// t0 + n·dt rounds to). In core the window is [t0, ∞): every segment. Out of core
// (kernels/bricked.cl) the windows of one ray partition its segments. (Endpoint schemes only.)
inline vint segment_in_window(const March* m, vint i, vreal window_end) {
  const vint last = i + 1 >= (vint)m->n;
  return vseli(vmask_of(sample_t(m, i + 1) <= window_end), vmask_of(window_end >= m->t1), last);
}

#endif
