// bricked_tangent.cl — forward mode out of core (every scheme; lib/brick/bricked_tangent.cpp): the
// out-of-core render's sweeps (kernels/bricked.cl) with IVR_LANES tangent lanes carried beside
// each ray's march state. TANGENT_MARCH walks a ray's window in this brick with the in-core
// tangent march itself (jacobian_midpoint.cl, jacobian_endpoints.cl, jacobian_exact.cl: from the
// carried radiance, tangents and sample or segment index; a window's first end sample from the
// brick's halo; exact: the window's pieces, and the ray's ends in its first and last window), so the composited tangents are the unsplit march's; TANGENT_FINISH turns each ray's
// final state into its pixel, its loss terms and the loss's derivatives (jacobian_pixel.cl, as
// kernels/jacobian.cl does in core), summed per work-group. One ray per work-item: a ray's lanes
// (TF, background, camera, voxel, a listed ray's columns) are per-ray state here, and the voxel
// lanes are moved into the brick's voxels. On CPUs a pass of TF and background lanes marches a
// tile of rays in vector lanes instead (bricked_tangent_packet, IVR_RAYS > 1, as in core).
// The loss gradient, not the Jacobian (jacobian_pixel.cl's default is the Jacobian).
#ifndef IVR_JACOBIAN
#define IVR_JACOBIAN 0
#endif
#include "bricked_state.cl"
#include "config.cl"
#include "geometry.cl"
#include "jacobian_endpoints.cl"
#include "jacobian_exact.cl"
#include "jacobian_midpoint.cl"
#include "jacobian_pixel.cl"
#include "jacobian_ray.cl"
#include "march.cl"

#if IVR_JACOBIAN || !IVR_LOSS_GRADIENT
#error "bricked_tangent.cl computes the loss gradient (no Jacobian out of core)"
#endif

#define IVR_BRICK_TANGENT_MARCH 5
#define IVR_BRICK_TANGENT_FINISH 6
// Per ray and lane, the carried tangents: d T and d (r, g, b) (absorption: d τ alone).
#if IVR_EMISSION
#define IVR_TANGENT_SUMS 4
#else
#define IVR_TANGENT_SUMS 1
#endif

// The density's gradient is clamped at the volume's border only: at the brick's faces that are box
// faces (±∞ planes), not at its inner ones.
inline void brick_grid_clamps(TangentRay* tr, real4 brick_lo, real4 brick_hi, int4 dims) {
  tr->grid_lo = (real4)(isinf(brick_lo.x) ? (real)0 : -(real)INFINITY,
                        isinf(brick_lo.y) ? (real)0 : -(real)INFINITY,
                        isinf(brick_lo.z) ? (real)0 : -(real)INFINITY, (real)0);
  tr->grid_hi = (real4)(isinf(brick_hi.x) ? (real)(dims.x - 1) : (real)INFINITY,
                        isinf(brick_hi.y) ? (real)(dims.y - 1) : (real)INFINITY,
                        isinf(brick_hi.z) ? (real)(dims.z - 1) : (real)INFINITY, (real)0);
}

#if IVR_RAYS == 1
inline void tangent_sums_load(__global const real* g, TangentRay* tr) {
  IVR_FOR_LANES(p) {
    __global const real* q = g + p * IVR_TANGENT_SUMS;
    tr->dT[p] = q[0];
#if IVR_EMISSION
    tr->dcr[p] = q[1], tr->dcg[p] = q[2], tr->dcb[p] = q[3];
#else
    tr->dcr[p] = tr->dcg[p] = tr->dcb[p] = (real)0;
#endif
  }
}

inline void tangent_sums_store(const TangentRay* tr, __global real* g) {
  IVR_FOR_LANES(p) {
    __global real* q = g + p * IVR_TANGENT_SUMS;
    q[0] = tr->dT[p];
#if IVR_EMISSION
    q[1] = tr->dcr[p], q[2] = tr->dcg[p], q[3] = tr->dcb[p];
#endif
  }
}

