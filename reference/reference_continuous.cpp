// reference_continuous.cpp — the high-accuracy references: the continuous integral of docs/design.md
// with no step parameter (render_continuous, optical_depth) and the definition of the
// `preintegrated` integrator (render_linear_segments: density linear between samples, the optical
// model integrated exactly along it). Written from docs/design.md alone, like reference.cpp.
//
// Method. Along a ray the density is a polynomial in t on "pieces": a cubic between consecutive
// crossings of the planes through voxel centres (trilinear interpolation of a straight line), or
// the linear profile of a preintegrated segment. On a piece d(s), s in [0, 1], is kept as monomial
// coefficients (a cubic is fitted exactly to four interior samples of `density`). For
// piecewise-linear and table TFs the piece is split where d crosses a knot density (first at the
// cubic's critical points, so that each part is monotone and crosses each knot at most once, then
// safeguarded Newton to full precision); on each resulting sub-piece sigma(d(t)) is a cubic in t
// and sigma*colour a degree-6 polynomial. Identity TFs need no split; Gaussian TFs are smooth and
// are subdivided so that no sub-interval spans more than a quarter of a relevant Gaussian's width.
// Each sub-piece is integrated with 8-point Gauss-Legendre (GL8, exact to degree 15):
//  - absorption: tau += GL8 of sigma (exact for the polynomial cases);
//  - emission-absorption: sub-intervals of optical depth <= 1; the optical depth from the
//    sub-interval's start to each node comes from the spectral integration matrix of the same
//    nodes (exact when sigma is a polynomial of degree <= 7, as here for all but Gaussian TFs),
//    and the emission is GL8 of exp(-tau) * sigma * colour. With depth <= 1 the GL8 error of
//    such an integrand is below 1e-16 relative (GL error ~ 1.7e-23 * depth^17 * scale).
// Optical depth is summed with compensation (Neumaier).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>
#include <stdexcept>
#include <thread>

#include "reference/reference.hpp"
#include "reference/sample_count.hpp"

