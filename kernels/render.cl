// render.cl — the forward renderer: one work-item per pixel and view, midpoint rule with a fixed
// step on the exactly clipped ray, early termination, both optical models.
#include "config.cl"
#include "geometry.cl"
#include "tf.cl"

// exp(-x), and in *fraction (1 - exp(-x)) / x: the share of a constant segment's emission that
// leaves it (1 at x = 0). No (1 - alpha) division and no cancellation: float64 uses expm1; float32
// uses one exp (expm1 costs as much again on CPUs) and a series below x = 0.1, whose truncation
// (x^6/720 < 2e-9) and the cancellation above it (< 1e-6 relative) stay within float32 rounding.
inline real decay_and_fraction(real x, real* fraction) {
#if IVR_F64
  *fraction = x > (real)0 ? -expm1(-x) / x : (real)1;
  return exp(-x);
#else
  const real decay = exp(-x);
  *fraction = x < 0.1f ? 1.0f - x * (0.5f - x * (1.0f / 6 - x * (1.0f / 24 - x * (1.0f / 120))))
                       : (1.0f - decay) / x;
  return decay;
#endif
}

__kernel void render(__global const real* restrict volume, const int4 dims,
                     const real4 box_min, const real4 box_max, const real4 inv_voxel,
                     __global const real* restrict cameras, const int width, const int height,
                     __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                     const real4 background, const real step, const real min_transmittance,
                     __global float* restrict image, __global uint* restrict samples) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  if (x >= width || y >= height) return;

  const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
  real transmittance = (real)1;
#if IVR_EMISSION
  real3 color = (real3)(0);
#endif
  uint taken = 0;
  real t0, t1;
  if (clip_box(ray, box_min.xyz, box_max.xyz, &t0, &t1)) {
    // n equal sub-steps of at most `step` cover [t0, t1] exactly.
    const real length = t1 - t0;
    const uint n = max((uint)1, (uint)ceil(length / step));
    const real dt = length / (real)n;
    // Continuous voxel coordinates along the ray: u(t) = u0 + t·du, voxel centre i at u = i.
    const real3 u0 = (ray.origin - box_min.xyz) * inv_voxel.xyz - (real)0.5;
    const real3 du = ray.dir * inv_voxel.xyz;
    for (uint i = 0; i < n; ++i) {
      const real t = t0 + ((real)i + (real)0.5) * dt;
      const real d = trilinear(volume, dims, u0 + t * du);
      real3 emission;
      const real sigma = tf_eval(d, tf, tf_count, tf_scalars, &emission);
      real fraction;
      const real decay = decay_and_fraction(sigma * dt, &fraction);
#if IVR_EMISSION
      color += transmittance * dt * fraction * emission;
#endif
      transmittance *= decay;
      ++taken;
#if IVR_EARLY_TERMINATION
      if (transmittance < min_transmittance) break;
#endif
    }
  }

  const size_t pixel = ((size_t)view * height + y) * width + x;
  samples[pixel] = taken;
#if IVR_EMISSION
  color += transmittance * background.xyz;
  __global float* out = image + pixel * 4;
  out[0] = (float)color.x;
  out[1] = (float)color.y;
  out[2] = (float)color.z;
  out[3] = (float)((real)1 - transmittance);
#else
  image[pixel] = (float)(background.x * transmittance);
#endif
}
