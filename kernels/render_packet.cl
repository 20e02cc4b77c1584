// render_packet.cl — the forward render for CPU devices: 16 (or 8) neighbouring pixels of a row per
// work-item, marched together in vector lanes (a lane stops taking samples when its ray ends
// or terminates; the packet stops when all have). PoCL runs one work-item's loop as scalar code
// and cannot vectorise across work-items whose loops differ in length, so on CPUs the lanes have
// to be explicit. Emission–absorption, the midpoint rule, a piecewise-linear TF, float32, no
// empty-space skipping (lib/render/render.cpp chooses it); the arithmetic is render.cl's, lane by lane.
#include "compositing.cl"
#include "config.cl"
#include "geometry.cl"
#include "march.cl"
#include "tf.cl"

// IVR_PACKET_PRIMAL: the adjoint's primal march (lib/adjoint/adjoint.cpp): each pixel's emitted colour C
// and transmittance T into `image` (not C + T·background, 1 − T), for kernels/adjoint.cl to read.
#ifndef IVR_PACKET_PRIMAL
#define IVR_PACKET_PRIMAL 0
#endif

// Rays per work-item: 8 or 16 (the host's preamble may set it).
#ifndef IVR_LANES
#define IVR_LANES 8
#endif
#if IVR_LANES == 16
typedef float16 lanes_t;
typedef int16 lanes_int;
typedef uint16 lanes_uint;
#define vload_lanes vload16
#define vstore_lanes vstore16
#define convert_lanes_int_rtz convert_int16_rtz
#define convert_lanes_float convert_float16
#define convert_lanes_uint convert_uint16
#else
typedef float8 lanes_t;
typedef int8 lanes_int;
typedef uint8 lanes_uint;
#define vload_lanes vload8
#define vstore_lanes vstore8
#define convert_lanes_int_rtz convert_int8_rtz
#define convert_lanes_float convert_float8
#define convert_lanes_uint convert_uint8
#endif

// The lanes' values of v[i] (OpenCL C has no gather).
inline lanes_t gather(__global const float* restrict v, lanes_int i) {
#if IVR_LANES == 16
  return (lanes_t)(v[i.s0], v[i.s1], v[i.s2], v[i.s3], v[i.s4], v[i.s5], v[i.s6], v[i.s7],
                   v[i.s8], v[i.s9], v[i.sa], v[i.sb], v[i.sc], v[i.sd], v[i.se], v[i.sf]);
#else
  return (lanes_t)(v[i.s0], v[i.s1], v[i.s2], v[i.s3], v[i.s4], v[i.s5], v[i.s6], v[i.s7]);
#endif
}

// exp(-x) in every lane by the scalar exp that render.cl and the adjoint kernel call (a vector exp
// may round differently in the last bit, and the adjoint's remaining radiance, C minus the prefix,
// needs this march's C bit for bit). Only lanes at or above decay_and_fraction's series limit use
// it: a packet where none is skips it.
inline lanes_t decay_lanes(lanes_t x, lanes_int small) {
  if (all(small)) return (lanes_t)1.0f;  // unused: every lane takes the series
  float v[IVR_LANES];
  vstore_lanes(x, 0, v);
  for (int l = 0; l < IVR_LANES; ++l) v[l] = exp(-v[l]);
  return vload_lanes(0, v);
}

inline lanes_t lerp_lanes(lanes_t a, lanes_t b, lanes_t t) {
  return a + (b - a) * t;
}

// cell_axis() in every lane: the clamped cell index and the fraction in *f.
inline lanes_int cell_axis_lanes(lanes_t u, int n, lanes_t* f) {
  const lanes_t c = fmin(fmax(u, (lanes_t)0.0f), (lanes_t)(float)(n - 1));
  const lanes_int i = convert_lanes_int_rtz(c);
  *f = c - convert_lanes_float(i);
  return i;
}

