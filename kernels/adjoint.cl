// adjoint.cl — reverse-mode gradients, one work-item per pixel: a primal march gives the pixel and
// its loss gradient, a second front-to-back march recovers each sample's remaining radiance as
// C minus the prefix (no division by 1 - alpha, no per-sample storage) and scatters dL/d density
// to the voxels (the current cell's 8 corners kept in registers and carried across faces, so that
// a ray adds to each voxel it touches once) and dL/d TF into the work-group's local accumulator,
// added to global memory once per group.
#include "atomics.cl"
#include "compositing.cl"
#include "config.cl"
#include "empty_space.cl"
#include "geometry.cl"
#include "geometry_tangent.cl"
#include "loss.cl"
#include "tf.cl"
#include "tf_grad.cl"

#ifndef IVR_GRAD_DENSITY
#define IVR_GRAD_DENSITY 1
#endif
#ifndef IVR_GRAD_TF
#define IVR_GRAD_TF 0
#endif
#ifndef IVR_GRAD_CAMERA  // dL / d (eye, target, fov_y) per view
#define IVR_GRAD_CAMERA 0
#endif

// The adjoint march keeps the ray's current cell in registers: its 8 corner densities v[k] (read
// once per cell, not once per sample) and the gradient of those corners g[k], added to global
// memory when the ray leaves them behind. Corner k (bit 0: +x, bit 1: +y, bit 2: +z) is voxel
// base + IVR_CORNER(k); the offsets are 0 on the clamped upper edges, as in trilinear_at().
#define IVR_CORNER(k) ((((k)&1) ? ox : 0) + (((k)&2) ? oy : 0) + (((k)&4) ? oz : 0))
#define IVR_LOAD(k) v[k] = volume[base + IVR_CORNER(k)]
#if IVR_GRAD_DENSITY
#define IVR_FLUSH(k)                                                                  \
  do {                                                                                \
    if (g[k] != (real)0) atomic_add_global(grad_volume + base + IVR_CORNER(k), g[k]); \
    g[k] = (real)0;                                                                   \
  } while (0)
#define IVR_MOVE_GRAD(to, from) \
  do {                          \
    g[to] = g[from];            \
    g[from] = (real)0;          \
  } while (0)
#else
#define IVR_FLUSH(k) (void)0
#define IVR_MOVE_GRAD(to, from) (void)0
#endif
#define IVR_EACH_CORNER(F) \
  do {                     \
    F(0);                  \
    F(1);                  \
    F(2);                  \
    F(3);                  \
    F(4);                  \
    F(5);                  \
    F(6);                  \
    F(7);                  \
  } while (0)
// Enters cell (X, Y, Z): its base voxel and the neighbour offsets.
#define IVR_SET_CELL(X, Y, Z)                    \
  do {                                           \
    pix = (X);                                   \
    piy = (Y);                                   \
    piz = (Z);                                   \
    base = (piz * dims.y + piy) * dims.x + pix;  \
    ox = pix + 1 < dims.x ? 1 : 0;               \
    oy = piy + 1 < dims.y ? dims.x : 0;          \
    oz = piz + 1 < dims.z ? dims.x * dims.y : 0; \
  } while (0)
// Crossing one face into cell (X, Y, Z), along the axis of bit B. The 4 corners on the shared face
// carry over, density and gradient so far (so a ray adds to each voxel once, not once per cell);
// the 4 left behind are flushed and the 4 ahead read. a..d are the corners with bit B clear; L is
// the bit of those left behind (0 going up, B going down), K = B - L that of those kept, which
// become corners with bit L.
#define IVR_CROSS_ONE(x, L, K)           \
  do {                                   \
    IVR_FLUSH((x) | (L));                \
    IVR_MOVE_GRAD((x) | (L), (x) | (K)); \
    v[(x) | (L)] = v[(x) | (K)];         \
  } while (0)
#define IVR_CROSS(L, K, a, b, c, d, X, Y, Z) \
  do {                                       \
    IVR_CROSS_ONE(a, L, K);                  \
    IVR_CROSS_ONE(b, L, K);                  \
    IVR_CROSS_ONE(c, L, K);                  \
    IVR_CROSS_ONE(d, L, K);                  \
    IVR_SET_CELL(X, Y, Z);                   \
    IVR_LOAD((a) | (K));                     \
    IVR_LOAD((b) | (K));                     \
    IVR_LOAD((c) | (K));                     \
    IVR_LOAD((d) | (K));                     \
  } while (0)

