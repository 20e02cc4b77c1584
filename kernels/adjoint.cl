// adjoint.cl — reverse-mode gradients, one work-item per pixel: the primal march gives the pixel
// and its loss gradient (kernels/primal.cl), a second front-to-back march of the scene's
// integrator (adjoint_<scheme>.cl) recovers each sample's remaining radiance as C minus the prefix
// (no division by 1 − α, no per-sample storage) and scatters dL/d density to the voxels (through
// the cell cache, once per voxel a ray touches, and the work-group's table where the host turns
// it on: kernels/scatter_cache.cl), dL/d TF into the work-group's local accumulator
// (added to global memory once per group) and dL/d camera into per-group partial sums.
#include "adjoint_ray.cl"
#include "atomics.cl"
#include "config.cl"
#include "geometry.cl"
#include "loss.cl"
#include "march.cl"
#include "primal.cl"
#include "scatter_cache.cl"
#include "adjoint_tf.cl"
// Every scheme's march (the files' own include lines are resolved once, wherever they first
// appear, so none is included under a condition); the scheme's is called.
#include "adjoint_endpoints.cl"
#include "adjoint_exact.cl"
#include "adjoint_midpoint.cl"
// IVR_PRIMAL_GIVEN: the primal march already ran (the CPU packet render, lib/adjoint/adjoint.cpp): each
// pixel's emitted colour and transmittance are in `image` and its samples in `samples`, read
// before this item overwrites them with the pixel.
#ifndef IVR_PRIMAL_GIVEN
#define IVR_PRIMAL_GIVEN 0
#endif
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
#define adjoint_march adjoint_march_midpoint
#elif IVR_ENDPOINT_SAMPLES
#define adjoint_march adjoint_march_endpoints
#else
#define adjoint_march adjoint_march_exact
#endif

__kernel void adjoint(__global const real* restrict volume, const int4 dims, const real4 box_min,
                      const real4 box_max, const real4 inv_voxel,
                      __global const real* restrict cameras, const int width, const int height,
                      __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                      const real4 background, const real step, const real min_transmittance,
                      __global const real* restrict target, const real norm,
                      __global real* restrict image, __global real* restrict pixel_terms,
                      __global real* restrict grad_volume, __global real* restrict grad_tf,
                      __local real* tf_acc, const int tf_acc_size, __global uint* restrict samples,
                      __global const real* restrict camera_params,
                      __global real* restrict camera_partial, __local real* camera_scratch,
                      __global const uchar* restrict occupied, const int4 bricks) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  const bool active = x < width && y < height;  // padding items still meet the barriers
  const int lid = get_local_id(1) * get_local_size(0) + get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1);
  // The density gradient's adds, through the group's table where the host turned it on
  // (kernels/scatter_cache.cl: its barriers are met by every item, padding included).
  IVR_SCATTER_SINK(density, grad_volume);
#if IVR_GRAD_TF
  for (int i = lid; i < tf_acc_size; i += lsize) tf_acc[i] = (real)0;
  barrier(CLK_LOCAL_MEM_FENCE);
#endif
#if IVR_GRAD_CAMERA
  real camera_terms[7] = {0, 0, 0, 0, 0, 0, 0};  // this pixel's dL / d camera component
