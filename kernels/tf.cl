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

// sigma(d), and with IVR_EMISSION the premultiplied emission in (*er, *eg, *eb). Scalars rather
// than real3 because PoCL compiles real3 into padded 4-wide vectors with lane shuffles around them.
// *segment is the piecewise-linear search's cursor: a marching loop starts it at 0 and passes it
// from one sample to the next; densities along a ray are continuous, so the search mostly stays
// put or moves one segment instead of scanning from the first point. The segment found, and so
// the value, is the same from any start. Other kinds ignore it.
__attribute__((always_inline)) inline real tf_sample(real d, __global const real* tf, int count,
                                                     real4 scalars, int* segment, real* er,
                                                     real* eg, real* eb) {
#if IVR_TF == IVR_TF_IDENTITY
  const real sigma = scalars.x * d;
#if IVR_EMISSION
  *er = *eg = *eb = sigma * scalars.y * d;
#endif
  return sigma;

#elif IVR_TF == IVR_TF_PIECEWISE_LINEAR
  // Constant beyond the ends; in between, linear on the segment [d_k, d_k+1) holding d.
  __global const real* a = tf;
  __global const real* b = tf;
  real w = (real)0;
  if (d >= tf[(count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR]) {
    a = b = tf + (count - 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR;
  } else if (d > tf[0]) {  // so count >= 2, and the k with d_k <= d < d_k+1 exists
    int k = *segment;
    while (k > 0 && tf[k * IVR_TF_STRIDE_PIECEWISE_LINEAR] > d) --k;
    while (tf[(k + 1) * IVR_TF_STRIDE_PIECEWISE_LINEAR] <= d) ++k;
    *segment = k;
    a = tf + k * IVR_TF_STRIDE_PIECEWISE_LINEAR;
    b = a + IVR_TF_STRIDE_PIECEWISE_LINEAR;
    w = (d - a[0]) / (b[0] - a[0]);  // b[0] > d >= a[0], never zero
  }
  const real sigma = lerp(a[4], b[4], w);
#if IVR_EMISSION
  *er = sigma * lerp(a[1], b[1], w);
  *eg = sigma * lerp(a[2], b[2], w);
  *eb = sigma * lerp(a[3], b[3], w);
#endif
  return sigma;

#elif IVR_TF == IVR_TF_TABLE
  // R entries at evenly spaced densities lo..hi, linear in between, constant beyond.
  const real u =
      clamp((d - scalars.x) / (scalars.y - scalars.x), (real)0, (real)1) * (real)(count - 1);
  const int i0 = min((int)u, count - 1);
  const int i1 = min(i0 + 1, count - 1);
  const real w = u - (real)i0;
  __global const real* a = tf + i0 * IVR_TF_STRIDE_TABLE;
  __global const real* b = tf + i1 * IVR_TF_STRIDE_TABLE;
  const real sigma = lerp(a[3], b[3], w);
#if IVR_EMISSION
  *er = sigma * lerp(a[0], b[0], w);
  *eg = sigma * lerp(a[1], b[1], w);
  *eb = sigma * lerp(a[2], b[2], w);
#endif
  return sigma;

#elif IVR_TF == IVR_TF_GAUSSIAN
  real sigma = (real)0;
#if IVR_EMISSION
  real r = (real)0, g = (real)0, bl = (real)0;
#endif
  for (int k = 0; k < count; ++k) {
    __global const real* p = tf + k * IVR_TF_STRIDE_GAUSSIAN;
    const real z = (d - p[0]) / p[1];
    const real s = p[5] * exp((real)-0.5 * z * z);
    sigma += s;
#if IVR_EMISSION
    r += s * p[2];
    g += s * p[3];
    bl += s * p[4];
#endif
  }
#if IVR_EMISSION
  *er = r;
  *eg = g;
  *eb = bl;
#endif
  return sigma;
#else
#error "unknown IVR_TF"
#endif
}

// sigma(d), and with IVR_EMISSION the premultiplied emission in *emission (absorption: untouched).
inline real tf_eval(real d, __global const real* tf, int count, real4 scalars, real3* emission) {
  int segment = 0;
  real r, g, b;
  const real sigma = tf_sample(d, tf, count, scalars, &segment, &r, &g, &b);
#if IVR_EMISSION
  *emission = (real3)(r, g, b);
#endif
  return sigma;
}

#endif