__kernel void adjoint(__global const real* restrict volume, const int4 dims, const real4 box_min,
                      const real4 box_max, const real4 inv_voxel,
                      __global const real* restrict cameras, const int width, const int height,
                      __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                      const real4 background, const real step, const real min_transmittance,
                      __global const real* restrict target, const real norm,
                      __global float* restrict image, __global real* restrict pixel_terms,
                      __global real* restrict grad_volume, __global real* restrict grad_tf,
                      __local real* tf_acc, const int tf_acc_size, __global uint* restrict samples,
                      __global const real* restrict camera_params,
                      __global real* restrict camera_partial, __local real* camera_scratch,
                      __global const uchar* restrict occupied, const int4 bricks) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  const bool active = x < width && y < height;  // padding items still meet the barriers
  const int lid = get_local_id(1) * get_local_size(0) + get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1);
#if IVR_GRAD_TF
  for (int i = lid; i < tf_acc_size; i += lsize) tf_acc[i] = (real)0;
  barrier(CLK_LOCAL_MEM_FENCE);
#endif
#if IVR_GRAD_CAMERA
  real camera_terms[7] = {0, 0, 0, 0, 0, 0, 0};  // this pixel's dL / d camera component
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
    uint end = 0;  // one past the last sample the march took (skipped samples are not taken)
    int segment = 0;
    for (uint i = 0; i < n;) {
      const real t = t0 + ((real)i + (real)0.5) * dt;
      const real ux = u0x + t * dux, uy = u0y + t * duy, uz = u0z + t * duz;
#if IVR_SKIP_EMPTY
      // Only where nothing differentiated can come from (lib/empty_space.hpp,
      // gradient_may_skip): the adjoint march below skips the same samples.
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
      end = ++i;
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
    int seg_value = 0, seg_scatter = 0;
    int base = -1, ox = 0, oy = 0, oz = 0, pix = 0, piy = 0, piz = 0;
    real v[8];
#if IVR_GRAD_DENSITY
    real g[8] = {0, 0, 0, 0, 0, 0, 0, 0};
#endif
#if IVR_GRAD_TF
    TfGradCache tf_cache;
    tf_cache_init(&tf_cache);
#endif
#if IVR_GRAD_CAMERA
    // The ray's own adjoint: sums over samples of dL/d position (p), t·dL/dp, the step index
    // times dL/dp along the ray, dL/dp along the ray, and dt·dL/d dt through tau and the weights.
    real gpx = 0, gpy = 0, gpz = 0, gtx = 0, gty = 0, gtz = 0, s_mid = 0, s_along = 0, s_dt = 0;
#endif
    for (uint i = 0; i < end;) {
      const real t = t0 + ((real)i + (real)0.5) * dt;
      const real ux = u0x + t * dux, uy = u0y + t * duy, uz = u0z + t * duz;
#if IVR_SKIP_EMPTY
      IVR_SKIP_EMPTY_BRICK(i, end, ux, uy, uz)
#endif
      // The sample's cell and weights, as trilinear_at() clamps and indexes them.
      real fx, fy, fz;
      const int ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
                iz = cell_axis(uz, dims.z, &fz);
      // Into a neighbouring cell (across a face, an edge or a corner) one face at a time; a
      // straight ray keeps its direction along each axis, so these branches are predictable.
      // Longer jumps (steps over a voxel long) and the first sample take the general path.
      if (base < 0 || abs(ix - pix) > 1 || abs(iy - piy) > 1 || abs(iz - piz) > 1) {
        if (base >= 0) IVR_EACH_CORNER(IVR_FLUSH);
        IVR_SET_CELL(ix, iy, iz);
        IVR_EACH_CORNER(IVR_LOAD);
      } else {
        if (ix != pix) {
          if (ix > pix)
            IVR_CROSS(0, 1, 0, 2, 4, 6, ix, piy, piz);
          else
            IVR_CROSS(1, 0, 0, 2, 4, 6, ix, piy, piz);
        }
        if (iy != piy) {
          if (iy > piy)
            IVR_CROSS(0, 2, 0, 1, 4, 5, ix, iy, piz);
          else
            IVR_CROSS(2, 0, 0, 1, 4, 5, ix, iy, piz);
        }
        if (iz != piz) {
          if (iz > piz)
            IVR_CROSS(0, 4, 0, 1, 2, 3, ix, iy, iz);
          else
            IVR_CROSS(4, 0, 0, 1, 2, 3, ix, iy, iz);
        }
      }
      // trilinear_at()'s interpolation, from the registers.
      const real d = lerp(lerp(lerp(v[0], v[1], fx), lerp(v[2], v[3], fx), fy),
                          lerp(lerp(v[4], v[5], fx), lerp(v[6], v[7], fx), fy), fz);
      real er, eg, eb, dsigma, der, deg, deb;
      const real sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &seg_value, &er, &eg, &eb,
                                         &dsigma, &der, &deg, &deb);
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

#if IVR_GRAD_DENSITY || IVR_GRAD_CAMERA
      const real gd = gsigma * dsigma + ger * der + geg * deg + geb * deb;  // dL / d density
#endif
#if IVR_GRAD_CAMERA
      {
        real ngx, ngy, ngz;
        trilinear_gradient(v, fx, fy, fz, ux, uy, uz, dims, &ngx, &ngy, &ngz);
        const real px = gd * ngx * inv_voxel.x, py = gd * ngy * inv_voxel.y,
                   pz = gd * ngz * inv_voxel.z;
        const real along = px * ray.dir.x + py * ray.dir.y + pz * ray.dir.z;
        gpx += px;
        gpy += py;
        gpz += pz;
        gtx += t * px;
        gty += t * py;
        gtz += t * pz;
        s_along += along;
        s_mid += ((real)i + (real)0.5) * along;
        // The pixel depends on dt through tau = sigma·dt (sigma·gsigma / dt, e held fixed) and
        // through the weight's own factor dt (dL/dweight · weight / dt).
#if IVR_EMISSION
        s_dt += sigma * gsigma + ger * er + geg * eg + geb * eb;
#else
        s_dt += sigma * gsigma;
#endif
      }
#endif
#if IVR_GRAD_DENSITY
      const real gx0 = gd * ((real)1 - fx), gx1 = gd * fx;
      const real wy0z0 = ((real)1 - fy) * ((real)1 - fz), wy1z0 = fy * ((real)1 - fz);
      const real wy0z1 = ((real)1 - fy) * fz, wy1z1 = fy * fz;
      g[0] += gx0 * wy0z0;
      g[1] += gx1 * wy0z0;
      g[2] += gx0 * wy1z0;
      g[3] += gx1 * wy1z0;
      g[4] += gx0 * wy0z1;
      g[5] += gx1 * wy0z1;
      g[6] += gx0 * wy1z1;
      g[7] += gx1 * wy1z1;
#endif
#if IVR_GRAD_TF
      tf_scatter(d, tf, tf_count, tf_scalars, &seg_scatter, gsigma, ger, geg, geb, &tf_cache,
                 tf_acc);
#endif
      ++i;
    }