#endif

  if (active) {
    const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
    March m;
    const bool hit = march_begin(ray, cameras + view * IVR_CAMERA_STRIDE, x, y, width, height, box_min,
                                 box_max, inv_voxel, step, &m);
    Radiance r = radiance_begin();
    const size_t pixel = ((size_t)view * height + y) * width + x;
#if IVR_PRIMAL_GIVEN && IVR_EMISSION && IVR_SCHEME == IVR_SCHEME_MIDPOINT
    r.cr = image[pixel * 4 + 0];
    r.cg = image[pixel * 4 + 1];
    r.cb = image[pixel * 4 + 2];
    r.transmittance = image[pixel * 4 + 3];
    r.samples = r.end = samples[pixel];  // the midpoint march: one sample per segment taken
#else
    if (hit)
      primal_march(volume, dims, &m, tf, tf_count, tf_scalars, min_transmittance, occupied, bricks,
                   &r);
#endif

    // The pixel, its loss terms and dL/dpixel.
    __global const real* tgt = target + pixel * IVR_CHANNELS;
    real loss = (real)0;
    AdjointRay ar;
    ar.t_end = r.transmittance;
    ar.end = r.end;
    ar.gr = ar.gg = ar.gb = ar.ga = ar.gi = ar.intensity = (real)0;
#if IVR_EMISSION
    ar.total_r = r.cr + r.transmittance * background.x;
    ar.total_g = r.cg + r.transmittance * background.y;
    ar.total_b = r.cb + r.transmittance * background.z;
    const real alpha = (real)1 - r.transmittance;
    ar.gr = loss_term(ar.total_r, tgt[0], norm, &loss);
    ar.gg = loss_term(ar.total_g, tgt[1], norm, &loss);
    ar.gb = loss_term(ar.total_b, tgt[2], norm, &loss);
    ar.ga = loss_term(alpha, tgt[3], norm, &loss);
    __global real* out = image + pixel * 4;
    out[0] = ar.total_r;
    out[1] = ar.total_g;
    out[2] = ar.total_b;
    out[3] = alpha;
    pixel_terms[pixel * 4 + 0] = loss;
    pixel_terms[pixel * 4 + 1] = ar.gr * r.transmittance;  // dL/dbackground, per pixel
    pixel_terms[pixel * 4 + 2] = ar.gg * r.transmittance;
    pixel_terms[pixel * 4 + 3] = ar.gb * r.transmittance;
#else
    ar.total_r = ar.total_g = ar.total_b = (real)0;
    ar.intensity = background.x * r.transmittance;
    ar.gi = loss_term(ar.intensity, tgt[0], norm, &loss);
    image[pixel] = ar.intensity;
    pixel_terms[pixel * 4 + 0] = loss;
    pixel_terms[pixel * 4 + 1] = ar.gi * r.transmittance;
    pixel_terms[pixel * 4 + 2] = (real)0;
    pixel_terms[pixel * 4 + 3] = (real)0;
#endif
    samples[pixel] = r.samples;

    if (hit) {
      TfGradCache tf_cache;
      tf_cache_init(&tf_cache);
      CameraSums cs;
      camera_sums_init(&cs, m.t1);
      adjoint_march(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, &ar, occupied,
                    bricks, density, &tf_cache, tf_acc, &cs);
#if IVR_GRAD_TF
      tf_cache_flush(&tf_cache, tf_acc);
#endif
#if IVR_GRAD_CAMERA
      camera_terms_of(&cs, ray, m.t0, box_min, box_max,
                      camera_params + view * IVR_CAMERA_PARAMS_STRIDE, width, height, x, y,
                      camera_terms);
#endif
    }
  }

#if IVR_GRAD_CAMERA
  // The work-group's camera gradient, summed in a fixed order (its view: the group's z).
  for (int k = 0; k < 7; ++k) camera_scratch[lid * 7 + k] = camera_terms[k];
  barrier(CLK_LOCAL_MEM_FENCE);
  const size_t group =
      ((size_t)get_group_id(2) * get_num_groups(1) + get_group_id(1)) * get_num_groups(0) +
      get_group_id(0);
  for (int k = lid; k < 7; k += lsize) {
    real sum = (real)0;
    for (int i = 0; i < lsize; ++i) sum += camera_scratch[i * 7 + k];
    camera_partial[group * 7 + k] = sum;
  }
#endif

  scatter_flush(density);
#if IVR_GRAD_TF
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int i = lid; i < tf_acc_size; i += lsize)
    if (tf_acc[i] != (real)0) atomic_add_global(grad_tf + i, tf_acc[i]);
#endif
}
