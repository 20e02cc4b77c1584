// tangents.cl — forward-mode derivatives, one work-item per pixel: the render's march carrying
// IVR_LANES tangent lanes, each the derivative of every quantity with respect to one parameter
// (a TF parameter, a camera component, a background channel, a voxel), through ray generation,
// clipping, sampling, the TF and compositing. Writes the Jacobian of the pixel (IVR_JACOBIAN)
// and/or this work-group's share of the loss and its gradient (IVR_LOSS_GRADIENT), reduced in
// local memory without writing the Jacobian.
#include "compositing.cl"
#include "config.cl"
#include "geometry.cl"
#include "geometry_tangent.cl"
#include "loss.cl"
#include "tf.cl"
#include "tf_grad.cl"
#include "tf_tangent.cl"

#ifndef IVR_LANES
#define IVR_LANES 1
#endif
#ifndef IVR_TANGENT_TF  // some lane is a TF parameter
#define IVR_TANGENT_TF 1
#endif
#ifndef IVR_TANGENT_CAMERA  // some lane is a camera component
#define IVR_TANGENT_CAMERA 1
#endif
#ifndef IVR_TANGENT_VOXEL  // some lane is a voxel
#define IVR_TANGENT_VOXEL 1
#endif
#ifndef IVR_JACOBIAN
#define IVR_JACOBIAN 1
#endif
#ifndef IVR_LOSS_GRADIENT
#define IVR_LOSS_GRADIENT 1
#endif

// What a lane differentiates (int4 per lane: kind, a, b, c).
#define IVR_LANE_NONE 0        // padding: derivative 0
#define IVR_LANE_TF 1          // a = row, b = column
#define IVR_LANE_BACKGROUND 2  // a = channel
#define IVR_LANE_CAMERA 3      // a = view, b = component (0..6)
#define IVR_LANE_VOXEL 4       // (a, b, c) = (x, y, z)
#define IVR_LANE_STEP 5        // the step enters only through the sample count: derivative 0

#define IVR_FOR_LANES(p) for (int p = 0; p < IVR_LANES; ++p)

// Weight of voxel index j along one axis in the trilinear interpolation of cell i (clamped like
// trilinear_at(): on the upper edge the cell's two corners are the same voxel).
inline real axis_weight(int j, int i, real f, int n) {
  return (j == i ? (real)1 - f : (real)0) + (j == i + 1 && i + 1 < n ? f : (real)0);
}

