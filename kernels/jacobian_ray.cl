// jacobian_ray.cl — what every integrator's forward-mode march shares: the lanes (what each
// differentiates), the ray's tangents (origin, direction, where it enters and leaves the box), the
// tangent of a sample's density, and the tangents of the pixel that the marches accumulate.
#ifndef IVR_TANGENT_RAY_CL
#define IVR_TANGENT_RAY_CL
#include "config.cl"
#include "geometry.cl"
#include "jacobian_geometry.cl"
#include "march.cl"
#include "primal.cl"

#ifndef IVR_LANES
#define IVR_LANES 1
#endif
#ifndef IVR_TANGENT_TF  // some lane is a TF parameter
#define IVR_TANGENT_TF 1
#endif
#ifndef IVR_TANGENT_CAMERA  // some lane is a camera component
#define IVR_TANGENT_CAMERA 1
#endif
#ifndef IVR_TANGENT_VOXEL  // some lane is a voxel
#define IVR_TANGENT_VOXEL 1
#endif

#include "ivr_constants.h"  // IVR_LANE_*: what a lane differentiates (int4: kind, a, b, c)

#define IVR_FOR_LANES(p) for (int p = 0; p < IVR_LANES; ++p)

// A packet of rays (kernels/rays.cl) carries TF and background lanes: each lane is then the same
// parameter for every ray, a vector of IVR_RAYS tangents. Camera and voxel lanes, whose geometry
// is per ray, take one ray per work-item.
#if IVR_RAYS > 1 && (IVR_TANGENT_CAMERA || IVR_TANGENT_VOXEL)
#error "camera and voxel tangent lanes take one ray per work-item (IVR_RAYS 1)"
#endif

typedef struct {
  int4 lane[IVR_LANES];
  real dox[IVR_LANES], doy[IVR_LANES], doz[IVR_LANES];  // d origin
  real ddx[IVR_LANES], ddy[IVR_LANES], ddz[IVR_LANES];  // d direction
  real dt0[IVR_LANES], dt1[IVR_LANES];  // d t0, d t1: the box's entry and exit move with the ray
  // The march's results: d transmittance, d emitted colour (per ray of a packet).
  vreal dT[IVR_LANES], dcr[IVR_LANES], dcg[IVR_LANES], dcb[IVR_LANES];
  // The volume's first and last voxel centres in the coordinates of the voxels marched (in core
  // 0 and dims − 1; in a brick moved by its origin, ±∞ at its inner faces): where the density's
  // gradient is clamped (sample_gradient).
  real4 grid_lo, grid_hi;
} TangentRay;

// d segment length of lane p (camera lanes move the ray's ends; 0 for every other lane).
#if IVR_TANGENT_CAMERA
#define IVR_DDT(tr, p, m) (((tr)->dt1[p] - (tr)->dt0[p]) / (real)(m)->n)
#else
#define IVR_DDT(tr, p, m) ((real)0)
#endif

// d t of the point where the ray meets a plane of `axis` (t = (plane − o_a)/dir_a); 0 for -1.
inline real plane_t_tangent(const TangentRay* tr, int p, Ray ray, int axis, real t) {
  if (axis < 0) return (real)0;
  const real3 o = (real3)(tr->dox[p], tr->doy[p], tr->doz[p]);
  const real3 d = (real3)(tr->ddx[p], tr->ddy[p], tr->ddz[p]);
  return -(component(o, axis) + t * component(d, axis)) / component(ray.dir, axis);
}

// The lanes and the ray's tangents for pixel (x, y) of `view`; entry and exit tangents for the
// clipped ray where m is given (the ray hits the box).
// A ray list's lanes (IVR_LANE_RAY, column k of the pixel's own ray: origin, direction, t_start,
// t_end) move its origin or direction by a unit, or an end of its interval where that end, not a
// box face, bounds the march. `cam` is the view's camera or the list.
inline void tangent_ray_begin(TangentRay* tr, __global const int4* lanes, __global const real* cam,
                              __global const real* camera_params, int view, int x, int y, int width,
                              int height, Ray ray, const March* m, real4 box_min, real4 box_max,
                              int4 dims) {
  tr->grid_lo = (real4)(real)0;
  tr->grid_hi = (real4)((real)(dims.x - 1), (real)(dims.y - 1), (real)(dims.z - 1), (real)0);
  IVR_FOR_LANES(p) {
    tr->lane[p] = lanes[p];
    tr->dox[p] = tr->doy[p] = tr->doz[p] = tr->ddx[p] = tr->ddy[p] = tr->ddz[p] = (real)0;
    tr->dt0[p] = tr->dt1[p] = (real)0;
    tr->dT[p] = tr->dcr[p] = tr->dcg[p] = tr->dcb[p] = (vreal)(real)0;
#if IVR_TANGENT_CAMERA && IVR_RAY_LIST
    if (tr->lane[p].x == IVR_LANE_RAY) {
      const int k = tr->lane[p].y;
      const real one = (real)1, zero = (real)0;
      tr->dox[p] = k == 0 ? one : zero, tr->doy[p] = k == 1 ? one : zero;
      tr->doz[p] = k == 2 ? one : zero, tr->ddx[p] = k == 3 ? one : zero;
      tr->ddy[p] = k == 4 ? one : zero, tr->ddz[p] = k == 5 ? one : zero;
    }
#elif IVR_TANGENT_CAMERA
    if (tr->lane[p].x == IVR_LANE_CAMERA && tr->lane[p].y == view) {
      const real sx = (real)2 * ((real)x + (real)0.5) / (real)width - (real)1;
      const real sy = (real)1 - (real)2 * ((real)y + (real)0.5) / (real)height;
      real3 o, d;
      camera_ray_tangent(camera_params + view * IVR_CAMERA_PARAMS_STRIDE, sx, sy, tr->lane[p].z, &o,
                         &d);
      tr->dox[p] = o.x, tr->doy[p] = o.y, tr->doz[p] = o.z;
      tr->ddx[p] = d.x, tr->ddy[p] = d.y, tr->ddz[p] = d.z;
    }
#endif
  }
#if IVR_TANGENT_CAMERA
  if (!m) return;
#if IVR_RAY_LIST
  // Where the list's own t_start (t_end) bounds the march, that end moves with its lane only;
  // else the box face that bounds it moves with the ray.
  real t_start, t_end;
  ray_interval(cam, x, &t_start, &t_end);
  const bool own0 = m->t0 == t_start, own1 = m->t1 == t_end;
  const int a0 = own0 ? -1 : face_axis(ray, box_min.xyz, box_max.xyz, m->t0, true);
  const int a1 = own1 ? -1 : face_axis(ray, box_min.xyz, box_max.xyz, m->t1, false);
#else
  const int a0 = clip_axis(ray, box_min.xyz, box_max.xyz, m->t0, true);
  const int a1 = clip_axis(ray, box_min.xyz, box_max.xyz, m->t1, false);
#endif
  IVR_FOR_LANES(p) {
    tr->dt0[p] = plane_t_tangent(tr, p, ray, a0, m->t0);
    tr->dt1[p] = plane_t_tangent(tr, p, ray, a1, m->t1);
#if IVR_RAY_LIST
    if (tr->lane[p].x == IVR_LANE_RAY && tr->lane[p].y == 6 && own0) tr->dt0[p] = (real)1;
    if (tr->lane[p].x == IVR_LANE_RAY && tr->lane[p].y == 7 && own1) tr->dt1[p] = (real)1;
#endif
  }
#else
  (void)cam, (void)ray, (void)m, (void)box_min, (void)box_max;
#endif
}