namespace ivr::reference {
namespace {

constexpr int kN = 8;                // Gauss-Legendre order
constexpr double kMaxDepth = 1.0;    // optical depth of one emission-absorption sub-interval
constexpr double kGaussSpan = 0.25;  // d-range of one sub-interval, in Gaussian widths
constexpr double kTauUnderflow = 690.7755278982137;  // -log(1e-300)
constexpr double kPi = 3.14159265358979323846;

// GL nodes/weights on [-1, 1], the integration matrix S[j][k] = int_{-1}^{x_j} l_k (l_k the
// Lagrange basis of the nodes), and the map from values at four Chebyshev points on [0, 1] to
// monomial coefficients of the interpolating cubic.
struct Rules {
  double x[kN], w[kN], S[kN][kN];
  double cheb[4], to_monomial[4][4];  // coefficient of s^j = sum_k to_monomial[j][k] * y_k
  Rules() {
    for (int i = 0; i < kN; ++i) {
      double z = std::cos(kPi * (i + 0.75) / (kN + 0.5)), dp = 0;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1, p1 = z;
        for (int k = 2; k <= kN; ++k) {
          const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
          p0 = p1, p1 = p2;
        }
        dp = kN * (z * p1 - p0) / (z * z - 1);
        const double dz = p1 / dp;
        z -= dz;
        if (std::abs(dz) < 1e-17) break;
      }
      x[kN - 1 - i] = z;  // ascending
      w[kN - 1 - i] = 2 / ((1 - z * z) * dp * dp);
    }
    for (int j = 0; j < kN; ++j)
      for (int k = 0; k < kN; ++k) {
        double sum = 0;  // GL on [-1, x_j] is exact for the degree-7 l_k
        for (int m = 0; m < kN; ++m) sum += w[m] * lagrange(k, -1 + (x[j] + 1) * (x[m] + 1) / 2);
        S[j][k] = sum * (x[j] + 1) / 2;
      }
    for (int k = 0; k < 4; ++k) cheb[k] = (1 - std::cos((2 * k + 1) * kPi / 8)) / 2;
    for (int k = 0; k < 4; ++k) {
      double poly[4] = {1, 0, 0, 0};  // prod_{m != k} (s - cheb_m) / (cheb_k - cheb_m)
      for (int m = 0; m < 4; ++m) {
        if (m == k) continue;
        const double scale = 1 / (cheb[k] - cheb[m]);
        for (int j = 3; j >= 0; --j) poly[j] = ((j ? poly[j - 1] : 0) - cheb[m] * poly[j]) * scale;
      }
      for (int j = 0; j < 4; ++j) to_monomial[j][k] = poly[j];
    }
  }
  double lagrange(int k, double y) const {
    double p = 1;
    for (int m = 0; m < kN; ++m)
      if (m != k) p *= (y - x[m]) / (x[k] - x[m]);
    return p;
  }
};

const Rules& rules() {
  static const Rules r;
  return r;
}

double eval(const double c[4], double s) {
  return ((c[3] * s + c[2]) * s + c[1]) * s + c[0];
}
double slope(const double c[4], double s) {
  return (3 * c[3] * s + 2 * c[2]) * s + c[1];
}

// Neumaier's compensated sum.
struct Sum {
  double hi = 0, lo = 0;
  void add(double v) {
    const double t = hi + v;
    lo += std::abs(hi) >= std::abs(v) ? (hi - t) + v : (v - t) + hi;
    hi = t;
  }
  double value() const { return hi + lo; }
};

// The density at p, with p clamped into the closed box first: callers pass points that lie in it
// mathematically, and rounding must not push a face point out (where the density is 0).
double density_in_box(const ivr::Scene& scene, const glm::dvec3& p) {
  return density(scene, glm::clamp(p, scene.box_min, scene.box_max));
}

// The cubic d(s) = density(o + (ta + s (tb - ta)) dir) on a piece between centre-plane crossings,
// fitted to samples at four interior Chebyshev points (exact: d is a cubic there).
void fit_cubic(const ivr::Scene& scene, const glm::dvec3& o, const glm::dvec3& dir, double ta,
               double tb, double c[4]) {
  const Rules& r = rules();
  double y[4];
  for (int k = 0; k < 4; ++k) y[k] = density_in_box(scene, o + (ta + r.cheb[k] * (tb - ta)) * dir);
  for (int j = 0; j < 4; ++j)
    c[j] = r.to_monomial[j][0] * y[0] + r.to_monomial[j][1] * y[1] + r.to_monomial[j][2] * y[2] +
           r.to_monomial[j][3] * y[3];
}

// Roots of d'(s) strictly inside (0, 1), ascending; returns their count (at most 2).
int critical_points(const double c[4], double out[2]) {
  const double A = 3 * c[3], B = 2 * c[2], C = c[1];
  double r[2];
  int n = 0;
  if (A == 0) {
    if (B != 0) r[n++] = -C / B;
  } else {
    const double disc = B * B - 4 * A * C;
    if (disc >= 0) {
      const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
      r[n++] = q / A;
      if (q != 0) r[n++] = C / q;
    }
  }
  int m = 0;
  for (int i = 0; i < n; ++i)
    if (r[i] > 0 && r[i] < 1) out[m++] = r[i];
  if (m == 2 && out[0] > out[1]) std::swap(out[0], out[1]);
  return m;
}

// The s in (sa, sb) where d(s) = dk, given d(sa) - dk and d(sb) - dk of strictly opposite signs:
// Newton kept inside the shrinking bracket, bisection where it would leave it.
double knot_crossing(const double c[4], double sa, double sb, double dk) {
  const double fa = eval(c, sa) - dk, fb = eval(c, sb) - dk;
  double same = sa, other = sb;  // f(same) has the sign of fa
  double s = sa + (sb - sa) * fa / (fa - fb);
  for (int it = 0; it < 200; ++it) {
    const double f = eval(c, s) - dk;
    if (f == 0) return s;
    ((f < 0) == (fa < 0) ? same : other) = s;
    const double lo = std::min(same, other), hi = std::max(same, other);
    const double df = slope(c, s);
    double next = df != 0 ? s - f / df : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - s) <= 1e-17 || hi - lo <= 4e-16 * std::max(1.0, std::abs(hi))) return next;
    s = next;
  }
  return s;
}

