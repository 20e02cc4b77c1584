// adjoint_bound.cpp — the a-priori bound on one ray's density-gradient contributions and the
// fixed-point scale it sets (lib/adjoint/adjoint_bound.hpp).
//
// Why the bound holds (docs/design.md's discrete model, T_i ≤ 1, Σ_i Δ_i = the chord ≤ L):
// emission–absorption, sample i with σ_i, premultiplied emission E_i = σ_i·c_i, weight
// w_i = T_i·Δ_i·f(τ_i) (f(τ) = (1 − e^{−τ})/τ ≤ 1, so w_i = T_i·α_i/σ_i ≤ T_i·Δ_i), C = Σ w_i E_i + T_n B:
//   ∂C/∂E_i = w_i ≤ T_i Δ_i;
//   ∂C/∂σ_i (E fixed) = T_i Δ_i² f'(τ_i) E_i − Δ_i T_{i+1} R_{i+1}, and τ|f'(τ)| = f(τ) − e^{−τ} ≤ 1,
//   |E_i| ≤ σ_i·max|c|, |R_{i+1}| ≤ M (a convex combination of colours and B), so |·| ≤ 2 T_i Δ_i M;
//   ∂A/∂σ_i = Δ_i T_n ≤ T_i Δ_i, ∂A/∂E_i = 0.
// By the chain rule |∂C_c/∂d_i| ≤ T_i Δ_i (2M max|σ'| + max|E_c'|), |∂A/∂d_i| ≤ T_i Δ_i max|σ'|, and
// summed over the ray ≤ L·(…). Trapezoid splits each segment's ∂/∂τ (≤ 2 T M, as above with
// τ = Δ(σ_a + σ_b)/2) and ∂/∂Ē (≤ T Δ) half to each end: the same sum. Preintegrated and exact
// integrate the continuous model, whose functional derivative T(t)·(E'(d) − σ'(d)·R(t)) is
// smaller still, and distribute it to the segment's ends with weights that sum to 1. Absorption:
// I = I_in·T_n, dI/dσ_i = −Δ_i·I, so |∂I/∂d_i| ≤ Δ_i |I_in| max|σ'| in every scheme (exact: Simpson's
// weights sum to the piece). The loss adjoint multiplies each channel's term; trilinear weights are
// ≥ 0 and sum to 1, and the cell cache only sums a ray's samples before they leave, so Σ over the
// ray's contributions of |c| is at most Σ over its samples of |dL/dd_i|: the bound.
#include "adjoint/adjoint_bound.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "ivr/error.hpp"

