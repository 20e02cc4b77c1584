// bricked_adjoint.cl — the out-of-core density gradient, brick by brick (every scheme; lib/brick/
// bricked_gradient.cpp). After the forward sweeps (kernels/bricked.cl), ADJOINT_BEGIN turns each
// ray's composited state into its loss terms and dL/dpixel (as adjoint.cl's pixel_adjoint) and
// restarts its march; ADJOINT_MARCH then walks the bricks front to back again with the in-core
// adjoint's own march (adjoint_midpoint.cl, adjoint_endpoints.cl, adjoint_exact.cl: its window and
// prefix carried in the state), so each sample's remaining radiance is C minus the prefix summed as
// in core (docs/design.md), and the ray's cell cache adds dL/d density once per voxel it touches
// into the brick's voxels (`grad`, zeroed per visit; the host adds it into the volume's gradient).
// The endpoint schemes' bricks hold a halo that reaches a window's first segment's near sample
// (lib/brick/brick_layout.hpp, brick_halo): the sample a window ends on goes on to the next
// brick with what it has collected (the state's BS_ADJ_* sums), which scatters it once, as in
// core; where the ray's march ends there (a slab's independent segment) this brick scatters its
// part. A work-item is one pixel, or on CPUs a tile of IVR_RAYS neighbouring pixels in vector
// lanes (kernels/rays.cl), each lane its own ray's arithmetic.
#include "adjoint_endpoints.cl"
#include "adjoint_exact.cl"
#include "adjoint_midpoint.cl"
#include "adjoint_ray.cl"
#include "adjoint_tf.cl"
#include "bricked_state.cl"
#include "config.cl"
#include "geometry.cl"
#include "loss.cl"
#include "march.cl"
#include "private_sums.cl"
#include "rays.cl"
#include "scatter_cache.cl"

#define IVR_BRICK_ADJOINT_BEGIN 3
#define IVR_BRICK_ADJOINT_MARCH 4
// The adjoint's own places in the march state, carried from brick to brick: the ray's Σ |density
// contribution| so far and the open sample's sums (AdjointPrefix; the forward march's ktau and
// carried end sample, which its pass no longer reads; ADJOINT_BEGIN zeroes them).
#define BS_ADJ_FLUSHED BS_KTAU
#define BS_ADJ_GSIGMA 9
#define BS_ADJ_GER 10
#define BS_ADJ_GEG 11
#define BS_ADJ_GEB 12
#define BS_ADJ_GD 13
// Per ray, beside the march state: dL/d(r, g, b, alpha) (absorption: dL/dI in 0), the pixel's
// radiance (r, g, b) and transmittance (absorption: its intensity in 4, unused 5–6).
#define IVR_BRICK_ADJOINT_REALS 8

#if IVR_RAYS == 1
// ADJOINT_BEGIN for one pixel: dL/dpixel from the composited state, its loss and dL/dbackground
// terms into `terms` (as adjoint.cl's pixel_terms: loss, then the background's r, g, b — absorption:
// its intensity — terms), and its march restarted as far as the forward march went (its `end`).
inline void brick_adjoint_begin(__global real* s, __global uint* su, __global real* a,
                                __global const real* tgt, real norm, real4 background,
                                __global real* terms) {
  Radiance r = brick_load(s, su);
  march_finish(&r);
  real loss = (real)0;
  const real t = r.transmittance;
#if IVR_EMISSION
  const real total_r = r.cr + t * background.x, total_g = r.cg + t * background.y,
             total_b = r.cb + t * background.z;
  a[0] = loss_term(total_r, tgt[0], norm, &loss);
  a[1] = loss_term(total_g, tgt[1], norm, &loss);
  a[2] = loss_term(total_b, tgt[2], norm, &loss);
  a[3] = loss_term((real)1 - t, tgt[3], norm, &loss);
  a[4] = total_r, a[5] = total_g, a[6] = total_b, a[7] = t;
  terms[1] = a[0] * t, terms[2] = a[1] * t, terms[3] = a[2] * t;
#else
  const real intensity = background.x * t;
  a[0] = loss_term(intensity, tgt[0], norm, &loss);
  a[1] = a[2] = a[3] = a[5] = a[6] = a[7] = (real)0;
  a[4] = intensity;
  terms[1] = a[0] * t, terms[2] = terms[3] = (real)0;
#endif
  terms[0] = loss;
  const uint end = su[BU_END];
  for (int k = 0; k <= BS_ADJ_GD; ++k) s[k] = (real)0;
  s[BS_T] = (real)1;
  s[BS_TNEXT] = s[BS_T0];
  su[BU_SAMPLES] = end;  // the adjoint march's end
  su[BU_NEXT] = 0u;
  su[BU_FLAGS] = end > 0u && su[BU_N] > 0u ? 0u : IVR_BRICK_DONE;
}
#endif