// Integrates one ray, piece by piece.
class RayIntegrator {
 public:
  RayIntegrator(const ivr::Scene& scene, bool emission, double tau_stop, int refinement)
      : tf_(scene.tf), ea_(emission), tau_stop_(tau_stop), refine_(std::max(1, refinement)) {
    if (tf_.kind == ivr::TfKind::piecewise_linear) {
      for (const auto& p : tf_.points) knots_.push_back(p.density);
    } else if (tf_.kind == ivr::TfKind::table && tf_.entries.size() > 1 &&
               tf_.range.y > tf_.range.x) {
      const int r = int(tf_.entries.size());
      for (int i = 0; i < r; ++i)
        knots_.push_back(tf_.range.x + (tf_.range.y - tf_.range.x) * i / (r - 1));
    }
    std::sort(knots_.begin(), knots_.end());
    knots_.erase(std::unique(knots_.begin(), knots_.end()), knots_.end());
  }

  void reset() {
    tau_ = Sum{};
    radiance_ = glm::dvec3(0.0);
    done_ = false;
  }
  bool done() const { return done_; }
  double tau() const { return tau_.value(); }
  const glm::dvec3& radiance() const { return radiance_; }

  // A piece of world length len on which the density is the polynomial d(s), s in [0, 1].
  void piece(const double c[4], double len) {
    if (done_ || !(len > 0)) return;
    double bounds[4] = {0, 0, 0, 0};
    const int nb = 2 + critical_points(c, bounds + 1);
    bounds[nb - 1] = 1;
    if (knots_.empty()) {
      double lo = eval(c, 0), hi = lo;
      for (int i = 1; i < nb; ++i)
        lo = std::min(lo, eval(c, bounds[i])), hi = std::max(hi, eval(c, bounds[i]));
      smooth(c, 0, 1, len, lo, hi);
      return;
    }
    // Monotone parts between critical points; each crosses a knot strictly between its end
    // values exactly once.
    for (int p = 0; p + 1 < nb && !done_; ++p) {
      const double sa = bounds[p], sb = bounds[p + 1];
      const double da = eval(c, sa), db = eval(c, sb);
      double prev = sa;
      const auto first = std::upper_bound(knots_.begin(), knots_.end(), std::min(da, db));
      const auto last = std::lower_bound(knots_.begin(), knots_.end(), std::max(da, db));
      const std::ptrdiff_t n = last - first;
      for (std::ptrdiff_t i = 0; i < n && !done_; ++i) {
        const double dk = da < db ? first[i] : first[n - 1 - i];
        const double r = knot_crossing(c, sa, sb, dk);
        if (r > prev && r < sb) {
          smooth(c, prev, r, len, 0, 0);
          prev = r;
        }
      }
      if (!done_) smooth(c, prev, sb, len, 0, 0);
    }
  }

 private:
  // TF samples at the GL nodes of [sl, sr].
  void sample(const double c[4], double sl, double sr, double sig[kN], glm::dvec3 em[kN]) const {
    const Rules& r = rules();
    for (int k = 0; k < kN; ++k) {
      const TfSample t = transfer(tf_, eval(c, sl + (sr - sl) * (r.x[k] + 1) / 2));
      sig[k] = t.sigma;
      em[k] = t.emission;
    }
  }

