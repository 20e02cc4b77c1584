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
#include "jacobian_pixel.cl"
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
                      hit ? &m : (const March*)0, box_min, box_max, dims);
    Radiance r = radiance_begin();
    if (hit)
      tangent_march(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, min_transmittance,
                    occupied, bricks, &tr, &r);

    tangent_pixels(&r, &tr, ray, x0, y0, view, width, height, background, target, norm, image,
                   jacobian, &loss, dloss);
  }

#if IVR_LOSS_GRADIENT
  tangent_group_sums(loss, dloss, scratch, partial);
#else
  (void)scratch, (void)partial, (void)loss;
#endif
}
