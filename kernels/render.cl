// render.cl — the forward renderer: one work-item per pixel, or per tile of IVR_RAYS neighbouring
// pixels (a packet of 8 or 16 in vector lanes on CPUs, kernels/rays.cl), and view, the scene's
// integrator on the exactly clipped ray (kernels/primal.cl), early termination, empty-space
// skipping, both optical models. A packet's image is the one-ray kernel's bit for bit.
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "primal.cl"
#include "rays.cl"

// IVR_PACKET_PRIMAL: the adjoint's primal march (lib/adjoint/adjoint.cpp; emission–absorption):
// each pixel's emitted colour C and transmittance T into `image` (not C + T·background, 1 − T),
// for kernels/adjoint.cl to read.
#ifndef IVR_PACKET_PRIMAL
#define IVR_PACKET_PRIMAL 0
#endif

__kernel void render(__global const real* restrict volume, const int4 dims, const real4 box_min,
                     const real4 box_max, const real4 inv_voxel,
                     __global const real* restrict cameras, const int width, const int height,
                     __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                     const real4 background, const real step, const real min_transmittance,
                     __global const uchar* restrict occupied, const int4 bricks,
                     __global real* restrict image, __global uint* restrict samples) {
  const int x0 = get_global_id(0) * IVR_PACKET_W, y0 = get_global_id(1) * IVR_PACKET_H;
  const int view = get_global_id(2);
  if (x0 >= width || y0 >= height) return;
  __global const real* cam = cameras + view * IVR_CAMERA_STRIDE;

  Radiance r = radiance_begin();
  March m;
#if IVR_RAYS == 1
  const bool hit = march_begin(camera_ray(cam, x0, y0, width, height), cam, x0, y0, width, height,
                               box_min, box_max, inv_voxel, step, &m);
#else
  const bool hit =
      march_begin_rays(cam, x0, y0, width, height, box_min, box_max, inv_voxel, step, &m);
#endif
  if (hit)
    primal_march(volume, dims, &m, tf, tf_count, tf_scalars, min_transmittance, occupied, bricks,
                 &r);

  real o0[IVR_RAYS], o1[IVR_RAYS], o2[IVR_RAYS], o3[IVR_RAYS];
  int taken[IVR_RAYS];
  IVR_STORE_RAYS(r.samples, taken);
#if IVR_EMISSION
#if IVR_PACKET_PRIMAL
  IVR_STORE_RAYS(r.cr, o0);
  IVR_STORE_RAYS(r.cg, o1);
  IVR_STORE_RAYS(r.cb, o2);
  IVR_STORE_RAYS(r.transmittance, o3);
#else
  IVR_STORE_RAYS(r.cr + r.transmittance * background.x, o0);
  IVR_STORE_RAYS(r.cg + r.transmittance * background.y, o1);
  IVR_STORE_RAYS(r.cb + r.transmittance * background.z, o2);
  IVR_STORE_RAYS((real)1 - r.transmittance, o3);
#endif
#else
  IVR_STORE_RAYS(background.x * r.transmittance, o0);
  (void)o1, (void)o2, (void)o3;
#endif
  for (int l = 0; l < IVR_RAYS; ++l) {
    const int x = x0 + IVR_LANE_X(l), y = y0 + IVR_LANE_Y(l);
    if (x >= width || y >= height) continue;
    const size_t pixel = ((size_t)view * height + y) * width + x;
    samples[pixel] = (uint)taken[l];
#if IVR_EMISSION
    __global real* out = image + pixel * 4;  // the image in the precision it was computed in
    out[0] = o0[l];
    out[1] = o1[l];
    out[2] = o2[l];
    out[3] = o3[l];
#else
    image[pixel] = o0[l];
#endif
  }
}
