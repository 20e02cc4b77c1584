// adjoint.cl — reverse-mode gradients, one work-item per pixel: a primal march gives the pixel and
// its loss gradient, a second front-to-back march recovers each sample's remaining radiance as
// C minus the prefix (no division by 1 - alpha, no per-sample storage) and scatters dL/d density
// to the voxels (8 corners kept in registers while the ray stays in one cell) and dL/d TF into
// the work-group's local accumulator, added to global memory once per group.
#include "atomics.cl"
#include "compositing.cl"
#include "config.cl"
#include "geometry.cl"
#include "tf.cl"
#include "tf_grad.cl"

#ifndef IVR_GRAD_DENSITY
#define IVR_GRAD_DENSITY 1
#endif
#ifndef IVR_GRAD_TF
#define IVR_GRAD_TF 0
#endif
#ifndef IVR_LOSS_L1  // 0: mean squared error, 1: mean absolute error
#define IVR_LOSS_L1 0
#endif

#if IVR_EMISSION
#define IVR_CHANNELS 4
#else
#define IVR_CHANNELS 1
#endif

// dL/dpixel for one channel; *loss += its term. `norm` = 1 / (number of elements).
inline real loss_term(real value, real target, real norm, real* loss) {
  const real diff = value - target;
#if IVR_LOSS_L1
  *loss += fabs(diff) * norm;
  return diff > (real)0 ? norm : (diff < (real)0 ? -norm : (real)0);
#else
  *loss += diff * diff * norm;
  return (real)2 * diff * norm;
#endif
}

// Adds the 8 corner contributions of the current cell to the gradient volume.
inline void flush_cell(__global real* grad, int base, int ox, int oy, int oz, real* corner) {
  if (base < 0) return;
  const int offsets[8] = {0, ox, oy, oy + ox, oz, oz + ox, oz + oy, oz + oy + ox};
  for (int k = 0; k < 8; ++k) {
    if (corner[k] != (real)0) atomic_add_global(grad + base + offsets[k], corner[k]);
    corner[k] = (real)0;
  }
}

__kernel void adjoint(__global const real* restrict volume, const int4 dims, const real4 box_min,
                      const real4 box_max, const real4 inv_voxel,
                      __global const real* restrict cameras, const int width, const int height,
                      __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                      const real4 background, const real step, const real min_transmittance,
                      __global const real* restrict target, const real norm,
                      __global float* restrict image, __global real* restrict pixel_terms,
                      __global real* restrict grad_volume, __global real* restrict grad_tf,
                      __local real* tf_acc, const int tf_acc_size,
                      __global uint* restrict samples) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  const bool active = x < width && y < height;  // padding items still meet the barriers
#if IVR_GRAD_TF
  const int lid = get_local_id(1) * get_local_size(0) + get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1);
  for (int i = lid; i < tf_acc_size; i += lsize) tf_acc[i] = (real)0;
  barrier(CLK_LOCAL_MEM_FENCE);
