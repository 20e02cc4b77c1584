// exp.cl — e^x in float32 from fused multiply-adds alone, the same bits on every device and in
// every vector width: OpenCL's exp may be 3 ulp off and differ between devices and between its
// scalar and vector forms, and a packet of rays (kernels/rays.cl) must render bit for bit what one
// ray per work-item renders, with a vector exp (PoCL's scalar one, called lane by lane, took a
// fifth of a packet render). Within 1 ulp of e^x (tests/render/exp_test.cpp, against the host's
// copy, reference/expf_steps.hpp, which runs the same steps). Subnormal results assume the
// device keeps subnormals (OpenCL's default for float32 on CPUs; a device or -cl-denorms-are-zero
// that flushes them returns 0 there instead).
#ifndef IVR_EXP_CL
#define IVR_EXP_CL
#include "config.cl"

// Cody–Waite reduction x = n·ln2 + r, |r| ≤ ln2/2 (ln2 split so that n·C1 is exact), Cephes'
// degree-6 polynomial for e^r, and 2^n applied as two power-of-two products (the first exact, the
// second exact too except that it rounds once into the subnormals). 0 below -104, +inf above
// log(FLT_MAX).
#define IVR_EXPF_BODY(T, TI, CONVERT_INT, AS_T)                                                  \
  const T xc = fmin(fmax(x, (T)-104.0f), (T)88.8f);                                            \
  const T n = floor(fma(xc, (T)1.44269504088896341f, (T)0.5f));                                \
  T r = fma(n, (T)-0.693359375f, xc);                                                          \
  r = fma(n, (T)2.12194440e-4f, r);                                                            \
  T p = fma((T)1.9875691500e-4f, r, (T)1.3981999507e-3f);                                      \
  p = fma(p, r, (T)8.3334519073e-3f);                                                          \
  p = fma(p, r, (T)4.1665795894e-2f);                                                          \
  p = fma(p, r, (T)1.6666665459e-1f);                                                          \
  p = fma(p, r, (T)5.0000001201e-1f);                                                          \
  p = (T)1.0f + fma(p, r * r, r); /* e^r = 1 + (r + r²·P(r)): one rounding near 1 */          \
  const TI k = CONVERT_INT(n);                                                                 \
  const TI low = k < -126, high = k > 127;                                                     \
  const TI biased = k + select((TI)0, (TI)100, low) - select((TI)0, (TI)1, high) + 127;        \
  const T second = select(select((T)1.0f, (T)7.88860905e-31f, low), (T)2.0f, high);            \
  T e = p * AS_T(biased << 23) * second; /* 2^k as 2^(k+100)·2^-100 or 2^(k-1)·2 at the ends */ \
  e = select(e, (T)0.0f, x < (T)-104.0f);                                                      \
  e = select(e, (T)INFINITY, x > (T)88.72283905206835f);                                       \
  return select(e, x + x, isnan(x)); /* NaN stays NaN (fmin/fmax above would drop it) */

inline float ivr_expf(float x) {
  // (select() of scalars takes the third operand's truth as C does.)
  IVR_EXPF_BODY(float, int, convert_int, as_float)
}
inline float8 ivr_expf8(float8 x) {
  IVR_EXPF_BODY(float8, int8, convert_int8, as_float8)
}
inline float16 ivr_expf16(float16 x) {
  IVR_EXPF_BODY(float16, int16, convert_int16, as_float16)
}
#undef IVR_EXPF_BODY

#endif
