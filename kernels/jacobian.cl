// jacobian.cl — forward-mode derivatives, one work-item per pixel (or per packet of IVR_RAYS
// neighbouring pixels in vector lanes on CPUs, kernels/rays.cl: TF and background lanes, midpoint
// and trapezoid): the scene's integrator's march carrying IVR_LANES tangent lanes
// (jacobian_<scheme>.cl), each the derivative of every quantity with respect to one parameter (a
// TF parameter, a camera component, a background channel, a voxel, one column of every listed
// ray's own row), through ray generation, clipping, sampling, the TF and compositing. Writes the
// Jacobian of the pixel (IVR_JACOBIAN), each ray's own loss gradient (IVR_RAY_GRADIENT) and/or
// this work-group's share of the loss and its gradient (IVR_LOSS_GRADIENT), reduced in local
// memory without writing the Jacobian.
#include "config.cl"
#include "geometry.cl"
#include "loss.cl"
#include "march.cl"
#include "primal.cl"
#include "rays.cl"
#include "jacobian_ray.cl"
// Every scheme's march (the files' own include lines are resolved once, wherever they first
// appear, so none is included under a condition); the scheme's is called.
#include "jacobian_endpoints.cl"
#include "jacobian_exact.cl"
#include "jacobian_midpoint.cl"
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
#define tangent_march tangent_march_midpoint
#elif IVR_ENDPOINT_SAMPLES
#define tangent_march tangent_march_endpoints
#else
#define tangent_march tangent_march_exact
#endif

#ifndef IVR_JACOBIAN
#define IVR_JACOBIAN 1
#endif
#ifndef IVR_LOSS_GRADIENT
#define IVR_LOSS_GRADIENT 1
#endif
// Each ray's own d loss / d lane into `jacobian` (pixel-major, IVR_LANES a pixel) instead of the
// Jacobian: a ray list's lanes (IVR_LANE_RAY, lanes 0..7 = columns 0..7), each ray's pixel depending
// on its own ray only. The direction's three are projected onto the plane normal to it: ivr
// normalises the directions it is given, so only their tangential change moves the ray.
#ifndef IVR_RAY_GRADIENT
#define IVR_RAY_GRADIENT 0
#endif
#if IVR_RAY_GRADIENT && (IVR_JACOBIAN || !IVR_LOSS_GRADIENT || IVR_LANES != 8 || IVR_RAYS != 1)
#error "IVR_RAY_GRADIENT takes the loss gradient, no Jacobian, 8 lanes and one ray per work-item"
#endif