namespace ivr {

namespace {

// A TF linear between knots (piecewise-linear points, table entries), constant beyond the ends.
struct Knot {
  double d, r, g, b, sigma;
  double color() const { return std::max(std::abs(r), std::max(std::abs(g), std::abs(b))); }
};

Knot lerp_knot(const Knot& a, const Knot& b, double x) {
  const double w = (x - a.d) / (b.d - a.d);
  auto at = [w](double p, double q) { return p + w * (q - p); };
  return {x, at(a.r, b.r), at(a.g, b.g), at(a.b, b.b), at(a.sigma, b.sigma)};
}

// The TF's value at x as the kernels take it: the segment [d_k, d_k+1) holding x.
Knot knot_value(const std::vector<Knot>& k, double x) {
  if (x <= k.front().d) return k.front();
  if (x >= k.back().d) return k.back();
  std::size_t i = 0;
  while (k[i + 1].d <= x) ++i;
  return lerp_knot(k[i], k[i + 1], x);
}

TfExtremes linear_extremes(const std::vector<Knot>& k, double lo, double hi) {
  TfExtremes e;
  // Linear pieces take their extremes at their ends: the range's two ends and the knots inside.
  auto take = [&](const Knot& v) {
    e.sigma = std::max(e.sigma, v.sigma);
    e.color = std::max(e.color, v.color());
  };
  take(knot_value(k, lo));
  take(knot_value(k, hi));
  for (const Knot& v : k)
    if (v.d >= lo && v.d <= hi) take(v);
  for (std::size_t i = 0; i + 1 < k.size(); ++i) {
    const Knot &a = k[i], &b = k[i + 1];
    const double width = b.d - a.d;
    if (!(width > 0) || b.d < lo || a.d > hi) continue;  // a jump, or outside the densities
    const double ds = std::abs(b.sigma - a.sigma) / width;
    const double dc = std::max(std::abs(b.r - a.r), std::max(std::abs(b.g - a.g),
                                                             std::abs(b.b - a.b))) / width;
    e.sigma_slope = std::max(e.sigma_slope, ds);
    // (σc)' = σ'c + σc' on the segment, with σ and |c| at most their larger end values.
    e.emission_slope = std::max(e.emission_slope, ds * std::max(a.color(), b.color()) +
                                                      std::max(a.sigma, b.sigma) * dc);
  }
  return e;
}

}  // namespace

TfExtremes tf_extremes(const TransferFunction& tf, double lo, double hi) {
  const double pad = std::ldexp(std::max(1.0, std::max(std::abs(lo), std::abs(hi))), -20);
  lo -= pad;
  hi += pad;
  TfExtremes e;
  switch (tf.kind) {
    case TfKind::identity: {  // σ = a·d, colour = b·d, σ·colour = a·b·d²
      const double a = std::abs(tf.extinction_scale), b = std::abs(tf.color_scale);
      const double d = std::max(std::abs(lo), std::abs(hi));
      e.sigma = a * d;
      e.sigma_slope = a;
      e.color = b * d;
      e.emission_slope = 2 * a * b * d;
      return e;
    }
    case TfKind::piecewise_linear: {
      std::vector<Knot> k;
      for (const TfPoint& p : tf.points)
        k.push_back({p.density, p.color.x, p.color.y, p.color.z, p.extinction});
      return linear_extremes(k, lo, hi);
    }
    case TfKind::table: {
      std::vector<Knot> k;
      const std::size_t n = tf.entries.size();
      for (std::size_t i = 0; i < n; ++i) {
        const double d =
            n > 1 ? tf.range.x + (tf.range.y - tf.range.x) * double(i) / double(n - 1) : tf.range.x;
        const glm::dvec4& v = tf.entries[i];
        k.push_back({d, v.x, v.y, v.z, v.w});
      }
      return linear_extremes(k, lo, hi);
    }
    case TfKind::gaussian: {
      // σ = Σ e_k G_k, G_k = exp(−z²/2), z = (d − mean)/width: G ≤ 1, |G'| = |z| G / width with
      // |z|·exp(−z²/2) at most e^{−1/2} (at |z| = 1); both over the range's z interval.
      double slope[3] = {0, 0, 0};
      for (const TfGaussian& g : tf.gaussians) {
        const double za = (lo - g.mean) / g.width, zb = (hi - g.mean) / g.width;
        const double peak = za <= 0 && zb >= 0 ? 1 : std::exp(-0.5 * std::min(za * za, zb * zb));
        auto h = [](double z) { return std::abs(z) * std::exp(-0.5 * z * z); };
        const bool holds_one = (za <= 1 && zb >= 1) || (za <= -1 && zb >= -1);
        const double steepest = (holds_one ? std::exp(-0.5) : std::max(h(za), h(zb))) / g.width;
        e.sigma += g.extinction * peak;
        e.sigma_slope += g.extinction * steepest;
        if (g.extinction * peak > 0)  // the colour is the Gaussians' σ-weighted mean
          e.color = std::max(e.color, std::max(std::abs(g.color.x),
                                               std::max(std::abs(g.color.y), std::abs(g.color.z))));
        for (int c = 0; c < 3; ++c) slope[c] += g.extinction * steepest * std::abs(g.color[c]);
      }
      e.emission_slope = std::max(slope[0], std::max(slope[1], slope[2]));
      return e;
    }
  }
  return e;
}

double ray_gradient_bound(const Scene& scene, const TfExtremes& tf, double target_abs_max,
                          Loss loss, std::size_t elements) {
  const double chord = glm::length(scene.box_max - scene.box_min);
  const double norm = 1.0 / double(std::max<std::size_t>(elements, 1));
  const glm::dvec3 bg = scene.effective_background();
  // |dL/dpixel| for a pixel value of at most `value` in magnitude (kernels/loss.cl).
  auto adjoint = [&](double value) {
    if (loss == Loss::dot) return target_abs_max;  // dL/dpixel is the target itself
    return loss == Loss::l1 ? norm : 2 * (value + target_abs_max) * norm;
  };
  if (scene.model == Model::absorption) {
    const double in = std::abs(bg.x);
    return chord * adjoint(in) * in * tf.sigma_slope;
  }
  const double m =
      std::max(tf.color, std::max(std::abs(bg.x), std::max(std::abs(bg.y), std::abs(bg.z))));
  return chord * (3 * adjoint(m) * (2 * m * tf.sigma_slope + tf.emission_slope) +
                  adjoint(1.0) * tf.sigma_slope);
}

namespace {
// Scales beyond any float's exponent range: the kernel's ldexp gives 0 or Inf there, which the
// pass reports (too few bits, or over the cap) like any other wrong scale.
constexpr int kExponentLimit = 1100;
}  // namespace

int fixed_cap_exponent(std::size_t rays) {
  int e = 0;
  std::frexp(double(std::max<std::size_t>(rays, 1)), &e);  // rays < 2^e
  const bool power_of_two = std::ldexp(1.0, e - 1) == double(std::max<std::size_t>(rays, 1));
  return 62 - (power_of_two ? e - 1 : e);  // 2^62 / rays, rounded down to a power of two
}

int fixed_exponent_for(double largest, int cap_exponent) {
  int e = 0;
  std::frexp(largest, &e);  // largest < 2^e
  return std::clamp(cap_exponent - 1 - e, -kExponentLimit, kExponentLimit);
}

int fixed_exponent_from_bound(double bound, int cap_exponent) {
  if (!(bound > 0)) return cap_exponent - 1;  // no gradient expected: any scale does
  if (!std::isfinite(bound)) return -kExponentLimit;
  return fixed_exponent_for(bound, cap_exponent);
}

int fixed_exponent_after(int exponent, std::int64_t over_cap, double largest, double largest_ray,
                         int cap_exponent) {
  if (!(largest_ray > 0)) return exponent;  // nothing was added: every scale gives zeros
  const int ideal = fixed_exponent_for(largest_ray, cap_exponent);
  if (over_cap > 0) return std::min(ideal, exponent - 1);
  int e = 0;
  std::frexp(largest, &e);  // largest ≥ 2^(e−1): scaled, ≥ 2^(e−1+S)
  return e - 1 + exponent >= kFixedBits || ideal <= exponent ? exponent : ideal;
}

int fixed_bound_shift() {
  const char* text = std::getenv("IVR_FIXED_BOUND_SHIFT");
  if (!text || !*text) return 0;
  char* end = nullptr;
  errno = 0;
  const long k = std::strtol(text, &end, 10);
  if (errno != 0 || *end != '\0' || k < -200 || k > 200)
    throw Error(Status::invalid_argument,
                std::string("IVR_FIXED_BOUND_SHIFT must be an integer in -200 .. 200, got '") +
                    text + "'");
  return int(k);
}

}  // namespace ivr