// ADJOINT_MARCH for the rays of the tile with corner (x0, y0) of `view` that enter this brick,
// their density gradient into `sink`.
__attribute__((always_inline)) inline void brick_adjoint_tile(
    const int x0, const int y0, const int view, __global const real* restrict volume,
    const int4 dims, const real4 inv_voxel, const int width, const int height,
    __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
    const real4 brick_lo, const real4 brick_hi, const int4 origin, __global real* restrict state,
    __global uint* restrict state_u, __global const real* restrict adj, const ScatterSink sink,
    __local real* tf_acc) {
  // Each lane's ray from its state (bricked_state.cl); lanes that do not enter march nothing
  // (end = 0).
  LaneWindows w;
  if (!brick_enter_lanes(state, state_u, x0, y0, view, width, height, brick_lo, brick_hi, origin,
                         &w))
    return;
  real T[IVR_RAYS], pr[IVR_RAYS], pg[IVR_RAYS], pb[IVR_RAYS], kr[IVR_RAYS], kg[IVR_RAYS],
      kb[IVR_RAYS];
  real a0[IVR_RAYS], a1[IVR_RAYS], a2[IVR_RAYS], a3[IVR_RAYS], a4[IVR_RAYS], a5[IVR_RAYS],
      a6[IVR_RAYS], a7[IVR_RAYS];
  real flushed[IVR_RAYS], gsigma[IVR_RAYS], ger[IVR_RAYS], geg[IVR_RAYS], geb[IVR_RAYS],
      gd[IVR_RAYS];
  // A ray whose march goes on past this brick (not a slab's independent segment ending here).
  int carry[IVR_RAYS];
  int next[IVR_RAYS], end[IVR_RAYS];
  for (int l = 0; l < IVR_RAYS; ++l) {
    if (w.entered[l]) {
      __global const real* s = state + w.pixel[l] * IVR_BRICK_REALS;
      __global const uint* su = state_u + w.pixel[l] * IVR_BRICK_UINTS;
      __global const real* a = adj + w.pixel[l] * IVR_BRICK_ADJOINT_REALS;
      T[l] = s[BS_T], pr[l] = s[BS_CR], pg[l] = s[BS_CG], pb[l] = s[BS_CB];
      kr[l] = s[BS_KR], kg[l] = s[BS_KG], kb[l] = s[BS_KB];
      a0[l] = a[0], a1[l] = a[1], a2[l] = a[2], a3[l] = a[3];
      a4[l] = a[4], a5[l] = a[5], a6[l] = a[6], a7[l] = a[7];
      next[l] = (int)su[BU_NEXT], end[l] = (int)su[BU_SAMPLES];
      flushed[l] = s[BS_ADJ_FLUSHED], gsigma[l] = s[BS_ADJ_GSIGMA], ger[l] = s[BS_ADJ_GER];
      geg[l] = s[BS_ADJ_GEG], geb[l] = s[BS_ADJ_GEB], gd[l] = s[BS_ADJ_GD];
      carry[l] = w.tb1[l] < w.tend[l] ? (IVR_RAYS == 1 ? 1 : -1) : 0;
    } else {
      T[l] = (real)1;
      pr[l] = pg[l] = pb[l] = kr[l] = kg[l] = kb[l] = (real)0;
      a0[l] = a1[l] = a2[l] = a3[l] = a4[l] = a5[l] = a6[l] = a7[l] = (real)0;
      flushed[l] = gsigma[l] = ger[l] = geg[l] = geb[l] = gd[l] = (real)0;
      next[l] = end[l] = carry[l] = 0;
    }
  }
  const March m = lanes_march(&w);
  AdjointRay ar;
#if IVR_EMISSION
  ar.gr = IVR_LOAD_RAYS(a0), ar.gg = IVR_LOAD_RAYS(a1), ar.gb = IVR_LOAD_RAYS(a2);
  ar.ga = IVR_LOAD_RAYS(a3);
  ar.total_r = IVR_LOAD_RAYS(a4), ar.total_g = IVR_LOAD_RAYS(a5), ar.total_b = IVR_LOAD_RAYS(a6);
  ar.t_end = IVR_LOAD_RAYS(a7);
  ar.gi = ar.intensity = (vreal)(real)0;
#else
  ar.gi = IVR_LOAD_RAYS(a0), ar.intensity = IVR_LOAD_RAYS(a4);
  ar.gr = ar.gg = ar.gb = ar.ga = ar.total_r = ar.total_g = ar.total_b = ar.t_end = (vreal)(real)0;
  (void)a1, (void)a2, (void)a3, (void)a5, (void)a6, (void)a7;
#endif
  ar.end = IVR_LOAD_RAYS(end);
  AdjointPrefix at;
  at.transmittance = IVR_LOAD_RAYS(T);
  at.pr = IVR_LOAD_RAYS(pr), at.pg = IVR_LOAD_RAYS(pg), at.pb = IVR_LOAD_RAYS(pb);
  at.kr = IVR_LOAD_RAYS(kr), at.kg = IVR_LOAD_RAYS(kg), at.kb = IVR_LOAD_RAYS(kb);
  at.i = IVR_LOAD_RAYS(next);
  at.flushed = IVR_LOAD_RAYS(flushed);
  at.gsigma = IVR_LOAD_RAYS(gsigma), at.ger = IVR_LOAD_RAYS(ger), at.geg = IVR_LOAD_RAYS(geg);
  at.geb = IVR_LOAD_RAYS(geb), at.gd = IVR_LOAD_RAYS(gd);

  const Ray ray = {(real3)(real)0, (real3)(real)0};  // (the camera gradient's: not out of core)
  TfGradCache tf_cache;
  tf_cache_init(&tf_cache);
  CameraSums cs;
  camera_sums_init(&cs, (real)0);
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
  adjoint_march_midpoint_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, &ar,
                                (__global const uchar*)0, (int4)0, sink, &tf_cache, tf_acc, &cs,
                                IVR_LOAD_RAYS(w.tb1), &at);
