// jacobian_pixel.cl — what a forward-mode march ends in (kernels/jacobian.cl in core,
// bricked_tangent.cl out of core): each ray's pixel, its loss terms and the lanes' tangents of
// the pixel (the Jacobian's entries, the loss's derivatives, a listed ray's own gradient), and the
// work-group's sums of the loss and its derivatives.
#ifndef IVR_JACOBIAN_PIXEL_CL
#define IVR_JACOBIAN_PIXEL_CL
#include "config.cl"
#include "jacobian_ray.cl"
#include "loss.cl"
#include "primal.cl"
#include "rays.cl"

#ifndef IVR_JACOBIAN
#define IVR_JACOBIAN 1
#endif
#ifndef IVR_LOSS_GRADIENT
#define IVR_LOSS_GRADIENT 1
#endif
// Each ray's own d loss / d lane into `jacobian` (pixel-major, IVR_LANES a pixel) instead of the
// Jacobian: a ray list's lanes (IVR_LANE_RAY, lanes 0..7 = columns 0..7), each ray's pixel
// depending on its own ray only. The direction's three are projected onto the plane normal to it:
// ivr normalises the directions it is given, so only their tangential change moves the ray.
#ifndef IVR_RAY_GRADIENT
#define IVR_RAY_GRADIENT 0
#endif
#if IVR_RAY_GRADIENT && (IVR_JACOBIAN || !IVR_LOSS_GRADIENT || IVR_LANES != 8 || IVR_RAYS != 1)
#error "IVR_RAY_GRADIENT takes the loss gradient, no Jacobian, 8 lanes and one ray per work-item"
#endif

// The pixels of the tile with corner (x0, y0) of `view` (one pixel, or a packet's) from their
// finished march (*r, *tr: tangent_finish() done): the image, the Jacobian (IVR_JACOBIAN), each
// listed ray's own loss gradient (IVR_RAY_GRADIENT, into `jacobian`); the loss terms added to
// *loss and the loss's derivatives to dloss[lane] (IVR_LOSS_GRADIENT).
inline void tangent_pixels(const Radiance* r, const TangentRay* tr, Ray ray, int x0, int y0,
                           int view, int width, int height, real4 background,
                           __global const real* target, real norm, __global real* image,
                           __global real* jacobian, real* loss, real* dloss) {
  (void)ray, (void)target, (void)norm, (void)loss, (void)dloss, (void)jacobian;
  // Each ray's pixel and its loss terms; then the tangents, lane by lane.
  real transmittance[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS];
  IVR_STORE_RAYS(r->transmittance, transmittance);
  IVR_STORE_RAYS(r->cr, cr);
  IVR_STORE_RAYS(r->cg, cg);
  IVR_STORE_RAYS(r->cb, cb);
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
      g[l][c] = loss_term(value[c], target[pixel * IVR_CHANNELS + c], norm, loss);
#endif
  }
  // The pixels' tangents; the background's own lanes.
#if IVR_RAY_GRADIENT
  real per_ray[IVR_LANES];
#endif
  IVR_FOR_LANES(p) {
    const int4 lane = tr->lane[p];
    real dT[IVR_RAYS], dcr[IVR_RAYS], dcg[IVR_RAYS], dcb[IVR_RAYS];
    IVR_STORE_RAYS(tr->dT[p], dT);
    IVR_STORE_RAYS(tr->dcr[p], dcr);
    IVR_STORE_RAYS(tr->dcg[p], dcg);
    IVR_STORE_RAYS(tr->dcb[p], dcb);
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

// The work-group's loss and gradient: summed in local memory in a fixed order (deterministic),
// one row of IVR_LANES + 1 values per group. Every item of the group calls it.
inline void tangent_group_sums(real loss, const real* dloss, __local real* scratch,
                               __global real* partial) {
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
}

#endif