// The arguments are bricked_render's up to `state_u` (the host sets them alike), then the
// tangents' (`tangents`: IVR_LANES · IVR_TANGENT_SUMS per ray, zero before the first brick),
// kernels/jacobian.cl's lanes, camera parameters, target and norm, and FINISH's outputs: the image,
// each listed ray's own gradient (IVR_RAY_GRADIENT) and the work-groups' rows of the loss and
// its derivatives (`scratch`: one row per item).
__kernel void bricked_tangent(
    __global const real* restrict volume, const int4 dims, const real4 box_min, const real4 box_max,
    const real4 inv_voxel, __global const real* restrict cameras, const int width, const int height,
    __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
    const real4 background, const real step, const real min_transmittance, const int phase,
    const real4 brick_lo, const real4 brick_hi, const int4 origin, __global real* restrict state,
    __global uint* restrict state_u, __global real* restrict tangents,
    __global const int4* restrict lanes, __global const real* restrict camera_params,
    __global const real* restrict target, const real norm, __global real* restrict image,
    __global real* restrict per_ray, __global real* restrict partial, __local real* scratch) {
  (void)step;
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  const bool active = x < width && y < height;  // padding items still meet FINISH's barrier
  const size_t pixel = ((size_t)view * height + y) * width + x;
  __global const real* cam = cameras + view * IVR_CAMERA_STRIDE;

  if (phase == IVR_BRICK_TANGENT_MARCH) {
    if (!active) return;
    __global real* s = state + pixel * IVR_BRICK_REALS;
    __global uint* su = state_u + pixel * IVR_BRICK_UINTS;
    RayMarch m;
    real tb1;
    if (!brick_enter(s, su, brick_lo, brick_hi, origin, &m, &tb1)) return;
    // The ray and its lanes as in core (its global march's ends: m.t0, m.t1 are the unsplit ones).
    const Ray ray = camera_ray(cam, x, y, width, height);
    TangentRay tr;
    tangent_ray_begin(&tr, lanes, cam, camera_params, view, x, y, width, height, ray, &m, box_min,
                      box_max, dims);
    brick_grid_clamps(&tr, brick_lo, brick_hi, dims);
    IVR_FOR_LANES(p) {  // a voxel lane in the brick's voxels (outside them: weight 0)
      if (tr.lane[p].x == IVR_LANE_VOXEL) tr.lane[p].yzw -= (int3)(origin.x, origin.y, origin.z);
    }
    __global real* g = tangents + pixel * (IVR_LANES * IVR_TANGENT_SUMS);
    tangent_sums_load(g, &tr);
    Radiance r = brick_load(s, su);
    int i = (int)su[BU_NEXT];
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
    tangent_march_midpoint_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars,
                                  min_transmittance, (__global const uchar*)0, (int4)0, &tr, &r,
                                  tb1, &i);
#elif IVR_ENDPOINT_SAMPLES
    tangent_march_endpoints_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars,
                                   min_transmittance, (__global const uchar*)0, (int4)0, &tr, &r,
                                   tb1, &i);
#else
    tangent_march_exact_window(
        volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars, min_transmittance,
        (__global const uchar*)0, (int4)0, &tr, &r, s[BS_TNEXT], tb1,
        brick_window_end_axis(s[BS_U0 + 0], s[BS_U0 + 1], s[BS_U0 + 2], s[BS_U0 + 3],
                              s[BS_U0 + 4], s[BS_U0 + 5], brick_lo, brick_hi, tb1));
#endif
    r.end = i;
    tangent_sums_store(&tr, g);
    brick_store(&r, s, su);
    su[BU_NEXT] = (uint)i;
    s[BS_TNEXT] = tb1;
    if (brick_stopped(&r, min_transmittance) || tb1 >= s[BS_TEND]) su[BU_FLAGS] |= IVR_BRICK_DONE;
    return;
  }

  real loss = (real)0, dloss[IVR_LANES];
  IVR_FOR_LANES(p) dloss[p] = (real)0;
  if (active && phase == IVR_BRICK_TANGENT_FINISH) {
    Radiance r = brick_load(state + pixel * IVR_BRICK_REALS, state_u + pixel * IVR_BRICK_UINTS);
    TangentRay tr;
    IVR_FOR_LANES(p) tr.lane[p] = lanes[p];
    tangent_sums_load(tangents + pixel * (IVR_LANES * IVR_TANGENT_SUMS), &tr);
    tangent_finish(&tr, &r);
    const Ray ray = camera_ray(cam, x, y, width, height);  // (a listed ray's direction)
    tangent_pixels(&r, &tr, ray, x, y, view, width, height, background, target, norm, image,
                   per_ray, &loss, dloss);
  }
  tangent_group_sums(loss, dloss, scratch, partial);
}
#endif

