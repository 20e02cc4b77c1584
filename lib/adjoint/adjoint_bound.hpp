// adjoint_bound.hpp — internal: the deterministic density gradient's fixed-point scale, chosen
// before the march from an a-priori bound on what one ray adds to the voxels (lib/adjoint/adjoint.cpp), so
// that one pass suffices; and the rule for the rare second pass.
#pragma once
#include <cstddef>
#include <cstdint>

#include "ivr/adjoint.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// The transfer function's extremes over the densities [lo, hi] (widened by a few float ulps: the
// kernels' trilinear interpolation may round a hair past the volume's range): σ ≤ sigma,
// |dσ/dd| ≤ sigma_slope, |colour channel| ≤ color, |d(σ·colour channel)/dd| ≤ emission_slope.
// Where the TF has a jump (two points at one density) the march never samples inside it, so it
// adds no slope.
struct TfExtremes {
  double sigma = 0, sigma_slope = 0, color = 0, emission_slope = 0;
};
TfExtremes tf_extremes(const TransferFunction& tf, double lo, double hi);

// A bound on Σ |contribution| over everything one ray adds to the density gradient (so on each
// single contribution too), for every scheme, given the TF's extremes over the densities, the
// largest |target element| and the loss over `elements` image elements (pixels × channels).
// With L the longest chord (the box diagonal) and M = max(|colour|, |background|):
//   emission–absorption  L·(Σ_rgb |dL/dC_c|·(2·M·max|σ'| + max|(σc)'|) + |dL/dA|·max|σ'|)
//   absorption           L·|dL/dI|·|I_in|·max|σ'|
// with |dL/dpixel| ≤ 2(|pixel| + |target|)/elements (mse; |C_c| ≤ M, A ≤ 1, |I| ≤ |I_in|) or
// 1/elements (l1). Derivation in lib/adjoint_bound.cpp.
double ray_gradient_bound(const Scene& scene, const TfExtremes& tf, double target_abs_max,
                          Loss loss, std::size_t elements);

// --- the fixed-point scale 2^S ---------------------------------------------------------------
// log2 of the cap on one ray's scaled Σ |contribution|: 2^62 / rays rounded down to a power of
// two, so that no voxel's sum (at most every ray's whole sum, plus half a unit of rounding per
// contribution) leaves the 64-bit range whatever the bound said. The kernel counts the rays (and
// single contributions) over the cap.
int fixed_cap_exponent(std::size_t rays);
// The scale that puts `largest` (> 0) just under cap/2; frexp keeps it a function of largest's
// bits alone.
int fixed_exponent_for(double largest, int cap_exponent);
// The scale for a per-ray bound: a ray within the bound stays under cap/2 (a factor 2 of slack for
// the kernels' float rounding against the bound's exact arithmetic). A bound of 0 (no density
// gradient) or one that is not finite gives a scale the pass itself will correct.
int fixed_exponent_from_bound(double bound, int cap_exponent);
// The bits the largest scaled contribution must keep (a float's significand): fewer, and the
// fixed-point rounding could show in the gradient beside the float atomics'.
constexpr int kFixedBits = 24;
// After a pass at scale `exponent` that counted `over_cap` rays or contributions over the cap and
// saw `largest` (the largest |contribution|) and `largest_ray` (the largest ray's Σ
// |contribution|; 0: nothing was added): `exponent` where the pass stands, else the scale a
// second pass must run at, fixed_exponent_for(largest_ray) — where the bound was violated
// (over_cap > 0) or so loose that the largest scaled contribution keeps fewer than kFixedBits
// bits. Both outcomes are functions of the inputs alone (the contributions are; the count and the
// maxima do not depend on the order of the adds).
int fixed_exponent_after(int exponent, std::int64_t over_cap, double largest, double largest_ray,
                         int cap_exponent);

// Test only: $IVR_FIXED_BOUND_SHIFT = k multiplies the bound by 2^k (k in -200 .. 200), so that
// tests can force either second pass (k < 0: rays over the cap; k > 0: too few bits).
// 0 when unset; a malformed value is an invalid_argument error.
int fixed_bound_shift();

}  // namespace ivr
