// adjoint.cl — reverse-mode gradients, one work-item per pixel (or, on CPUs, per packet of
// IVR_RAYS neighbouring pixels in vector lanes, kernels/rays.cl: every integrator's density and TF
// gradients, each lane its own ray's arithmetic; there, with IVR_PRIVATE_SUMS, one work-item per
// work-group marching packets from a shared counter and summing into memory of its own without
// atomics, kernels/private_sums.cl): the primal march gives the pixel
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
#include "private_sums.cl"
#include "rays.cl"
#include "scatter_cache.cl"
#include "adjoint_tf.cl"
// Every scheme's march (the files' own include lines are resolved once, wherever they first
// appear, so none is included under a condition); the scheme's is called.
#include "adjoint_endpoints.cl"
#include "adjoint_exact.cl"
#include "adjoint_midpoint.cl"
// IVR_PRIMAL_GIVEN: the primal march already ran (the CPU packet render, lib/adjoint/adjoint.cpp):
// each pixel's emitted colour and transmittance are in `image` and its samples in `samples`, read
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

// One pixel from its march's emitted colour C and transmittance T: its value into `image`, its
// loss and dL/dbackground terms into `pixel_terms`, and dL/dpixel with what the adjoint march
// needs of the primal into lane `l` of the arrays of `out` (one ray: l = 0).
typedef struct {
  real gr[IVR_RAYS], gg[IVR_RAYS], gb[IVR_RAYS], ga[IVR_RAYS], gi[IVR_RAYS];
  real total_r[IVR_RAYS], total_g[IVR_RAYS], total_b[IVR_RAYS], intensity[IVR_RAYS];
} PixelAdjoints;

inline void pixel_adjoint(real cr, real cg, real cb, real t, size_t pixel,
                          __global const real* target, real4 background, real norm,
                          __global real* image, __global real* pixel_terms, PixelAdjoints* out,
                          int l) {
  __global const real* tgt = target + pixel * IVR_CHANNELS;
  real loss = (real)0;
  out->gr[l] = out->gg[l] = out->gb[l] = out->ga[l] = out->gi[l] = out->intensity[l] = (real)0;
#if IVR_EMISSION
  const real total_r = cr + t * background.x, total_g = cg + t * background.y,
             total_b = cb + t * background.z, alpha = (real)1 - t;
  const real gr = loss_term(total_r, tgt[0], norm, &loss);
  const real gg = loss_term(total_g, tgt[1], norm, &loss);
  const real gb = loss_term(total_b, tgt[2], norm, &loss);
  out->ga[l] = loss_term(alpha, tgt[3], norm, &loss);
  __global real* o = image + pixel * 4;
  o[0] = total_r;
  o[1] = total_g;
  o[2] = total_b;
  o[3] = alpha;
  pixel_terms[pixel * 4 + 0] = loss;
  pixel_terms[pixel * 4 + 1] = gr * t;  // dL/dbackground, per pixel
  pixel_terms[pixel * 4 + 2] = gg * t;
  pixel_terms[pixel * 4 + 3] = gb * t;
  out->gr[l] = gr, out->gg[l] = gg, out->gb[l] = gb;
  out->total_r[l] = total_r, out->total_g[l] = total_g, out->total_b[l] = total_b;
#else
  (void)cr, (void)cg, (void)cb;
  out->total_r[l] = out->total_g[l] = out->total_b[l] = (real)0;
  const real intensity = background.x * t;
  const real gi = loss_term(intensity, tgt[0], norm, &loss);
  image[pixel] = intensity;
  pixel_terms[pixel * 4 + 0] = loss;
  pixel_terms[pixel * 4 + 1] = gi * t;
  pixel_terms[pixel * 4 + 2] = (real)0;
  pixel_terms[pixel * 4 + 3] = (real)0;
  out->gi[l] = gi, out->intensity[l] = intensity;
#endif
}

// The AdjointRay of a work-item's rays from their pixels' adjoints.
inline void adjoint_ray_of(const PixelAdjoints* p, vreal t_end, vint end, AdjointRay* ar) {
  ar->gr = IVR_LOAD_RAYS(p->gr), ar->gg = IVR_LOAD_RAYS(p->gg), ar->gb = IVR_LOAD_RAYS(p->gb);
  ar->ga = IVR_LOAD_RAYS(p->ga), ar->gi = IVR_LOAD_RAYS(p->gi);
  ar->total_r = IVR_LOAD_RAYS(p->total_r), ar->total_g = IVR_LOAD_RAYS(p->total_g);
  ar->total_b = IVR_LOAD_RAYS(p->total_b), ar->intensity = IVR_LOAD_RAYS(p->intensity);
  ar->t_end = t_end;
  ar->end = end;
}