#elif IVR_ENDPOINT_SAMPLES
  adjoint_march_endpoints_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, &ar,
                                 (__global const uchar*)0, (int4)0, sink, &tf_cache, tf_acc, &cs,
                                 IVR_LOAD_RAYS(w.tb1), IVR_LOAD_RAYS(carry), &at);
#else
  adjoint_march_exact_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, &ar,
                             (__global const uchar*)0, (int4)0, sink, &tf_cache, tf_acc, &cs,
                             IVR_LOAD_RAYS(w.tb0), IVR_LOAD_RAYS(w.tb1), &at);
#endif
#if IVR_GRAD_TF
  tf_cache_flush(&tf_cache, tf_acc);
#endif

  IVR_STORE_RAYS(at.transmittance, T);
  IVR_STORE_RAYS(at.pr, pr);
  IVR_STORE_RAYS(at.pg, pg);
  IVR_STORE_RAYS(at.pb, pb);
  IVR_STORE_RAYS(at.kr, kr);
  IVR_STORE_RAYS(at.kg, kg);
  IVR_STORE_RAYS(at.kb, kb);
  IVR_STORE_RAYS(at.i, next);
  IVR_STORE_RAYS(at.flushed, flushed);
  IVR_STORE_RAYS(at.gsigma, gsigma);
  IVR_STORE_RAYS(at.ger, ger);
  IVR_STORE_RAYS(at.geg, geg);
  IVR_STORE_RAYS(at.geb, geb);
  IVR_STORE_RAYS(at.gd, gd);
  real ended[IVR_RAYS];  // the Σ |contribution| of the rays that end here (the cap's check)
  for (int l = 0; l < IVR_RAYS; ++l) {
    ended[l] = (real)0;
    if (!w.entered[l]) continue;
    __global real* s = state + w.pixel[l] * IVR_BRICK_REALS;
    __global uint* su = state_u + w.pixel[l] * IVR_BRICK_UINTS;
    s[BS_T] = T[l];
    s[BS_CR] = pr[l], s[BS_CG] = pg[l], s[BS_CB] = pb[l];
    s[BS_KR] = kr[l], s[BS_KG] = kg[l], s[BS_KB] = kb[l];
    s[BS_ADJ_FLUSHED] = flushed[l], s[BS_ADJ_GSIGMA] = gsigma[l], s[BS_ADJ_GER] = ger[l];
    s[BS_ADJ_GEG] = geg[l], s[BS_ADJ_GEB] = geb[l], s[BS_ADJ_GD] = gd[l];
    su[BU_NEXT] = (uint)next[l];
    s[BS_TNEXT] = w.tb1[l];
    if (next[l] >= end[l] || w.tb1[l] >= w.tend[l]) {
      su[BU_FLAGS] |= IVR_BRICK_DONE;
      ended[l] = flushed[l];
    }
  }
  adjoint_ray_end(sink, IVR_LOAD_RAYS(ended));
}

