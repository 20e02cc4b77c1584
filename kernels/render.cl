// render.cl — the forward renderer: one work-item per pixel and view, the scene's integrator on the
// exactly clipped ray (kernels/primal.cl), early termination, empty-space skipping, both optical
// models.
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "primal.cl"

__kernel void render(__global const real* restrict volume, const int4 dims, const real4 box_min,
                     const real4 box_max, const real4 inv_voxel,
                     __global const real* restrict cameras, const int width, const int height,
                     __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                     const real4 background, const real step, const real min_transmittance,
                     __global const uchar* restrict occupied, const int4 bricks,
                     __global real* restrict image, __global uint* restrict samples) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;

  const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
  Radiance r = radiance_begin();
  March m;
  if (march_begin(ray, cameras + view * IVR_CAMERA_STRIDE, x, y, width, height, box_min, box_max,
                  inv_voxel, step, &m))
    primal_march(volume, dims, &m, tf, tf_count, tf_scalars, min_transmittance, occupied, bricks,
                 &r);

  const size_t pixel = ((size_t)view * height + y) * width + x;
  samples[pixel] = r.samples;
#if IVR_EMISSION
  __global real* out = image + pixel * 4;  // the image in the precision it was computed in
  out[0] = r.cr + r.transmittance * background.x;
  out[1] = r.cg + r.transmittance * background.y;
  out[2] = r.cb + r.transmittance * background.z;
  out[3] = (real)1 - r.transmittance;
#else
  image[pixel] = background.x * r.transmittance;
#endif
}