__kernel void render_packet(__global const real* restrict volume, const int4 dims,
                            const real4 box_min, const real4 box_max, const real4 inv_voxel,
                            __global const real* restrict cameras, const int width,
                            const int height, __global const real* restrict tf,
                            const int tf_count, const real4 tf_scalars, const real4 background,
                            const real step, const real min_transmittance,
                            __global const uchar* restrict occupied, const int4 bricks,
                            __global float* restrict image, __global uint* restrict samples) {
  (void)occupied, (void)bricks, (void)tf_scalars;
  const int x0 = get_global_id(0) * IVR_LANES, y = get_global_id(1), view = get_global_id(2);
  if (x0 >= width || y >= height) return;

  // Each lane's ray, set up as render.cl sets it up (lanes past the image's edge and rays that
  // miss the box take no samples).
  float u0x[IVR_LANES], u0y[IVR_LANES], u0z[IVR_LANES], dux[IVR_LANES], duy[IVR_LANES],
      duz[IVR_LANES], t0[IVR_LANES], dt[IVR_LANES];
  int n[IVR_LANES];
  uint longest = 0;
  for (int l = 0; l < IVR_LANES; ++l) {
    March m;
    if (x0 + l < width &&
        march_begin(camera_ray(cameras + view * IVR_CAMERA_STRIDE, x0 + l, y, width, height),
                    cameras + view * IVR_CAMERA_STRIDE, x0 + l, y, width, height, box_min,
                    box_max, inv_voxel, step, &m)) {
      u0x[l] = m.u0x, u0y[l] = m.u0y, u0z[l] = m.u0z;
      dux[l] = m.dux, duy[l] = m.duy, duz[l] = m.duz;
      t0[l] = m.t0, dt[l] = m.dt, n[l] = (int)m.n;
      longest = max(longest, m.n);
    } else {
      u0x[l] = u0y[l] = u0z[l] = dux[l] = duy[l] = duz[l] = t0[l] = dt[l] = 0.0f;
      n[l] = 0;
    }
  }
  const lanes_t U0X = vload_lanes(0, u0x), U0Y = vload_lanes(0, u0y), U0Z = vload_lanes(0, u0z);
  const lanes_t DUX = vload_lanes(0, dux), DUY = vload_lanes(0, duy), DUZ = vload_lanes(0, duz);
  const lanes_t T0 = vload_lanes(0, t0), DT = vload_lanes(0, dt);
  const lanes_int N = vload_lanes(0, n);

  const int sx = dims.x, sxy = dims.x * dims.y;
  const int last = (tf_count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR;
  lanes_t T = (lanes_t)1.0f, cr = (lanes_t)0.0f, cg = cr, cb = cr, kr = cr, kg = cr, kb = cr;
  lanes_int taken = (lanes_int)0;
  // Lanes still marching: -1 (all bits) where true, as vector comparisons give.
  lanes_int live = (lanes_int)0 < N;
  for (uint i = 0; i < longest && any(live); ++i) {
    const lanes_t t = T0 + ((float)i + 0.5f) * DT;
    lanes_t fx, fy, fz;
    const lanes_int ix = cell_axis_lanes(U0X + t * DUX, dims.x, &fx);
    const lanes_int iy = cell_axis_lanes(U0Y + t * DUY, dims.y, &fy);
    const lanes_int iz = cell_axis_lanes(U0Z + t * DUZ, dims.z, &fz);
    const lanes_int ox = select((lanes_int)0, (lanes_int)1, ix + 1 < dims.x);
    const lanes_int oy = select((lanes_int)0, (lanes_int)sx, iy + 1 < dims.y);
    const lanes_int oz = select((lanes_int)0, (lanes_int)sxy, iz + 1 < dims.z);
    const lanes_int p = iz * sxy + iy * sx + ix;
    const lanes_t c00 = lerp_lanes(gather(volume, p), gather(volume, p + ox), fx);
    const lanes_t c10 = lerp_lanes(gather(volume, p + oy), gather(volume, p + oy + ox), fx);
    const lanes_t c01 = lerp_lanes(gather(volume, p + oz), gather(volume, p + oz + ox), fx);
    const lanes_t c11 = lerp_lanes(gather(volume, p + oz + oy), gather(volume, p + oz + oy + ox), fx);
    const lanes_t d = lerp_lanes(lerp_lanes(c00, c10, fy), lerp_lanes(c01, c11, fy), fz);

    // tf_sample() in every lane: the first point's values below it, the segment [d_k, d_k+1)
    // holding d, the last point's values from it on.
    lanes_t sigma = (lanes_t)tf[4], r = (lanes_t)tf[1], g = (lanes_t)tf[2], b = (lanes_t)tf[3];
    for (int k = 0; k + 1 < tf_count; ++k) {
      __global const real* a = tf + k * IVR_TF_STRIDE_PIECEWISE_LINEAR;
      __global const real* e = a + IVR_TF_STRIDE_PIECEWISE_LINEAR;
      const lanes_int in = d >= a[0] & d < e[0] & d > tf[0];
      const lanes_t w = (d - a[0]) / (e[0] - a[0]);
      sigma = select(sigma, lerp_lanes((lanes_t)a[4], (lanes_t)e[4], w), in);
      r = select(r, lerp_lanes((lanes_t)a[1], (lanes_t)e[1], w), in);
      g = select(g, lerp_lanes((lanes_t)a[2], (lanes_t)e[2], w), in);
      b = select(b, lerp_lanes((lanes_t)a[3], (lanes_t)e[3], w), in);
    }
    const lanes_int beyond = d >= tf[last];
    sigma = select(sigma, (lanes_t)tf[last + 4], beyond);
    r = select(r, (lanes_t)tf[last + 1], beyond);
    g = select(g, (lanes_t)tf[last + 2], beyond);
    b = select(b, (lanes_t)tf[last + 3], beyond);

    // composite() in every lane: decay_and_fraction's series below 0.1, one exp above.
    const lanes_t tau = sigma * DT;
    const lanes_int small = tau < 0.1f;
    const lanes_t series =
        1.0f - tau * (0.5f - tau * (1.0f / 6 - tau * (1.0f / 24 - tau * (1.0f / 120))));
    const lanes_t decay_big = decay_lanes(tau, small);
    const lanes_t fraction = select((decay_big - 1.0f) / -tau, series, small);
    const lanes_t weight = T * DT * fraction;
    // The emitted colour as accumulate() receives it: each product its own statement, so that the
    // compiler cannot fuse it with the compensation's subtraction (FP_CONTRACT fuses within an
    // expression only) — the adjoint's prefix must equal this C bit for bit.
    const lanes_t er = sigma * r, eg = sigma * g, eb = sigma * b;
    const lanes_t xr = weight * er, xg = weight * eg, xb = weight * eb;
    lanes_t y, s;
#define IVR_LANE_ACCUMULATE(sum, error, x)      \
  y = x - error;                                \
  s = sum + y;                                  \
  error = select(error, (s - sum) - y, live);   \
  sum = select(sum, s, live)
    IVR_LANE_ACCUMULATE(cr, kr, xr);
    IVR_LANE_ACCUMULATE(cg, kg, xg);
    IVR_LANE_ACCUMULATE(cb, kb, xb);
#undef IVR_LANE_ACCUMULATE
    T = select(T, select(T * decay_big, fma(-T, tau * fraction, T), small), live);
    taken -= live;  // live is -1 where true
#if IVR_EARLY_TERMINATION
    live = live & ((lanes_int)(int)(i + 1) < N) & (T >= min_transmittance);
#else
    live = live & ((lanes_int)(int)(i + 1) < N);
#endif
  }

  float out_t[IVR_LANES], out_r[IVR_LANES], out_g[IVR_LANES], out_b[IVR_LANES];
  uint out_n[IVR_LANES];
  vstore_lanes(T, 0, out_t);
#if IVR_PACKET_PRIMAL
  vstore_lanes(cr, 0, out_r);
  vstore_lanes(cg, 0, out_g);
  vstore_lanes(cb, 0, out_b);
#else
  vstore_lanes(cr + T * background.x, 0, out_r);
  vstore_lanes(cg + T * background.y, 0, out_g);
  vstore_lanes(cb + T * background.z, 0, out_b);
#endif
  vstore_lanes(convert_lanes_uint(taken), 0, out_n);
  for (int l = 0; l < IVR_LANES && x0 + l < width; ++l) {
    const size_t pixel = ((size_t)view * height + y) * width + x0 + l;
    samples[pixel] = out_n[l];
    __global float* o = image + pixel * 4;
    o[0] = out_r[l];
    o[1] = out_g[l];
    o[2] = out_b[l];
#if IVR_PACKET_PRIMAL
    o[3] = out_t[l];
#else
    o[3] = 1.0f - out_t[l];
#endif
  }
}