#if IVR_GRAD_DENSITY
    if (base >= 0) IVR_EACH_CORNER(IVR_FLUSH);
#endif
#if IVR_GRAD_TF
    tf_cache_flush(&tf_cache, tf_acc);
#endif
#if IVR_GRAD_CAMERA
    if (hit) {
      // Samples sit at t_i = t0 + (i + 1/2) dt with dt = (t1 - t0) / n; t0 and t1 move with the
      // ray where a slab plane sets them: t = (plane - o_a) / d_a.
      const real dldt = s_dt / dt + s_mid;
      const real dldt1 = dldt / (real)n, dldt0 = s_along - dldt1;
      real lo[3] = {gpx, gpy, gpz}, ld[3] = {gtx, gty, gtz};
      const int a0 = clip_axis(ray, box_min.xyz, box_max.xyz, t0, true);
      const int a1 = clip_axis(ray, box_min.xyz, box_max.xyz, t1, false);
      if (a0 >= 0) {
        const real inv = (real)1 / component(ray.dir, a0);
        lo[a0] -= dldt0 * inv;
        ld[a0] -= dldt0 * t0 * inv;
      }
      if (a1 >= 0) {
        const real inv = (real)1 / component(ray.dir, a1);
        lo[a1] -= dldt1 * inv;
        ld[a1] -= dldt1 * t1 * inv;
      }
      const real sx = (real)2 * ((real)x + (real)0.5) / (real)width - (real)1;
      const real sy = (real)1 - (real)2 * ((real)y + (real)0.5) / (real)height;
      for (int k = 0; k < 7; ++k) {
        real3 o, d;
        camera_ray_tangent(camera_params + view * IVR_CAMERA_PARAMS_STRIDE, sx, sy, k, &o, &d);
        camera_terms[k] =
            lo[0] * o.x + lo[1] * o.y + lo[2] * o.z + ld[0] * d.x + ld[1] * d.y + ld[2] * d.z;
      }
    }
#endif
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

#if IVR_GRAD_TF
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int i = lid; i < tf_acc_size; i += lsize)
    if (tf_acc[i] != (real)0) atomic_add_global(grad_tf + i, tf_acc[i]);
#endif
}