// The rays of the tile with corner (x, y) of `view` (one ray: pixel (x, y); kernels/rays.cl): the
// primal march, each pixel, its loss terms and dL/dpixel, then the adjoint march, whose density
// gradient goes to `density`, its TF gradient to `tf_acc` and (one ray) its camera gradient to
// `camera_terms`.
__attribute__((always_inline)) inline void adjoint_pixels(
    const int x, const int y, const int view, __global const real* restrict volume, const int4 dims,
    const real4 box_min, const real4 box_max, const real4 inv_voxel,
    __global const real* restrict cameras, const int width, const int height,
    __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
    const real4 background, const real step, const real min_transmittance,
    __global const real* restrict target, const real norm, __global real* restrict image,
    __global real* restrict pixel_terms, const ScatterSink density, __local real* tf_acc,
    __global uint* restrict samples, __global const real* restrict camera_params,
    __global const uchar* restrict occupied, const int4 bricks, real* camera_terms) {
  __global const real* cam = cameras + view * IVR_CAMERA_STRIDE;
  March m;
#if IVR_RAYS == 1
  const Ray ray = camera_ray(cam, x, y, width, height);
  const bool hit =
      march_begin(ray, cam, x, y, width, height, box_min, box_max, inv_voxel, step, &m);
#else
  const Ray ray = {(real3)(real)0, (real3)(real)0};  // (the camera gradient's; one ray)
  const bool hit =
      march_begin_rays(cam, x, y, width, height, box_min, box_max, inv_voxel, step, &m);
#endif
  Radiance r = radiance_begin();
#if IVR_PRIMAL_GIVEN && IVR_EMISSION && IVR_SCHEME == IVR_SCHEME_MIDPOINT && IVR_RAYS == 1
  {
    const size_t pixel = ((size_t)view * height + y) * width + x;
    r.cr = image[pixel * 4 + 0];
    r.cg = image[pixel * 4 + 1];
    r.cb = image[pixel * 4 + 2];
    r.transmittance = image[pixel * 4 + 3];
    r.samples = r.end = samples[pixel];  // the midpoint march: one sample per segment taken
  }
#else
  if (hit)
    primal_march(volume, dims, &m, tf, tf_count, tf_scalars, min_transmittance, occupied, bricks,
                 &r);
#endif

  // Each ray's pixel, its loss terms and dL/dpixel.
  real t_end[IVR_RAYS], cr[IVR_RAYS], cg[IVR_RAYS], cb[IVR_RAYS];
  int taken[IVR_RAYS];
  IVR_STORE_RAYS(r.transmittance, t_end);
  IVR_STORE_RAYS(r.cr, cr);
  IVR_STORE_RAYS(r.cg, cg);
  IVR_STORE_RAYS(r.cb, cb);
  IVR_STORE_RAYS(r.samples, taken);
  PixelAdjoints pa;
  for (int l = 0; l < IVR_RAYS; ++l) {
    const int px = x + IVR_LANE_X(l), py = y + IVR_LANE_Y(l);
    const size_t pixel = ((size_t)view * height + py) * width + px;
    if (px < width && py < height) {
      pixel_adjoint(cr[l], cg[l], cb[l], t_end[l], pixel, target, background, norm, image,
                    pixel_terms, &pa, l);
      samples[pixel] = (uint)taken[l];
    } else {  // past the image's edge: no ray (n = 0), nothing to add
      pa.gr[l] = pa.gg[l] = pa.gb[l] = pa.ga[l] = pa.gi[l] = (real)0;
      pa.total_r[l] = pa.total_g[l] = pa.total_b[l] = pa.intensity[l] = (real)0;
    }
  }
  AdjointRay ar;
  adjoint_ray_of(&pa, r.transmittance, r.end, &ar);

  if (hit) {
    TfGradCache tf_cache;
    tf_cache_init(&tf_cache);
    CameraSums cs;
#if IVR_RAYS == 1
    camera_sums_init(&cs, m.t1);
#else
    camera_sums_init(&cs, (real)0);  // unused: no camera gradient in packets
#endif
    adjoint_march(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, &ar, occupied, bricks,
                  density, &tf_cache, tf_acc, &cs);
#if IVR_GRAD_TF
    tf_cache_flush(&tf_cache, tf_acc);
#endif
#if IVR_GRAD_CAMERA
    camera_terms_of(&cs, ray, m.t0, box_min, box_max,
                    camera_params + view * IVR_CAMERA_PARAMS_STRIDE, width, height, x, y,
                    camera_terms);
#else
    (void)camera_params, (void)camera_terms;
#endif
  }
}

