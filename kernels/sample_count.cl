// sample_count.cl — whether a camera ray meets the box and into how many segments it is cut,
// defined in float32 arithmetic whose every operation is correctly rounded (docs/integrators.md,
// sample counts), so that float32 and float64 kernels on every device and compiler take the same n.
//
// Why not n = ceil(length / step) from the march's own geometry: that length carries the rounding
// of the precision, of the device's division (NVIDIA's float32 quotient is not correctly rounded
// by default) and of the compiler's contraction of a·b + c into FMAs, and a ray whose length is
// an integer number of steps (the hard cases are built that way) then gets n or n + 1 depending on
// all three. Here the inputs are the float32 roundings of the camera, box and step (the float64
// kernel rounds its own), products are summed only through explicit fma (nothing left to
// contract), and division and square root are correctly rounded (rounded.cl). reference/sample_count.cpp is the same definition on the
// host.
#ifndef IVR_SAMPLE_COUNT_CL
#define IVR_SAMPLE_COUNT_CL
#include "config.cl"
#include "rounded.cl"

// One slab of the box, as clip_slab() in geometry.cl, with the count's division.
inline void count_slab(float o, float d, float lo, float hi, float* t0, float* t1) {
  if (d != 0.0f) {
    const float ta = rounded_divide(lo - o, d), tb = rounded_divide(hi - o, d);
    const float enter = ta < tb ? ta : tb, leave = ta < tb ? tb : ta;
    if (enter > *t0) *t0 = enter;
    if (leave < *t1) *t1 = leave;
  } else if (o < lo || o > hi) {
    *t1 = -1.0f;
  }
}

// The ray of pixel (x, y) of the camera `cam` (IVR_CAMERA_STRIDE values): 0 where it misses the
// box, else n ≥ 1 segments of at most `step` (ceil of the correctly rounded length / step). The
// screen coordinates are the exact fractions (2x + 1 − W)/W and (H − 2y − 1)/H, rounded once.
inline uint sample_count(__global const real* cam, int x, int y, int width, int height,
                         real4 box_min, real4 box_max, real step) {
  float o[3], d[3];
  float t0 = 0.0f, t1 = INFINITY;
#if IVR_RAY_LIST
  // A ray list: the float32 roundings of the ray's own origin, direction and interval.
  (void)y, (void)width, (void)height;
  __global const real* row = cam + (size_t)x * IVR_RAY_STRIDE;
  for (int k = 0; k < 3; ++k) o[k] = (float)row[k], d[k] = (float)row[3 + k];
  t0 = (float)row[6];
  t1 = (float)row[7];
#else
  const float sx = rounded_divide((float)(2 * x + 1 - width), (float)width);
  const float sy = rounded_divide((float)(height - 2 * y - 1), (float)height);
  for (int k = 0; k < 3; ++k) {
    const float eye = (float)cam[k], fwd = (float)cam[3 + k];
    const float right = (float)cam[6 + k], up = (float)cam[9 + k];
    if (cam[12] != (real)0) {  // orthographic
      o[k] = fma(sy, up, fma(sx, right, eye));
      d[k] = fwd;
    } else {
      o[k] = eye;
      d[k] = fma(sy, up, fma(sx, right, fwd));
    }
  }
  if (cam[12] == (real)0) {
    const float norm = rounded_sqrt(fma(d[0], d[0], fma(d[1], d[1], d[2] * d[2])));
    for (int k = 0; k < 3; ++k) d[k] = rounded_divide(d[k], norm);
  }
#endif
  count_slab(o[0], d[0], (float)box_min.x, (float)box_max.x, &t0, &t1);
  count_slab(o[1], d[1], (float)box_min.y, (float)box_max.y, &t0, &t1);
  count_slab(o[2], d[2], (float)box_min.z, (float)box_max.z, &t0, &t1);
  // A ray list's empty interval (t_start = t_end, or one that ends before the box) misses.
  if (!(t0 < t1)) return 0u;
  const float q = rounded_divide(t1 - t0, (float)step);
  // Below 2^32 as a float; a longer march is no march anyone waits for (and the cast is defined).
  return q < 4294967040.0f ? max(1u, (uint)ceil(q)) : 4294967040u;
}

#endif