#if IVR_RAYS > 1
#if IVR_TANGENT_CAMERA || IVR_TANGENT_VOXEL || IVR_RAY_GRADIENT
#error "bricked_tangent_packet carries TF and background lanes (camera, voxel, ray lanes: one ray)"
#endif
#if IVR_SCHEME == IVR_SCHEME_EXACT
#error "bricked_tangent_packet marches the fixed-step schemes (exact: one ray a work-item)"
#endif
// TANGENT_MARCH on CPUs for a tile of IVR_RAYS neighbouring pixels in vector lanes (as
// kernels/bricked_packet.cl marches the render): each lane's ray takes its window in this brick
// exactly as bricked_tangent does — the same state, tangents and in-core window march — so the
// states and tangents it leaves, and the gradient, are the one-ray kernel's. The arguments are
// bricked_tangent's (the host sets both alike; FINISH is bricked_tangent's); a work-item is the
// tile with corner (IVR_PACKET_W · x, IVR_PACKET_H · y) of view z.
__kernel void bricked_tangent_packet(
    __global const real* restrict volume, const int4 dims, const real4 box_min, const real4 box_max,
    const real4 inv_voxel, __global const real* restrict cameras, const int width, const int height,
    __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
    const real4 background, const real step, const real min_transmittance, const int phase,
    const real4 brick_lo, const real4 brick_hi, const int4 origin, __global real* restrict state,
    __global uint* restrict state_u, __global real* restrict tangents,
    __global const int4* restrict lanes, __global const real* restrict camera_params,
    __global const real* restrict target, const real norm, __global real* restrict image,
    __global real* restrict per_ray, __global real* restrict partial, __local real* scratch) {
  (void)background, (void)step, (void)phase, (void)target, (void)norm, (void)image, (void)per_ray;
  (void)partial, (void)scratch;
  const int x0 = get_global_id(0) * IVR_PACKET_W, y0 = get_global_id(1) * IVR_PACKET_H;
  const int view = get_global_id(2);
  if (x0 >= width || y0 >= height) return;
  LaneWindows w;
  if (!brick_enter_lanes(state, state_u, x0, y0, view, width, height, brick_lo, brick_hi, origin,
                         &w))
    return;
  const March m = lanes_march(&w);
  vint i;
  Radiance r = brick_load_lanes(state, state_u, &w, &i);
  // The lanes (TF and background: no geometry of their own) and each lane's carried tangents.
  const Ray ray = {(real3)(real)0, (real3)(real)0};
  TangentRay tr;
  tangent_ray_begin(&tr, lanes, cameras + view * IVR_CAMERA_STRIDE, camera_params, view, x0, y0,
                    width, height, ray, (const March*)0, box_min, box_max, dims);
  brick_grid_clamps(&tr, brick_lo, brick_hi, dims);
  IVR_FOR_LANES(p) {
    real dT[IVR_RAYS], dcr[IVR_RAYS], dcg[IVR_RAYS], dcb[IVR_RAYS];
    for (int l = 0; l < IVR_RAYS; ++l) {
      __global const real* q =
          tangents + w.pixel[l] * (IVR_LANES * IVR_TANGENT_SUMS) + p * IVR_TANGENT_SUMS;
      dT[l] = w.entered[l] ? q[0] : (real)0;
#if IVR_EMISSION
      dcr[l] = w.entered[l] ? q[1] : (real)0, dcg[l] = w.entered[l] ? q[2] : (real)0;
      dcb[l] = w.entered[l] ? q[3] : (real)0;
#else
      dcr[l] = dcg[l] = dcb[l] = (real)0;
#endif
    }
    tr.dT[p] = IVR_LOAD_RAYS(dT), tr.dcr[p] = IVR_LOAD_RAYS(dcr);
    tr.dcg[p] = IVR_LOAD_RAYS(dcg), tr.dcb[p] = IVR_LOAD_RAYS(dcb);
  }
  const vreal window_end = IVR_LOAD_RAYS(w.tb1);
#if IVR_SCHEME == IVR_SCHEME_MIDPOINT
  tangent_march_midpoint_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars,
                                min_transmittance, (__global const uchar*)0, (int4)0, &tr, &r,
                                window_end, &i);
#else
  tangent_march_endpoints_window(volume, dims, &m, ray, inv_voxel, tf, tf_count, tf_scalars,
                                 min_transmittance, (__global const uchar*)0, (int4)0, &tr, &r,
                                 window_end, &i);
#endif
  r.end = i;  // (as bricked_tangent: the march's end is where this window left it)
  brick_store_lanes(&r, i, min_transmittance, state, state_u, &w);
  IVR_FOR_LANES(p) {
    real dT[IVR_RAYS], dcr[IVR_RAYS], dcg[IVR_RAYS], dcb[IVR_RAYS];
    IVR_STORE_RAYS(tr.dT[p], dT);
    IVR_STORE_RAYS(tr.dcr[p], dcr);
    IVR_STORE_RAYS(tr.dcg[p], dcg);
    IVR_STORE_RAYS(tr.dcb[p], dcb);
    for (int l = 0; l < IVR_RAYS; ++l) {
      if (!w.entered[l]) continue;
      __global real* q =
          tangents + w.pixel[l] * (IVR_LANES * IVR_TANGENT_SUMS) + p * IVR_TANGENT_SUMS;
      q[0] = dT[l];
#if IVR_EMISSION
      q[1] = dcr[l], q[2] = dcg[l], q[3] = dcb[l];
#else
      (void)dcr, (void)dcg, (void)dcb;
#endif
    }
  }
}
#endif