  // int_{sl}^{u} sigma(d(s)) len ds by GL8 (exact for sigma of degree <= 15 in s).
  double depth(const double c[4], double sl, double u, double len) const {
    const Rules& r = rules();
    double sum = 0;
    for (int k = 0; k < kN; ++k)
      sum += r.w[k] * transfer(tf_, eval(c, sl + (u - sl) * (r.x[k] + 1) / 2)).sigma;
    return sum * (u - sl) * len / 2;
  }

  // A sub-piece [sl, sr] on which sigma(d(s)) and the emission are smooth; [dlo, dhi] bounds d
  // there (used for Gaussian TFs only).
  void smooth(const double c[4], double sl, double sr, double len, double dlo, double dhi) {
    if (!(sr > sl)) return;
    double sig[kN];
    glm::dvec3 em[kN];
    sample(c, sl, sr, sig, em);
    double m = parts_for_depth(sig, (sr - sl) * len);
    if (tf_.kind == ivr::TfKind::gaussian) {
      // Sub-intervals spanning at most kGaussSpan widths of every Gaussian that is not
      // negligible (exp(-800) underflows) on [dlo, dhi].
      double width = std::numeric_limits<double>::infinity();
      for (const auto& g : tf_.gaussians) {
        const double gap = std::max({0.0, g.mean - dhi, dlo - g.mean});
        if (g.extinction != 0 && gap < 40 * g.width) width = std::min(width, g.width);
      }
      if (std::isfinite(width)) {
        double dmax = std::max(std::abs(slope(c, sl)), std::abs(slope(c, sr)));
        if (c[3] != 0) {
          const double v = -c[2] / (3 * c[3]);
          if (v > sl && v < sr) dmax = std::max(dmax, std::abs(slope(c, v)));
        }
        m = std::max(m, std::ceil(dmax * (sr - sl) / (kGaussSpan * width)));
      }
    }
    m = std::min(m * refine_, 1e9);
    const long count = long(m);
    const double ds = (sr - sl) / double(count);
    for (long i = 0; i < count && !done_; ++i) {
      const double a = sl + ds * double(i), b = i + 1 == count ? sr : sl + ds * double(i + 1);
      if (count > 1) sample(c, a, b, sig, em);
      checked_interval(c, a, b, len, sig, em, 0);
    }
  }

  // Emission-absorption: how many parts of optical depth <= kMaxDepth an interval of world length
  // `width` needs, judged from its node samples (1 for absorption).
  double parts_for_depth(const double sig[kN], double width) const {
    if (!ea_) return 1;
    const Rules& r = rules();
    double est = 0, peak = 0;
    for (int k = 0; k < kN; ++k) est += r.w[k] * sig[k], peak = std::max(peak, std::abs(sig[k]));
    return std::max(1.0, std::ceil(std::max(std::abs(est) * width / 2, peak * width) / kMaxDepth));
  }

  // interval(), after re-checking the optical depth on the interval's own nodes (a narrow
  // extinction peak that the coarser nodes missed makes it split further).
  void checked_interval(const double c[4], double a, double b, double len, const double sig[kN],
                        const glm::dvec3 em[kN], int level) {
    const double parts = std::min(parts_for_depth(sig, (b - a) * len), 64.0);
    if (parts == 1 || level >= 6) return interval(c, a, b, len, sig, em);
    const long count = long(parts);
    double s2[kN];
    glm::dvec3 e2[kN];
    for (long i = 0; i < count && !done_; ++i) {
      const double lo = a + (b - a) * double(i) / double(count);
      const double hi = i + 1 == count ? b : a + (b - a) * double(i + 1) / double(count);
      sample(c, lo, hi, s2, e2);
      checked_interval(c, lo, hi, len, s2, e2, level + 1);
    }
  }