__kernel void tangents(__global const real* restrict volume, const int4 dims, const real4 box_min,
                       const real4 box_max, const real4 inv_voxel,
                       __global const real* restrict cameras, const int width, const int height,
                       __global const real* restrict tf, const int tf_count, const real4 tf_scalars,
                       const real4 background, const real step, const real min_transmittance,
                       __global const int4* restrict lanes,
                       __global const real* restrict camera_params,
                       __global const real* restrict target, const real norm,
                       __global float* restrict image, __global float* restrict jacobian,
                       __global real* restrict partial, __local real* scratch) {
  const int x = get_global_id(0), y = get_global_id(1), view = get_global_id(2);
  const bool active = x < width && y < height;  // padding items still meet the barrier
  real loss = (real)0, dloss[IVR_LANES];
  IVR_FOR_LANES(p) dloss[p] = (real)0;

  if (active) {
    const Ray ray = camera_ray(cameras + view * IVR_CAMERA_STRIDE, x, y, width, height);
    // The lanes, in private memory for the sample loop.
    int4 lane_of[IVR_LANES];
    IVR_FOR_LANES(p) lane_of[p] = lanes[p];
    // Tangents of the ray: only camera lanes of this view move it.
    real dox[IVR_LANES], doy[IVR_LANES], doz[IVR_LANES];
    real ddx[IVR_LANES], ddy[IVR_LANES], ddz[IVR_LANES];
    IVR_FOR_LANES(p) {
      dox[p] = doy[p] = doz[p] = ddx[p] = ddy[p] = ddz[p] = (real)0;
#if IVR_TANGENT_CAMERA
      if (lane_of[p].x == IVR_LANE_CAMERA && lane_of[p].y == view) {
        const real sx = (real)2 * ((real)x + (real)0.5) / (real)width - (real)1;
        const real sy = (real)1 - (real)2 * ((real)y + (real)0.5) / (real)height;
        real3 o, d;
        camera_ray_tangent(camera_params + view * IVR_CAMERA_PARAMS_STRIDE, sx, sy, lane_of[p].z,
                           &o, &d);
        dox[p] = o.x, doy[p] = o.y, doz[p] = o.z, ddx[p] = d.x, ddy[p] = d.y, ddz[p] = d.z;
      }
#endif
    }

    real transmittance = (real)1, cr = 0, cg = 0, cb = 0, kr = 0, kg = 0, kb = 0;
    real dT[IVR_LANES], dcr[IVR_LANES], dcg[IVR_LANES], dcb[IVR_LANES];
    IVR_FOR_LANES(p) dT[p] = dcr[p] = dcg[p] = dcb[p] = (real)0;
    real t0, t1;
    if (clip_box(ray, box_min.xyz, box_max.xyz, &t0, &t1)) {
      const real length = t1 - t0;
      const uint n = max((uint)1, (uint)ceil(length / step));
      const real dt = length / (real)n;
      const real u0x = (ray.origin.x - box_min.x) * inv_voxel.x - (real)0.5;
      const real u0y = (ray.origin.y - box_min.y) * inv_voxel.y - (real)0.5;
      const real u0z = (ray.origin.z - box_min.z) * inv_voxel.z - (real)0.5;
      const real dux = ray.dir.x * inv_voxel.x, duy = ray.dir.y * inv_voxel.y,
                 duz = ray.dir.z * inv_voxel.z;
      // Entry and exit move with the ray: dt0, dt1, and the sub-step d(dt) = (dt1 - dt0) / n.
      real dt0[IVR_LANES], ddt[IVR_LANES];
#if IVR_TANGENT_CAMERA
      const int a0 = clip_axis(ray, box_min.xyz, box_max.xyz, t0, true);
      const int a1 = clip_axis(ray, box_min.xyz, box_max.xyz, t1, false);
#endif
      IVR_FOR_LANES(p) {
        dt0[p] = ddt[p] = (real)0;
#if IVR_TANGENT_CAMERA
        const real3 o = (real3)(dox[p], doy[p], doz[p]), d = (real3)(ddx[p], ddy[p], ddz[p]);
        const real e0 =
            a0 < 0 ? (real)0 : -(component(o, a0) + t0 * component(d, a0)) / component(ray.dir, a0);
        const real e1 =
            a1 < 0 ? (real)0 : -(component(o, a1) + t1 * component(d, a1)) / component(ray.dir, a1);
        dt0[p] = e0;
        ddt[p] = (e1 - e0) / (real)n;
#endif
      }
      int segment = 0, cursor = 0;
      for (uint i = 0; i < n; ++i) {
        const real mid = (real)i + (real)0.5;
        const real t = t0 + mid * dt;
        const real ux = u0x + t * dux, uy = u0y + t * duy, uz = u0z + t * duz;
        const real d = trilinear_at(volume, dims, ux, uy, uz);
        real er, eg, eb, dsigma_dd, der_dd, deg_dd, deb_dd;
        const real sigma = tf_sample_slope(d, tf, tf_count, tf_scalars, &segment, &er, &eg, &eb,
                                           &dsigma_dd, &der_dd, &deg_dd, &deb_dd);
        const real tau = sigma * dt;
        real fraction;
        const real decay = decay_and_fraction(tau, &fraction);
#if IVR_EMISSION
        const real weight = transmittance * dt * fraction;
        const real fslope = fraction_slope(tau, decay, fraction);
#endif
        const real next = attenuate(transmittance, tau, fraction, decay);

#if IVR_TANGENT_CAMERA || IVR_TANGENT_VOXEL
        // The sample's cell and weights (as trilinear_at() clamps them).
        real fx, fy, fz;
        const int ix = cell_axis(ux, dims.x, &fx), iy = cell_axis(uy, dims.y, &fy),
                  iz = cell_axis(uz, dims.z, &fz);
#endif
#if IVR_TANGENT_CAMERA
        // d density / d u, 0 along an axis where the position is clamped to the edge centres.
        real gx, gy, gz;
        {
          const int ox = ix + 1 < dims.x ? 1 : 0, oy = iy + 1 < dims.y ? dims.x : 0,
                    oz = iz + 1 < dims.z ? dims.x * dims.y : 0;
          __global const real* q = volume + ((iz * dims.y + iy) * dims.x + ix);
          const real v[8] = {q[0],  q[ox],      q[oy],      q[oy + ox],
                             q[oz], q[oz + ox], q[oz + oy], q[oz + oy + ox]};
          trilinear_gradient(v, fx, fy, fz, ux, uy, uz, dims, &gx, &gy, &gz);
        }
#endif
#if IVR_TANGENT_TF
        const TfPoint point = tf_point(d, tf, tf_count, tf_scalars, &cursor);
#endif

        IVR_FOR_LANES(p) {
          const int4 lane = lane_of[p];
          // d density: through the sample position (camera) or the voxel's own value.
          real dd = (real)0;
#if IVR_TANGENT_CAMERA
          const real dtp = dt0[p] + mid * ddt[p];  // d t of this sample
          dd = gx * (dox[p] + t * ddx[p] + dtp * ray.dir.x) * inv_voxel.x +
               gy * (doy[p] + t * ddy[p] + dtp * ray.dir.y) * inv_voxel.y +
               gz * (doz[p] + t * ddz[p] + dtp * ray.dir.z) * inv_voxel.z;
#endif
#if IVR_TANGENT_VOXEL
          if (lane.x == IVR_LANE_VOXEL)
            dd = axis_weight(lane.y, ix, fx, dims.x) * axis_weight(lane.z, iy, fy, dims.y) *
                 axis_weight(lane.w, iz, fz, dims.z);
#endif
          real dsig = dsigma_dd * dd, der = der_dd * dd, deg = deg_dd * dd, deb = deb_dd * dd;
#if IVR_TANGENT_TF
          if (lane.x == IVR_LANE_TF) {
            real pr, pg, pb;
            dsig += tf_param_partial(d, sigma, point, tf, tf_count, tf_scalars, lane.y, lane.z, &pr,
                                     &pg, &pb);
            der += pr;
            deg += pg;
            deb += pb;
          }
#endif
          const real dtau = dsig * dt + sigma * ddt[p];
#if IVR_EMISSION
          const real dweight =
              (dT[p] * dt + transmittance * ddt[p]) * fraction + transmittance * dt * fslope * dtau;
          dcr[p] += dweight * er + weight * der;
          dcg[p] += dweight * eg + weight * deg;
          dcb[p] += dweight * eb + weight * deb;
#else
          (void)der, (void)deg, (void)deb;
#endif
          dT[p] = dT[p] * decay - next * dtau;  // d (T e^-tau)
        }
#if IVR_EMISSION
        accumulate(&cr, &kr, weight * er);
        accumulate(&cg, &kg, weight * eg);
        accumulate(&cb, &kb, weight * eb);
#endif
        transmittance = next;
#if IVR_EARLY_TERMINATION
        if (transmittance < min_transmittance) break;
#endif
      }
    }

    // The pixel and its tangents; the background's own lanes.
    const size_t pixel = ((size_t)view * height + y) * width + x;
    real value[IVR_CHANNELS];
#if IVR_EMISSION
    value[0] = cr + transmittance * background.x;
    value[1] = cg + transmittance * background.y;
    value[2] = cb + transmittance * background.z;
    value[3] = (real)1 - transmittance;
#else
    value[0] = background.x * transmittance;
#endif
    for (int c = 0; c < IVR_CHANNELS; ++c) image[pixel * IVR_CHANNELS + c] = (float)value[c];
#if IVR_LOSS_GRADIENT
    real g[IVR_CHANNELS];
    for (int c = 0; c < IVR_CHANNELS; ++c)
      g[c] = loss_term(value[c], target[pixel * IVR_CHANNELS + c], norm, &loss);
#endif
    IVR_FOR_LANES(p) {
      const int4 lane = lane_of[p];
      real dv[IVR_CHANNELS];
#if IVR_EMISSION
      const real bg[3] = {background.x, background.y, background.z};
      const real dc[3] = {dcr[p], dcg[p], dcb[p]};
      for (int c = 0; c < 3; ++c)
        dv[c] = dc[c] + dT[p] * bg[c] +
                (lane.x == IVR_LANE_BACKGROUND && lane.y == c ? transmittance : (real)0);
      dv[3] = -dT[p];
#else
      dv[0] = background.x * dT[p] + (lane.x == IVR_LANE_BACKGROUND ? transmittance : (real)0);
#endif
#if IVR_JACOBIAN
      for (int c = 0; c < IVR_CHANNELS; ++c)
        jacobian[(pixel * IVR_CHANNELS + c) * IVR_LANES + p] = (float)dv[c];
#endif
#if IVR_LOSS_GRADIENT
      for (int c = 0; c < IVR_CHANNELS; ++c) dloss[p] += g[c] * dv[c];
#endif
    }
  }

#if IVR_LOSS_GRADIENT
  // The work-group's loss and gradient: summed in local memory in a fixed order (deterministic),
  // one row of IVR_LANES + 1 values per group.
  const int lid = get_local_id(1) * get_local_size(0) + get_local_id(0);
  const int lsize = get_local_size(0) * get_local_size(1);
  scratch[lid * (IVR_LANES + 1)] = loss;
  IVR_FOR_LANES(p) scratch[lid * (IVR_LANES + 1) + 1 + p] = dloss[p];
  barrier(CLK_LOCAL_MEM_FENCE);
  const size_t group =
      ((size_t)get_group_id(2) * get_num_groups(1) + get_group_id(1)) * get_num_groups(0) +
      get_group_id(0);
  for (int k = lid; k < IVR_LANES + 1; k += lsize) {
    real sum = (real)0;
    for (int i = 0; i < lsize; ++i) sum += scratch[i * (IVR_LANES + 1) + k];
    partial[group * (IVR_LANES + 1) + k] = sum;
  }
#endif
}