__kernel void jacobian(__global const real* restrict volume, const int4 dims, const real4 box_min,
                       const real4 box_max, const real4 inv_voxel,
                       __global const real* restrict cameras, const int width, const int height,
                       __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                       const real4 background, const real step, const real min_transmittance,
                       __global const int4* restrict lanes,
                       __global const real* restrict camera_params,
                       __global const real* restrict target, const real norm,
                       __global real* restrict image, __global real* restrict jacobian,
                       __global real* restrict partial, __local real* scratch,
                       __global const uchar* restrict occupied, const int4 bricks) {
  // One pixel, or the tile of a packet (kernels/rays.cl), with corner (x0, y0).
  const int x0 = get_global_id(0) * IVR_PACKET_W, y0 = get_global_id(1) * IVR_PACKET_H;
  const int view = get_global_id(2);
  const bool active = x0 < width && y0 < height;  // padding items still meet the barrier
  real loss = (real)0, dloss[IVR_LANES];
  IVR_FOR_LANES(p) dloss[p] = (real)0;

  if (active) {
    __global const real* cam = cameras + view * IVR_CAMERA_STRIDE;
    March m;
#if IVR_RAYS == 1
    const Ray ray = camera_ray(cam, x0, y0, width, height);
    const bool hit =
        march_begin(ray, cam, x0, y0, width, height, box_min, box_max, inv_voxel, step, &m);
#else
    // A packet carries no camera lanes: the rays' own geometry is in their marches.
    const Ray ray = {(real3)(real)0, (real3)(real)0};
    const bool hit =
        march_begin_rays(cam, x0, y0, width, height, box_min, box_max, inv_voxel, step, &m);
#endif
    TangentRay tr;
    tangent_ray_begin(&tr, lanes, cam, camera_params, view, x0, y0, width, height, ray,
                      hit ? &m : (const March*)0, box_min, box_max);
    Radiance r = radiance_begin();
    if (hit)
      tangent_march(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, min_transmittance,
                    occupied, bricks, &tr, &r);

    // Each ray's pixel and its loss terms; then the tangents, lane by lane.
    real transmittance[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS];
    IVR_STORE_RAYS(r.transmittance, transmittance);
    IVR_STORE_RAYS(r.cr, cr);
    IVR_STORE_RAYS(r.cg, cg);
    IVR_STORE_RAYS(r.cb, cb);
#if IVR_LOSS_GRADIENT
    real g[IVR_RAYS][IVR_CHANNELS];
#endif
    for (int l = 0; l < IVR_RAYS; ++l) {
      const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
      if (x >= width || y >= height) continue;
      const size_t pixel = ((size_t)view * height + y) * width + x;
      real value[IVR_CHANNELS];
#if IVR_EMISSION
      value[0] = cr[l] + transmittance[l] * background.x;
      value[1] = cg[l] + transmittance[l] * background.y;
      value[2] = cb[l] + transmittance[l] * background.z;
      value[3] = (real)1 - transmittance[l];
#else
      value[0] = background.x * transmittance[l];
#endif
      for (int c = 0; c < IVR_CHANNELS; ++c) image[pixel * IVR_CHANNELS + c] = value[c];
#if IVR_LOSS_GRADIENT
      for (int c = 0; c < IVR_CHANNELS; ++c)
        g[l][c] = loss_term(value[c], target[pixel * IVR_CHANNELS + c], norm, &loss);
#endif
    }
    // The pixels' tangents; the background's own lanes.
#if IVR_RAY_GRADIENT
    real per_ray[IVR_LANES];
#endif
    IVR_FOR_LANES(p) {
      const int4 lane = tr.lane[p];
      real dT[IVR_RAYS], dcr[IVR_RAYS], dcg[IVR_RAYS], dcb[IVR_RAYS];
      IVR_STORE_RAYS(tr.dT[p], dT);
      IVR_STORE_RAYS(tr.dcr[p], dcr);
      IVR_STORE_RAYS(tr.dcg[p], dcg);
      IVR_STORE_RAYS(tr.dcb[p], dcb);
      for (int l = 0; l < IVR_RAYS; ++l) {
        const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
        if (x >= width || y >= height) continue;
        const size_t pixel = ((size_t)view * height + y) * width + x;
        real dv[IVR_CHANNELS];
#if IVR_EMISSION
        const real bg[3] = {background.x, background.y, background.z};
        const real dc[3] = {dcr[l], dcg[l], dcb[l]};
        for (int c = 0; c < 3; ++c)
          dv[c] = dc[c] + dT[l] * bg[c] +
                  (lane.x == IVR_LANE_BACKGROUND && lane.y == c ? transmittance[l] : (real)0);
        dv[3] = -dT[l];
#else
        (void)dcr, (void)dcg, (void)dcb;
        dv[0] = background.x * dT[l] + (lane.x == IVR_LANE_BACKGROUND ? transmittance[l] : (real)0);
#endif
#if IVR_JACOBIAN
        for (int c = 0; c < IVR_CHANNELS; ++c)
          jacobian[(pixel * IVR_CHANNELS + c) * IVR_LANES + p] = dv[c];
#endif
#if IVR_LOSS_GRADIENT
        for (int c = 0; c < IVR_CHANNELS; ++c) dloss[p] += g[l][c] * dv[c];
#endif
#if IVR_RAY_GRADIENT
        per_ray[p] = (real)0;
        for (int c = 0; c < IVR_CHANNELS; ++c) per_ray[p] += g[l][c] * dv[c];
#endif
      }
    }
#if IVR_RAY_GRADIENT
    {
      const real along = ray.dir.x * per_ray[3] + ray.dir.y * per_ray[4] + ray.dir.z * per_ray[5];
      per_ray[3] -= along * ray.dir.x;
      per_ray[4] -= along * ray.dir.y;
      per_ray[5] -= along * ray.dir.z;
      const size_t pixel = ((size_t)view * height + y0) * width + x0;
      IVR_FOR_LANES(p) jacobian[pixel * IVR_LANES + p] = per_ray[p];
    }
#endif
  }

#if IVR_LOSS_GRADIENT
  // The work-group's loss and gradient: summed in local memory in a fixed order (deterministic),
  // one row of IVR_LANES + 1 values per group.
  const int lid = get_local_id(1) * get_local_size(0) + get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1);
  scratch[lid * (IVR_LANES + 1)] = loss;
  IVR_FOR_LANES(p) scratch[lid * (IVR_LANES + 1) + 1 + p] = dloss[p];
  barrier(CLK_LOCAL_MEM_FENCE);
  const size_t group =
      ((size_t)get_group_id(2) * get_num_groups(1) + get_group_id(1)) * get_num_groups(0) +
      get_group_id(0);
  for (int k = lid; k < IVR_LANES + 1; k += lsize) {
    real sum = (real)0;
    for (int i = 0; i < lsize; ++i) sum += scratch[i * (IVR_LANES + 1) + k];
    partial[group * (IVR_LANES + 1) + k] = sum;
  }
#endif
}