  // One sub-interval [a, b] with its node samples.
  void interval(const double c[4], double a, double b, double len, const double sig[kN],
                const glm::dvec3 em[kN]) {
    const Rules& r = rules();
    const double h = (b - a) * len / 2;
    double sum = 0;
    for (int k = 0; k < kN; ++k) sum += r.w[k] * sig[k];
    const double dtau = sum * h;
    const double tau0 = tau_.value();
    if (tau0 + dtau >= tau_stop_) {
      stop_inside(c, a, b, len, tau0, dtau);
      return;
    }
    if (ea_) add_emission(sig, em, h, tau0);
    tau_.add(dtau);
    if (ea_ && tau_.value() > kTauUnderflow) done_ = true;
  }

  // radiance += int exp(-tau(t)) sigma colour over the interval whose node samples are given.
  void add_emission(const double sig[kN], const glm::dvec3 em[kN], double h, double tau0) {
    const Rules& r = rules();
    for (int j = 0; j < kN; ++j) {
      double part = 0;
      for (int k = 0; k < kN; ++k) part += r.S[j][k] * sig[k];
      radiance_ += (r.w[j] * h * std::exp(-(tau0 + part * h))) * em[j];
    }
  }

  // tau reaches tau_stop_ inside [a, b]: find the exact point u (tau(u) = tau_stop_, monotone in
  // u), add the emission up to it and stop there.
  void stop_inside(const double c[4], double a, double b, double len, double tau0, double dtau) {
    double lo = a, hi = b;
    double u = tau_stop_ <= tau0 ? a : a + (b - a) * (tau_stop_ - tau0) / dtau;
    for (int it = 0; it < 200 && tau_stop_ > tau0; ++it) {
      const double g = tau0 + depth(c, a, u, len) - tau_stop_;
      if (g == 0) break;
      (g < 0 ? lo : hi) = u;
      const double dg = transfer(tf_, eval(c, u)).sigma * len;
      double next = dg > 0 ? u - g / dg : 0.5 * (lo + hi);
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      if (std::abs(next - u) <= 1e-17 || hi - lo <= 4e-16 * std::max(1.0, std::abs(hi))) {
        u = next;
        break;
      }
      u = next;
    }
    if (ea_ && u > a) {
      double sig[kN];
      glm::dvec3 em[kN];
      sample(c, a, u, sig, em);
      add_emission(sig, em, (u - a) * len / 2, tau0);
    }
    tau_ = Sum{};
    tau_.add(tau_stop_);
    done_ = true;
  }

  const ivr::TransferFunction& tf_;
  const bool ea_;
  const double tau_stop_;
  const double refine_;
  std::vector<double> knots_;
  Sum tau_;
  glm::dvec3 radiance_{0.0};
  bool done_ = false;
};

void background_pixel(const ivr::Scene& scene, double* out) {
  const glm::dvec3 bg = scene.effective_background();
  if (scene.model == ivr::Model::emission_absorption) {
    out[0] = bg.x, out[1] = bg.y, out[2] = bg.z, out[3] = 0.0;
  } else {
    out[0] = bg.x;
  }
}

void finish_pixel(const ivr::Scene& scene, const RayIntegrator& ri, double* out) {
  const glm::dvec3 bg = scene.effective_background();
  const double transmittance = std::exp(-ri.tau());
  if (scene.model == ivr::Model::emission_absorption) {
    const glm::dvec3 c = ri.radiance() + transmittance * bg;
    out[0] = c.x, out[1] = c.y, out[2] = c.z, out[3] = 1.0 - transmittance;
  } else {
    out[0] = bg.x * transmittance;
  }
}

// The continuous integral along one ray: pieces between centre-plane crossings (as in
// reference.cpp's integrate_ray), each a cubic.
void continuous_ray(const ivr::Scene& scene, const glm::dvec3& o, const glm::dvec3& dir,
                    RayIntegrator& ri) {
  ri.reset();
  double t0, t1;
  if (!clip_to_box(scene.box_min, scene.box_max, o, dir, &t0, &t1)) return;
  const std::vector<double> cuts = centre_plane_cuts(scene, o, dir, t0, t1);
  for (std::size_t p = 0; p + 1 < cuts.size() && !ri.done(); ++p) {
    if (!(cuts[p + 1] > cuts[p])) continue;
    double c[4];
    fit_cubic(scene, o, dir, cuts[p], cuts[p + 1], c);
    ri.piece(c, cuts[p + 1] - cuts[p]);
  }
}