// `packets`: with IVR_PRIVATE_SUMS, every view's packets; `work`: the counter they are taken from
// with -DIVR_PRIVATE_DYNAMIC (0 before the launch).
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
                      __global const uchar* restrict occupied, const int4 bricks,
                      volatile __global int* restrict work, const int packets) {
  const int lid = get_local_id(1) * get_local_size(0) + get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1);
#if IVR_GRAD_TF
  for (int i = lid; i < tf_acc_size; i += lsize) tf_acc[i] = (real)0;
  barrier(CLK_LOCAL_MEM_FENCE);
#endif
  real camera_terms[7] = {0, 0, 0, 0, 0, 0, 0};  // this pixel's dL / d camera component

#if IVR_PRIVATE_SUMS
  // One work-item per group (kernels/private_sums.cl): chunks of packets dealt out in turn (group
  // g takes chunks g, g + groups, …, each in order, so that every copy's sums, and the density
  // gradient's bits, are the same on every call; -DIVR_PRIVATE_DYNAMIC takes them from the shared
  // counter instead), the density gradient into the group's own copy of the volume (`grad_volume`
  // holds the copies).
  // (Without a density gradient the buffer holds one value, and nothing is added to it.)
  const ScatterSink density = {
      grad_volume +
      (IVR_GRAD_DENSITY ? private_copy_offset(get_group_id(0), dims.x * dims.y * dims.z) : 0)};
  const int per_row = (width + IVR_PACKET_W - 1) / IVR_PACKET_W;
  const int per_view = per_row * ((height + IVR_PACKET_H - 1) / IVR_PACKET_H);
  const int take = private_take_size(packets);
#ifdef IVR_PRIVATE_DYNAMIC
  for (;;) {
    const int first = atomic_add(work, take);
    if (first >= packets) break;
#else
  (void)work;
  for (int first = get_group_id(0) * take; first < packets; first += get_num_groups(0) * take) {
#endif
    for (int p = first; p < min(first + take, packets); ++p) {
      const int view = p / per_view, tile = p % per_view;  // the tile's index in its view
      adjoint_pixels((tile % per_row) * IVR_PACKET_W, (tile / per_row) * IVR_PACKET_H, view, volume,
                     dims, box_min, box_max, inv_voxel, cameras, width, height, tf, tf_count,
                     tf_scalars, background, step, min_transmittance, target, norm, image,
                     pixel_terms, density, tf_acc, samples, camera_params, occupied, bricks,
                     camera_terms);
    }
  }
#else
  (void)work, (void)packets;
  // One pixel per work-item, or a packet of IVR_RAYS neighbouring pixels (CPUs: a tile).
  const int x = get_global_id(0) * IVR_PACKET_W, y = get_global_id(1) * IVR_PACKET_H;
  const int view = get_global_id(2);
  // The density gradient's adds, through the group's table where the host turned it on
  // (kernels/scatter_cache.cl: its barriers are met by every item, padding included).
  IVR_SCATTER_SINK(density, grad_volume);
  if (x < width && y < height)  // padding items still meet the barriers
    adjoint_pixels(x, y, view, volume, dims, box_min, box_max, inv_voxel, cameras, width, height,
                   tf, tf_count, tf_scalars, background, step, min_transmittance, target, norm,
                   image, pixel_terms, density, tf_acc, samples, camera_params, occupied, bricks,
                   camera_terms);
#endif

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
#else
  (void)camera_partial, (void)camera_scratch;
#endif

  scatter_flush(density);
#if IVR_GRAD_TF
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int i = lid; i < tf_acc_size; i += lsize)
    if (tf_acc[i] != (real)0) atomic_add_global(grad_tf + i, tf_acc[i]);
#endif
}
