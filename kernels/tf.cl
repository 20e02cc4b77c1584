// tf.cl — the transfer functions of DESIGN.md: extinction sigma(d) and, for emission–absorption,
// the premultiplied emission sigma(d)·colour(d). Only the scene's TF kind is compiled.
#ifndef IVR_TF_CL
#define IVR_TF_CL
#include "config.cl"

// Packed parameters per kind (the host writes them in this layout):
//   identity:          none; scalars = (extinction_scale, color_scale)
//   piecewise_linear:  rows [density, r, g, b, sigma], sorted by density
//   table:             rows [r, g, b, sigma]; scalars = (lo, hi)
//   gaussian:          rows [mean, width, r, g, b, extinction]
#define IVR_TF_STRIDE_PIECEWISE_LINEAR 5
#define IVR_TF_STRIDE_TABLE 4
#define IVR_TF_STRIDE_GAUSSIAN 6

inline real tf_eval(real d, __global const real* tf, int count, real4 scalars, real3* emission) {
#if IVR_TF == IVR_TF_IDENTITY
  const real sigma = scalars.x * d;
#if IVR_EMISSION
  *emission = (real3)(sigma * scalars.y * d);
#endif
  return sigma;

#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR
  // Constant beyond the ends; in between, linear on the segment [d_k, d_k+1) holding d.
  __global const real* a = tf;
  __global const real* b = tf;
  real w = (real)0;
  if (d >= tf[(count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR]) {
    a = b = tf + (count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR;
  } else if (d > tf[0]) {
    int k = 0;
    while (tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR] <= d) ++k;
    a = tf + k * IVR_TF_STRIDE_PIECEWISE_LINEAR;
    b = a + IVR_TF_STRIDE_PIECEWISE_LINEAR;
    w = (d - a[0]) / (b[0] - a[0]);  // b[0] > d >= a[0], never zero
  }
  const real sigma = mix(a[4], b[4], w);
#if IVR_EMISSION
  *emission = sigma * mix((real3)(a[1], a[2], a[3]), (real3)(b[1], b[2], b[3]), w);
#endif
  return sigma;

#elif IVR_TF == IVR_TF_TABLE
  // R entries at evenly spaced densities lo..hi, linear in between, constant beyond.
  const real u = clamp((d - scalars.x) / (scalars.y - scalars.x), (real)0, (real)1) * (real)(count - 1);
  const int i0 = min((int)u, count - 1);
  const int i1 = min(i0 + 1, count - 1);
  const real w = u - (real)i0;
  __global const real* a = tf + i0 * IVR_TF_STRIDE_TABLE;
  __global const real* b = tf + i1 * IVR_TF_STRIDE_TABLE;
  const real sigma = mix(a[3], b[3], w);
#if IVR_EMISSION
  *emission = sigma * mix((real3)(a[0], a[1], a[2]), (real3)(b[0], b[1], b[2]), w);
#endif
  return sigma;

#elif IVR_TF == IVR_TF_GAUSSIAN
  real sigma = (real)0;
#if IVR_EMISSION
  real3 e = (real3)(0);
#endif
  for (int k = 0; k < count; ++k) {
    __global const real* g = tf + k * IVR_TF_STRIDE_GAUSSIAN;
    const real z = (d - g[0]) / g[1];
    const real s = g[5] * exp((real)-0.5 * z * z);
    sigma += s;
#if IVR_EMISSION
    e += s * (real3)(g[2], g[3], g[4]);
#endif
  }
#if IVR_EMISSION
  *emission = e;
#endif
  return sigma;
#else
#error "unknown IVR_TF"
#endif
}

#endif