// The arguments are bricked_render's up to `pending`'s place (the host sets them alike), then the
// adjoint's. A work-item is the tile with corner (IVR_PACKET_W · x, IVR_PACKET_H · y) of view z;
// with IVR_PRIVATE_SUMS (CPU packets, kernels/private_sums.cl) a work-group of one item takes its
// turns of the `packets` tiles of the rectangle `rect` (first tile x, y; tiles across, down) of
// views first_view… and adds into its own copy of the brick's gradient in `grad`. With IVR_GRAD_TF
// the TF gradient is summed in the group's `tf_acc` (tf_acc_size values) and added to `grad_tf`
// once per group, as in core.
__kernel void bricked_adjoint(
    __global const real* restrict volume, const int4 dims, const real4 box_min, const real4 box_max,
    const real4 inv_voxel, __global const real* restrict cameras, const int width, const int height,
    __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
    const real4 background, const real step, const real min_transmittance, const int phase,
    const real4 brick_lo, const real4 brick_hi, const int4 origin, __global real* restrict state,
    __global uint* restrict state_u, __global real* restrict adj,
    __global const real* restrict target, const real norm, __global real* restrict pixel_terms,
    __global real* grad, const int4 rect, const int first_view, const int packets,
    __global real* grad_tf, __local real* tf_acc, const int tf_acc_size) {
  (void)cameras, (void)box_min, (void)box_max, (void)step, (void)min_transmittance;
#if IVR_GRAD_TF
  const int lid = (get_local_id(2) * get_local_size(1) + get_local_id(1)) * get_local_size(0) +
                  get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1) * get_local_size(2);
  for (int i = lid; i < tf_acc_size; i += lsize) tf_acc[i] = (real)0;
  barrier(CLK_LOCAL_MEM_FENCE);
#else
  (void)grad_tf, (void)tf_acc_size;
#endif
#if IVR_PRIVATE_SUMS
  (void)phase, (void)target, (void)norm, (void)pixel_terms, (void)background;
  const ScatterSink sink = {grad + private_copy_offset(get_group_id(0), dims.x * dims.y * dims.z)};
  const int per_view = rect.z * rect.w;
  const int take = private_take_size(packets);
  for (int first = get_group_id(0) * take; first < packets; first += get_num_groups(0) * take)
    for (int p = first; p < min(first + take, packets); ++p) {
      const int tile = p % per_view;
      const int x0 = (rect.x + tile % rect.z) * IVR_PACKET_W;
      const int y0 = (rect.y + tile / rect.z) * IVR_PACKET_H;
      if (x0 < width && y0 < height)
        brick_adjoint_tile(x0, y0, first_view + p / per_view, volume, dims, inv_voxel, width,
                           height, tf, tf_count, tf_scalars, brick_lo, brick_hi, origin, state,
                           state_u, adj, sink, tf_acc);
    }
#else
  (void)rect, (void)first_view, (void)packets;
  const int x0 = get_global_id(0) * IVR_PACKET_W, y0 = get_global_id(1) * IVR_PACKET_H;
  const int view = get_global_id(2);
  // (No early return: with the TF gradient every item of the group meets the barriers.)
  if (x0 < width && y0 < height) {
#if IVR_RAYS == 1
    if (phase == IVR_BRICK_ADJOINT_BEGIN) {  // (packet kernels march; BEGIN runs one ray a pixel)
      const size_t pixel = ((size_t)view * height + y0) * width + x0;
      brick_adjoint_begin(state + pixel * IVR_BRICK_REALS, state_u + pixel * IVR_BRICK_UINTS,
                          adj + pixel * IVR_BRICK_ADJOINT_REALS, target + pixel * IVR_CHANNELS,
                          norm, background, pixel_terms + pixel * 4);
    } else
#else
    (void)phase, (void)target, (void)norm, (void)pixel_terms, (void)background;
#endif
    {
      const ScatterSink sink = {grad};
      brick_adjoint_tile(x0, y0, view, volume, dims, inv_voxel, width, height, tf, tf_count,
                         tf_scalars, brick_lo, brick_hi, origin, state, state_u, adj, sink, tf_acc);
    }
  }
#endif
#if IVR_GRAD_TF
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int i = lid; i < tf_acc_size; i += lsize)
    if (tf_acc[i] != (real)0) atomic_add_global(grad_tf + i, tf_acc[i]);
#endif
}
