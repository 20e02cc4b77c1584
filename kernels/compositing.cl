// compositing.cl — one sample's share of the emission–absorption integral: decay exp(-tau) and
// the emitted fraction (1 - exp(-tau)) / tau, with its derivative for the adjoint.
#ifndef IVR_COMPOSITING_CL
#define IVR_COMPOSITING_CL
#include "config.cl"
#include "rays.cl"

// exp(-x), and in *fraction (1 - exp(-x)) / x: the share of a constant segment's emission that
// leaves it (1 at x = 0). No (1 - alpha) division and no cancellation: float64 uses expm1; float32
// uses a series below x = 0.1, whose truncation (x^5/720 < 1.4e-8) stays within float32 rounding,
// and one exp above (expm1 costs as much again on CPUs; the cancellation in 1 - exp(-x) is < 1e-6
// relative there). Below 0.1 the decay needs no exp either: exp(-x) = 1 - x·fraction, one fused
// multiply-add, within 0.58 ulp of the exact exp(-x) over every float in [0, 0.1) (glibc's expf:
// 0.50 ulp, OpenCL's exp: 3 ulp allowed). Optical depths per step are mostly that small, and exp
// is the costliest part of a sample: PoCL's takes about a third of the render's time.
// Every ray of a packet (kernels/rays.cl) takes the same arithmetic: the series where its x is
// small, the exp (computed only where some ray needs it) elsewhere.
__attribute__((always_inline)) inline vreal decay_and_fraction(vreal x, vreal* fraction) {
#if IVR_F64
  *fraction = vsel((vreal)1.0, -vexpm1(-x) / x, vmask_of(x > (vreal)0.0));
  return vexp(-x);
#else
  const vint small = vmask_of(x < 0.1f);
  const vreal series = 1.0f - x * (0.5f - x * (1.0f / 6 - x * (1.0f / 24 - x * (1.0f / 120))));
  if (vall(small)) {
    *fraction = series;
    return 1.0f - x * series;
  }
  const vreal decay = vexp(-x);
  *fraction = vsel((1.0f - decay) / x, series, small);
  return vsel(decay, 1.0f - x * series, small);
#endif
}

// d/dx of (1 - exp(-x)) / x, given decay = exp(-x) and fraction = (1 - exp(-x)) / x. Above 0.1
// it is (decay - fraction) / x (cancellation < 20 ulp there); below, its Taylor series
// sum_k (-1)^k k x^(k-1) / (k+1)!, truncated where the next term is below the precision.
inline vreal fraction_slope(vreal x, vreal decay, vreal fraction) {
#if IVR_RAYS == 1
  if (x >= (real)0.1) return (decay - fraction) / x;  // one ray: the series only where needed
#endif
#if IVR_F64
  const vreal series =
      -0.5 +
      x * (1.0 / 3 +
           x * (-1.0 / 8 +
                x * (1.0 / 30 +
                     x * (-1.0 / 144 +
                          x * (1.0 / 840 + x * (-1.0 / 5760 +
                                                x * (1.0 / 45360 + x * (-1.0 / 403200 +
                                                                        x * (1.0 / 3991680)))))))));
#else
  const vreal series =
      -0.5f +
      x * (1.0f / 3 + x * (-1.0f / 8 + x * (1.0f / 30 + x * (-1.0f / 144 + x * (1.0f / 840)))));
#endif
  return vsel(series, (decay - fraction) / x, vmask_of(x >= (real)0.1));
}

// sum += x, compensated (Kahan) in float32 so that 1e5-sample rays keep float32 accuracy; *error
// carries the running rounding error. float64 adds plainly. Only the rays where `m` is true add
// (a packet's finished or skipping rays keep their sums).
__attribute__((always_inline)) inline void accumulate_where(vreal* sum, vreal* error, vreal x,
                                                            vint m) {
#if IVR_F64
  (void)error;
  *sum = vsel(*sum, *sum + x, m);
#else
  const vreal y = x - *error;
  const vreal t = *sum + y;
  *error = vsel(*error, (t - *sum) - y, m);
  *sum = vsel(*sum, t, m);
#endif
}

inline void accumulate(vreal* sum, vreal* error, vreal x) {
  accumulate_where(sum, error, x, vtrue);
}

// transmittance·exp(-x). Below x = 0.1 as T - T·(x·fraction) in one fused multiply-add: forming
// 1 - x·fraction first would round x to the float spacing near 1 and bias long rays of small
// steps; above, the product with the decay (no cancellation there).
__attribute__((always_inline)) inline vreal attenuate(vreal transmittance, vreal x, vreal fraction,
                                                      vreal decay) {
  return vsel(transmittance * decay, fma(-transmittance, x * fraction, transmittance),
              vmask_of(x < (vreal)(real)0.1));
}

#endif
