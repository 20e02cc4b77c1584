// rounded.cl — float32 division and square root correctly rounded on every device: the ray
// geometry and the sample count (sample_count.cl) use them so that no device's rounding of
// division moves a ray (NVIDIA's float32 quotient is not correctly rounded by default; 28 % of
// random quotients differ). The host picks the means per device (IVR_COUNT_ARITHMETIC,
// lib/runtime/runtime.hpp count_arithmetic): per ray a handful of these, never per sample.
#ifndef IVR_ROUNDED_CL
#define IVR_ROUNDED_CL
#include "config.cl"

#define IVR_COUNT_FP64 0      // through float64, whose quotient and root are correctly rounded
#define IVR_COUNT_OPTION 1    // the device's own, built with -cl-fp32-correctly-rounded-divide-sqrt
#define IVR_COUNT_RESIDUAL 2  // the device's own, corrected by exact fma residuals
#ifndef IVR_COUNT_ARITHMETIC
#define IVR_COUNT_ARITHMETIC IVR_COUNT_RESIDUAL
#endif

// Test only ($IVR_BUILD_OPTIONS=-DIVR_EMULATE_DIVISION_ERROR=1): the device's own float32 quotients
// and roots that the residual path starts from come out 1 ulp high, as on a device whose float32
// division is faithful but not correctly rounded (NVIDIA's by default), so that tests on any
// device can show that the correction undoes it (with IVR_COUNT_ARITHMETIC=residual).
#if defined(IVR_EMULATE_DIVISION_ERROR) && IVR_EMULATE_DIVISION_ERROR
#define ivr_divide_f32(a, b) nextafter((float)(a) / (float)(b), INFINITY)
#define ivr_sqrt_f32(a) nextafter(sqrt((float)(a)), INFINITY)
#else
#define ivr_divide_f32(a, b) ((float)(a) / (float)(b))
#define ivr_sqrt_f32(a) sqrt((float)(a))
#endif
#if IVR_COUNT_ARITHMETIC == IVR_COUNT_FP64 && !IVR_F64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif

#if IVR_COUNT_ARITHMETIC == IVR_COUNT_RESIDUAL
// Of c and its two neighbours, the one whose residual |r(c)| is smallest. For the quotient a/b,
// r(c) = fma(−c, b, a) = a − c·b exactly while c is within an ulp or so of a/b, and |a − c·b| =
// |b|·|a/b − c| orders the candidates by their distance to a/b; no quotient of floats lies half
// way between two floats, so there are no ties. Twice, to reach a start up to 2 ulp off.
#define IVR_NEAREST_OF_THREE(c, residual)                             \
  do {                                                                \
    for (int pass = 0; pass < 2; ++pass) {                            \
      const float lo_ = nextafter(c, -INFINITY), hi_ = nextafter(c, INFINITY); \
      const float rc_ = fabs(residual(c)), rl_ = fabs(residual(lo_)), rh_ = fabs(residual(hi_)); \
      if (rl_ < rc_ && rl_ <= rh_)                                    \
        c = lo_;                                                      \
      else if (rh_ < rc_)                                             \
        c = hi_;                                                      \
      else                                                            \
        break;                                                        \
    }                                                                 \
  } while (0)
#endif

inline float rounded_divide(float a, float b) {
#if IVR_COUNT_ARITHMETIC == IVR_COUNT_FP64
  // 53 ≥ 2·24 + 2 bits: rounding the float64 quotient to float32 is the correctly rounded one.
  return (float)((double)a / (double)b);
#elif IVR_COUNT_ARITHMETIC == IVR_COUNT_OPTION
  return a / b;
#else
  float q = ivr_divide_f32(a, b);
  if (b == 0.0f || !isfinite(q) || q == 0.0f) return q;
#define IVR_QUOTIENT_RESIDUAL(c) fma(-(c), b, a)
  IVR_NEAREST_OF_THREE(q, IVR_QUOTIENT_RESIDUAL);
#undef IVR_QUOTIENT_RESIDUAL
  return q;
#endif
}

inline float rounded_sqrt(float a) {
#if IVR_COUNT_ARITHMETIC == IVR_COUNT_FP64
  return (float)sqrt((double)a);  // innocuous double rounding, as for the quotient
#elif IVR_COUNT_ARITHMETIC == IVR_COUNT_OPTION
  return sqrt(a);
#else
  float s = ivr_sqrt_f32(a);
  if (!(a > 0.0f) || !isfinite(s)) return s;
  // |a − c²| = |√a − c|·(√a + c): the factor √a + c differs between the candidates by a few ulp,
  // and √a of a float never lies close enough to a midpoint for that to change the order.
#define IVR_ROOT_RESIDUAL(c) fma(-(c), (c), a)
  IVR_NEAREST_OF_THREE(s, IVR_ROOT_RESIDUAL);
#undef IVR_ROOT_RESIDUAL
  return s;
#endif
}

#endif
