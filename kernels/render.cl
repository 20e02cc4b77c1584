// render.cl — the forward renderer: one work-item per pixel and view, midpoint rule with a fixed
// step on the exactly clipped ray, early termination, empty-space skipping, both optical models.
#include "compositing.cl"
#include "config.cl"
#include "empty_space.cl"
#include "geometry.cl"
#include "tf.cl"

__kernel void render(__global const real* restrict volume, const int4 dims, const real4 box_min,
                     const real4 box_max, const real4 inv_voxel,
                     __global const real* restrict cameras, const int width, const int height,
                     __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                     const real4 background, const real step, const real min_transmittance,
                     __global const uchar* restrict occupied, const int4 bricks,
                     __global float* restrict image, __global uint* restrict samples) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;

  const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
  real transmittance = (real)1;
#if IVR_EMISSION
  real cr = (real)0, cg = (real)0, cb = (real)0;
  real kr = (real)0, kg = (real)0, kb = (real)0;  // compensation (accumulate)
#endif
  uint taken = 0;
  real t0, t1;
  if (clip_box(ray, box_min.xyz, box_max.xyz, &t0, &t1)) {
    // n equal sub-steps of at most `step` cover [t0, t1] exactly.
    const real length = t1 - t0;
    const uint n = max((uint)1, (uint)ceil(length / step));
    const real dt = length / (real)n;
    // Continuous voxel coordinates along the ray: u(t) = u0 + t·du, voxel centre i at u = i.
    // Scalars, not real3: PoCL compiles real3 into padded 4-wide vectors and lane shuffles.
    const real u0x = (ray.origin.x - box_min.x) * inv_voxel.x - (real)0.5;
    const real u0y = (ray.origin.y - box_min.y) * inv_voxel.y - (real)0.5;
    const real u0z = (ray.origin.z - box_min.z) * inv_voxel.z - (real)0.5;
    const real dux = ray.dir.x * inv_voxel.x, duy = ray.dir.y * inv_voxel.y,
               duz = ray.dir.z * inv_voxel.z;
    int segment = 0;  // the transfer function's search cursor (tf_sample)

    for (uint i = 0; i < n;) {
      const real t = t0 + ((real)i + (real)0.5) * dt;
      const real ux = u0x + t * dux, uy = u0y + t * duy, uz = u0z + t * duz;
#if IVR_SKIP_EMPTY
      // (Reading the grid at every sample measured faster on PoCL than tracking where the ray
      // leaves each occupied brick: bench/empty_space_bench.cpp.)
      IVR_SKIP_EMPTY_BRICK(i, n, ux, uy, uz)
#endif
      const real d = trilinear_at(volume, dims, ux, uy, uz);
      real er, eg, eb;
      const real sigma = tf_sample(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb);
      const real tau = sigma * dt;
      real fraction;
      const real decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
      const real weight = transmittance * dt * fraction;
      accumulate(&cr, &kr, weight * er);
      accumulate(&cg, &kg, weight * eg);
      accumulate(&cb, &kb, weight * eb);
#endif
      transmittance = attenuate(transmittance, tau, fraction, decay);
      ++taken;
      ++i;
#if IVR_EARLY_TERMINATION
      if (transmittance < min_transmittance) break;
#endif
    }
  }

  const size_t pixel = ((size_t)view * height + y) * width + x;
  samples[pixel] = taken;
#if IVR_EMISSION
  __global float* out = image + pixel * 4;
  out[0] = (float)(cr + transmittance * background.x);
  out[1] = (float)(cg + transmittance * background.y);
  out[2] = (float)(cb + transmittance * background.z);
  out[3] = (float)((real)1 - transmittance);
#else
  image[pixel] = (float)(background.x * transmittance);
#endif
}