// Every pixel of every view through `one_ray(o, dir, pixel, out)`, rows interleaved over two threads.
template <class PerThread>
std::vector<double> render_rows(const ivr::Scene& scene, PerThread make) {
  if (scene.cameras.empty()) return {};
  const int w = scene.cameras[0].width, h = scene.cameras[0].height, c = scene.channels();
  const int views = int(scene.cameras.size());
  std::vector<double> image(std::size_t(views) * h * w * c);
  const int rows = views * h;
  auto work = [&](int first, int stride) {
    auto one_ray = make();
    for (int r = first; r < rows; r += stride) {
      const int v = r / h, y = r % h;
      for (int x = 0; x < w; ++x) {
        glm::dvec3 o, d;
        ray(scene.cameras[v], x, y, &o, &d);
        one_ray(o, d, Pixel{v, x, y}, &image[((std::size_t(v) * h + y) * w + x) * c]);
      }
    }
  };
  std::thread other(work, 1, 2);
  work(0, 2);
  other.join();
  return image;
}

double stop_depth(const ivr::Scene& scene, bool early) {
  const double t = scene.integrator.min_transmittance;
  return early && t > 0 ? -std::log(t) : std::numeric_limits<double>::infinity();
}

}  // namespace

std::vector<double> render_continuous(const ivr::Scene& scene, bool early_termination,
                                      int refinement) {
  const bool ea = scene.model == ivr::Model::emission_absorption;
  const double tau_stop = stop_depth(scene, early_termination);
  return render_rows(scene, [&] {
    return [&, ri = RayIntegrator(scene, ea, tau_stop, refinement)](
               const glm::dvec3& o, const glm::dvec3& d, Pixel, double* out) mutable {
      double t0, t1;
      if (!clip_to_box(scene.box_min, scene.box_max, o, d, &t0, &t1))
        return background_pixel(scene, out);
      continuous_ray(scene, o, d, ri);
      finish_pixel(scene, ri, out);
    };
  });
}

double optical_depth(const ivr::Scene& scene, glm::dvec3 origin, glm::dvec3 dir) {
  RayIntegrator ri(scene, false, std::numeric_limits<double>::infinity(), 1);
  continuous_ray(scene, origin, glm::normalize(dir), ri);
  return ri.tau();
}

std::vector<double> render_linear_segments(const ivr::Scene& scene, double step_world) {
  if (!(step_world > 0))
    throw std::invalid_argument("reference::render_linear_segments: step must be > 0");
  const bool ea = scene.model == ivr::Model::emission_absorption;
  return render_rows(scene, [&] {
    return [&, ri = RayIntegrator(scene, ea, std::numeric_limits<double>::infinity(), 1)](
               const glm::dvec3& o, const glm::dvec3& d, Pixel p, double* out) mutable {
      double t0, t1;
      const unsigned n = sample_count(scene, p.view, p.x, p.y, step_world);
      if (n == 0 || !clip_to_box(scene.box_min, scene.box_max, o, d, &t0, &t1))
        return background_pixel(scene, out);
      ri.reset();
      const double dt = (t1 - t0) / n;
      double prev = density_in_box(scene, o + t0 * d);
      for (long i = 1; i <= long(n) && !ri.done(); ++i) {
        const double next = density_in_box(scene, o + (t0 + double(i) * dt) * d);
        const double c[4] = {prev, next - prev, 0, 0};
        ri.piece(c, dt);
        prev = next;
      }
      finish_pixel(scene, ri, out);
    };
  });
}

}  // namespace ivr::reference