// Weight of voxel index j along one axis in the trilinear interpolation of cell i (clamped like
// trilinear_at(): on the upper edge the cell's two corners are the same voxel).
inline real axis_weight(int j, int i, real f, int n) {
  return (j == i ? (real)1 - f : (real)0) + (j == i + 1 && i + 1 < n ? f : (real)0);
}

// The tangent of a sample's density in lane p: through its position (camera lanes; the sample
// sits at ray parameter t, which moves by dts; (gx, gy, gz) = d density / d u) or the voxel's own
// value (voxel lanes: its trilinear weight in cell (ix, iy, iz) at fractions f).
inline vreal density_tangent(const TangentRay* tr, int p, Ray ray, vreal t, vreal dts, vreal gx,
                             vreal gy, vreal gz, vint ix, vint iy, vint iz, vreal fx, vreal fy,
                             vreal fz, int4 dims, real4 inv_voxel) {
  vreal dd = (vreal)(real)0;
  (void)tr, (void)p;
#if IVR_TANGENT_CAMERA
  dd = gx * (tr->dox[p] + t * tr->ddx[p] + dts * ray.dir.x) * inv_voxel.x +
       gy * (tr->doy[p] + t * tr->ddy[p] + dts * ray.dir.y) * inv_voxel.y +
       gz * (tr->doz[p] + t * tr->ddz[p] + dts * ray.dir.z) * inv_voxel.z;
#else
  (void)ray, (void)t, (void)dts, (void)gx, (void)gy, (void)gz, (void)inv_voxel;
#endif
#if IVR_TANGENT_VOXEL
  const int4 lane = tr->lane[p];
  if (lane.x == IVR_LANE_VOXEL)
    dd = axis_weight(lane.y, ix, fx, dims.x) * axis_weight(lane.z, iy, fy, dims.y) *
         axis_weight(lane.w, iz, fz, dims.z);
#else
  (void)ix, (void)iy, (void)iz, (void)fx, (void)fy, (void)fz, (void)dims;
#endif
  return dd;
}

// The gradient d density / d u at a sample (camera lanes), from the cell's corners; 0 along an
// axis where the position is clamped to the edge centres.
inline void sample_gradient(const TangentRay* tr, __global const real* volume, int4 dims, vint ix,
                            vint iy, vint iz, vreal fx, vreal fy, vreal fz, vreal ux, vreal uy,
                            vreal uz, vreal* gx, vreal* gy, vreal* gz) {
#if IVR_TANGENT_CAMERA
  const int ox = ix + 1 < dims.x ? 1 : 0, oy = iy + 1 < dims.y ? dims.x : 0,
            oz = iz + 1 < dims.z ? dims.x * dims.y : 0;
  __global const real* q = volume + ((iz * dims.y + iy) * dims.x + ix);
  const real v[8] = {q[0],  q[ox],      q[oy],      q[oy + ox],
                     q[oz], q[oz + ox], q[oz + oy], q[oz + oy + ox]};
  trilinear_gradient_within(v, fx, fy, fz, ux, uy, uz, tr->grid_lo, tr->grid_hi, gx, gy, gz);
#else
  (void)tr, (void)volume, (void)dims, (void)ix, (void)iy, (void)iz, (void)fx, (void)fy, (void)fz;
  (void)ux, (void)uy, (void)uz;
  *gx = *gy = *gz = (vreal)(real)0;
#endif
}

// The end of a march: absorption sums the optical depth's tangent in dT along the ray (as it sums
// τ itself, march_finish), then dT = −T·dτ.
inline void tangent_finish(TangentRay* tr, Radiance* r) {
  march_finish(r);
#if !IVR_EMISSION
  IVR_FOR_LANES(p) tr->dT[p] *= -r->transmittance;
#else
  (void)tr;
#endif
}

#endif