#endif

  if (active) {
    const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
    real t0, t1;
    const bool hit = clip_box(ray, box_min.xyz, box_max.xyz, &t0, &t1);
    uint n = 0;
    real dt = (real)0;
    real u0x = 0, u0y = 0, u0z = 0, dux = 0, duy = 0, duz = 0;
    if (hit) {
      const real length = t1 - t0;
      n = max((uint)1, (uint)ceil(length / step));
      dt = length / (real)n;
      u0x = (ray.origin.x - box_min.x) * inv_voxel.x - (real)0.5;
      u0y = (ray.origin.y - box_min.y) * inv_voxel.y - (real)0.5;
      u0z = (ray.origin.z - box_min.z) * inv_voxel.z - (real)0.5;
      dux = ray.dir.x * inv_voxel.x;
      duy = ray.dir.y * inv_voxel.y;
      duz = ray.dir.z * inv_voxel.z;
    }

    // Primal march: exactly the render kernel's arithmetic, so the gradient is that of what was
    // rendered (including where early termination stopped the ray).
    real transmittance = (real)1, cr = 0, cg = 0, cb = 0;
    real kr = 0, kg = 0, kb = 0;  // compensation (accumulate)
    uint taken = 0;
    int segment = 0;
    for (uint i = 0; i < n; ++i) {
      const real t = t0 + ((real)i + (real)0.5) * dt;
      const real d = trilinear_at(volume, dims, u0x + t * dux, u0y + t * duy, u0z + t * duz);
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
#if IVR_EARLY_TERMINATION
      if (transmittance < min_transmittance) break;
#endif
    }
    const real t_end = transmittance;

    // The pixel, its loss terms and dL/dpixel.
    const size_t pixel = ((size_t)view * height + y) * width + x;
    __global const real* tgt = target + pixel * IVR_CHANNELS;
    real loss = (real)0;
#if IVR_EMISSION
    const real total_r = cr + t_end * background.x, total_g = cg + t_end * background.y,
               total_b = cb + t_end * background.z, alpha = (real)1 - t_end;
    const real gr = loss_term(total_r, tgt[0], norm, &loss);
    const real gg = loss_term(total_g, tgt[1], norm, &loss);
    const real gb = loss_term(total_b, tgt[2], norm, &loss);
    const real ga = loss_term(alpha, tgt[3], norm, &loss);
    __global float* out = image + pixel * 4;
    out[0] = (float)total_r;
    out[1] = (float)total_g;
    out[2] = (float)total_b;
    out[3] = (float)alpha;
    pixel_terms[pixel * 4 + 0] = loss;
    pixel_terms[pixel * 4 + 1] = gr * t_end;  // dL/dbackground, per pixel
    pixel_terms[pixel * 4 + 2] = gg * t_end;
    pixel_terms[pixel * 4 + 3] = gb * t_end;
#else
    const real intensity = background.x * t_end;
    const real gi = loss_term(intensity, tgt[0], norm, &loss);
    image[pixel] = (float)intensity;
    pixel_terms[pixel * 4 + 0] = loss;
    pixel_terms[pixel * 4 + 1] = gi * t_end;
    pixel_terms[pixel * 4 + 2] = (real)0;
    pixel_terms[pixel * 4 + 3] = (real)0;
#endif
    samples[pixel] = taken;

    // Adjoint march, front to back. dL/dsigma_i needs the radiance remaining behind sample i,
    // R_i = C - prefix_i (prefix including sample i), which includes the background term.
    transmittance = (real)1;
    real pr = 0, pg = 0, pb = 0;  // emission prefix, summed exactly as the primal march summed C
    kr = kg = kb = 0;
    int seg_value = 0, seg_slope = 0, seg_scatter = 0;
    int base = -1, box = 0, boy = 0, boz = 0;
    real corner[8] = {0, 0, 0, 0, 0, 0, 0, 0};
#if IVR_GRAD_TF
    TfGradCache tf_cache;
    tf_cache_init(&tf_cache);
#endif
    for (uint i = 0; i < taken; ++i) {
      const real t = t0 + ((real)i + (real)0.5) * dt;
      const real ux = u0x + t * dux, uy = u0y + t * duy, uz = u0z + t * duz;
      const real d = trilinear_at(volume, dims, ux, uy, uz);
      real er, eg, eb;
      const real sigma = tf_sample(d, tf, tf_count, tf_scalars, &seg_value, &er, &eg, &eb);
      const real tau = sigma * dt;
      real fraction;
      const real decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
      const real weight = transmittance * dt * fraction;
      accumulate(&pr, &kr, weight * er);
      accumulate(&pg, &kg, weight * eg);
      accumulate(&pb, &kb, weight * eb);
      const real slope = transmittance * dt * dt * fraction_slope(tau, decay, fraction);
      const real gsigma = gr * (slope * er - dt * (total_r - pr)) +
                          gg * (slope * eg - dt * (total_g - pg)) +
                          gb * (slope * eb - dt * (total_b - pb)) + ga * dt * t_end;
      const real ger = gr * weight, geg = gg * weight, geb = gb * weight;
#else
      const real gsigma = -dt * intensity * gi;
      const real ger = (real)0, geg = (real)0, geb = (real)0;
#endif
      transmittance = attenuate(transmittance, tau, fraction, decay);

#if IVR_GRAD_DENSITY
      real der, deg, deb;
      const real dsigma = tf_slope(d, tf, tf_count, tf_scalars, &seg_slope, &der, &deg, &deb);
      const real gd = gsigma * dsigma + ger * der + geg * deg + geb * deb;
      // The cell and trilinear weights of this sample (as trilinear_at clamps and indexes them).
      const real cx = fmin(fmax(ux, (real)0), (real)(dims.x - 1));
      const real cy = fmin(fmax(uy, (real)0), (real)(dims.y - 1));
      const real cz = fmin(fmax(uz, (real)0), (real)(dims.z - 1));
      const int ix = (int)cx, iy = (int)cy, iz = (int)cz;
      const real fx = cx - (real)ix, fy = cy - (real)iy, fz = cz - (real)iz;
      const int cell = (iz * dims.y + iy) * dims.x + ix;
      if (cell != base) {
        flush_cell(grad_volume, base, box, boy, boz, corner);
        base = cell;
        box = ix + 1 < dims.x ? 1 : 0;
        boy = iy + 1 < dims.y ? dims.x : 0;
        boz = iz + 1 < dims.z ? dims.x * dims.y : 0;
      }
      const real gx0 = gd * ((real)1 - fx), gx1 = gd * fx;
      const real wy0z0 = ((real)1 - fy) * ((real)1 - fz), wy1z0 = fy * ((real)1 - fz);
      const real wy0z1 = ((real)1 - fy) * fz, wy1z1 = fy * fz;
      corner[0] += gx0 * wy0z0;
      corner[1] += gx1 * wy0z0;
      corner[2] += gx0 * wy1z0;
      corner[3] += gx1 * wy1z0;
      corner[4] += gx0 * wy0z1;
      corner[5] += gx1 * wy0z1;
      corner[6] += gx0 * wy1z1;
      corner[7] += gx1 * wy1z1;
#endif
#if IVR_GRAD_TF
      tf_scatter(d, tf, tf_count, tf_scalars, &seg_scatter, gsigma, ger, geg, geb, &tf_cache,
                 tf_acc);
#endif
    }
#if IVR_GRAD_DENSITY
    flush_cell(grad_volume, base, box, boy, boz, corner);
#endif
#if IVR_GRAD_TF
    tf_cache_flush(&tf_cache, tf_acc);
#endif
  }

#if IVR_GRAD_TF
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int i = lid; i < tf_acc_size; i += lsize)
    if (tf_acc[i] != (real)0) atomic_add_global(grad_tf + i, tf_acc[i]);
#endif
}
