// native_marcher.cpp — plain C++/OpenMP float32 ray marcher and its hand-written adjoint: the
// native CPU limit ivr is measured against (same camera, clipping, trilinear, piecewise-linear TF,
// compositing and adjoint march as the kernels).
#include "reference/native_marcher.hpp"

#include "reference/sample_count.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <stdexcept>

namespace ivr::bench {

namespace {

struct V3 {
  float x, y, z;
};
inline V3 operator+(V3 a, V3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline V3 operator-(V3 a, V3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline V3 operator*(float s, V3 a) {
  return {s * a.x, s * a.y, s * a.z};
}
inline V3 mul(V3 a, V3 b) {
  return {a.x * b.x, a.y * b.y, a.z * b.z};
}
V3 v3(const glm::dvec3& v) {
  return {float(v.x), float(v.y), float(v.z)};
}

inline float lerp(float a, float b, float t) {
  return a + (b - a) * t;
}

// sum += x, compensated (Kahan), as kernels/compositing.cl's accumulate.
inline void kahan(float& sum, float& error, float x) {
  const float y = x - error, t = sum + y;
  error = (t - sum) - y;
  sum = t;
}

struct Point {
  float d, r, g, b, sigma;
};

// One view as the kernel's camera buffer holds it (lib/scene/device_scene.hpp, pack_cameras): eye,
// forward, and right and up scaled to the image plane.
struct View {
  V3 eye, fwd, right, up;
  bool ortho;
};

// The scene as the marches read it: float32, the step in world units.
struct Prepared {
  bool absorption = false;  // the absorption model (render only)
  bool identity = false;    // the identity TF σ = a·d, colour b·d (render only)
  float id_a = 0, id_b = 0;
  std::vector<Point> tf;
  std::vector<View> views;
  const float* vol;
  int nx, ny, nz, W, H;
  float step, min_t;
  V3 bmin, bmax, inv_h, bg;
  glm::dvec3 box_min, box_max;
  std::vector<reference::PackedCamera> packed;  // for ivr's sample count (docs/integrators.md)
};

// The gradient takes emission–absorption through a piecewise-linear TF; the render also the
// absorption model and the identity TF.
Prepared prepare(const Scene& scene, double step_voxels, bool render_only) {
  const bool pwl = scene.tf.kind == TfKind::piecewise_linear && !scene.tf.points.empty();
  if (!render_only && (scene.model != Model::emission_absorption || !pwl))
    throw std::runtime_error(
        "the native baseline's gradient takes emission_absorption with piecewise_linear only");
  if (!pwl && scene.tf.kind != TfKind::identity)
    throw std::runtime_error("the native baseline renders piecewise_linear and identity TFs only");
  Prepared p;
  p.absorption = scene.model == Model::absorption;
  p.identity = scene.tf.kind == TfKind::identity;
  p.id_a = float(scene.tf.extinction_scale), p.id_b = float(scene.tf.color_scale);
  for (const TfPoint& q : scene.tf.points)
    p.tf.push_back({float(q.density), float(q.color.x), float(q.color.y), float(q.color.z),
                    float(q.extinction)});
  const Volume& vol = scene.volume;
  p.vol = vol.data.data();
  p.nx = vol.nx, p.ny = vol.ny, p.nz = vol.nz;
  const glm::dvec3 h = scene.voxel_size();
  p.step = float(step_voxels * std::min(h.x, std::min(h.y, h.z)));
  p.min_t = float(scene.integrator.min_transmittance);
  p.bmin = v3(scene.box_min), p.bmax = v3(scene.box_max), p.inv_h = v3(1.0 / h);
  p.bg = v3(scene.effective_background());
  p.box_min = scene.box_min, p.box_max = scene.box_max;
  p.W = scene.cameras[0].width, p.H = scene.cameras[0].height;
  for (const Camera& c : scene.cameras) {
    p.packed.push_back(reference::packed_camera(c));
    const glm::dvec3 fwd = glm::normalize(c.target - c.eye),
                     right = glm::normalize(glm::cross(fwd, c.up));
    const glm::dvec3 up = glm::cross(right, fwd);
    const bool ortho = c.projection == Projection::orthographic;
    const double half = ortho ? 0.5 * c.ortho_height : std::tan(0.5 * c.fov_y * M_PI / 180.0);
    p.views.push_back(
        {v3(c.eye), v3(fwd), v3(half * double(p.W) / p.H * right), v3(half * up), ortho});
  }
  return p;
}

inline void slab(float o, float d, float lo, float hi, float& t0, float& t1) {
  if (d != 0) {
    const float inv = 1 / d, ta = (lo - o) * inv, tb = (hi - o) * inv;
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  } else if (o < lo || o > hi) {
    t1 = -1;
  }
}

// A ray inside the box as kernels/march.cl cuts it: n segments of dt from t0, sample i at its
// midpoint t0 + (i + ½)·dt, at voxel coordinates u0 + t·du (voxel centre i at u = i).
struct Ray {
  float t0 = 0, dt = 0;  // set by ray_at where the ray hits the box
  unsigned n = 0;
  V3 u0, du;
};

// The ray through pixel (x, y) of a view (kernels/geometry.cl's camera_ray and clip_box); false
// where it misses the box.
inline bool ray_at(const Prepared& p, int view, int x, int y, Ray& ray) {
  const View& c = p.views[view];
  const float sx = 2.f * (x + 0.5f) / p.W - 1.f, sy = 1.f - 2.f * (y + 0.5f) / p.H;
  V3 origin = c.eye, dir = c.fwd;
  if (c.ortho) {
    origin = c.eye + sx * c.right + sy * c.up;
  } else {
    dir = c.fwd + sx * c.right + sy * c.up;
    dir = (1.f / std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z)) * dir;
  }
  float t0 = 0, t1 = INFINITY;
  slab(origin.x, dir.x, p.bmin.x, p.bmax.x, t0, t1);
  slab(origin.y, dir.y, p.bmin.y, p.bmax.y, t0, t1);
  slab(origin.z, dir.z, p.bmin.z, p.bmax.z, t0, t1);
  // Whether the ray meets the box and its segment count: ivr's definition (docs/integrators.md).
  ray.n = reference::sample_count(p.packed[std::size_t(view)], x, y, p.W, p.H, p.box_min,
                                  p.box_max, p.step);
  if (ray.n == 0) return false;
  if (!(t0 < t1)) t1 = t0;
  const float length = t1 - t0;
  ray.dt = length / float(ray.n);
  ray.t0 = t0;
  ray.u0 = mul(origin - p.bmin, p.inv_h) + V3{-0.5f, -0.5f, -0.5f};
  ray.du = mul(dir, p.inv_h);
  return true;
}

// The cell holding voxel coordinates u, clamped to the edge centres as kernels/geometry.cl's
// trilinear_at: its first voxel, the neighbours' offsets (0 on a clamped upper edge) and the
// fractions. Corner k (bit 0: +x, bit 1: +y, bit 2: +z) is voxel base + corner(k).
struct Cell {
  std::ptrdiff_t base, ox, oy, oz;
  float fx, fy, fz;
  std::ptrdiff_t corner(int k) const {
    return base + ((k & 1) ? ox : 0) + ((k & 2) ? oy : 0) + ((k & 4) ? oz : 0);
  }
};

inline Cell cell_at(const Prepared& p, V3 u) {
  u.x = std::clamp(u.x, 0.f, float(p.nx - 1));
  u.y = std::clamp(u.y, 0.f, float(p.ny - 1));
  u.z = std::clamp(u.z, 0.f, float(p.nz - 1));
  const int x0 = int(u.x), y0 = int(u.y), z0 = int(u.z);
  const std::ptrdiff_t sxy = std::ptrdiff_t(p.nx) * p.ny;
  return {z0 * sxy + std::ptrdiff_t(y0) * p.nx + x0,
          x0 + 1 < p.nx ? 1 : 0,
          y0 + 1 < p.ny ? p.nx : 0,
          z0 + 1 < p.nz ? sxy : 0,
          u.x - x0,
          u.y - y0,
          u.z - z0};
}

inline void load_corners(const float* vol, const Cell& c, float v[8]) {
  for (int k = 0; k < 8; ++k) v[k] = vol[c.corner(k)];
}

// trilinear_at's interpolation of the corners: along x, then y, then z.
inline float interpolate(const float v[8], const Cell& c) {
  return lerp(lerp(lerp(v[0], v[1], c.fx), lerp(v[2], v[3], c.fx), c.fy),
              lerp(lerp(v[4], v[5], c.fx), lerp(v[6], v[7], c.fx), c.fy), c.fz);
}

// The TF around density d as kernels/tf.cl's tf_sample finds it: the segment [d_k, d_k+1) holding
// d, constant at and above the last point and at and below the first (a == b there); b's weight
// w and its slope in d (one-sided at a point, 0 outside). `cursor` is the search's start, carried
// along the ray.
struct TfAt {
  const Point *a, *b;
  float w, dw;
};

inline TfAt tf_at(const std::vector<Point>& tf, float d, int& cursor) {
  const int last = int(tf.size()) - 1;
  if (d >= tf[last].d) return {&tf[last], &tf[last], 0.f, 0.f};
  if (!(d > tf[0].d)) return {&tf[0], &tf[0], 0.f, 0.f};
  int k = cursor;
  while (k > 0 && tf[k].d > d) --k;
  while (tf[k + 1].d <= d) ++k;
  cursor = k;
  const float width = tf[k + 1].d - tf[k].d;
  return {&tf[k], &tf[k + 1], (d - tf[k].d) / width, 1.f / width};
}

// A sample's extinction and premultiplied emission σ·c, as tf_sample computes them.
struct Optics {
  float sigma, er, eg, eb;
};

inline Optics optics(const TfAt& s) {
  const float sigma = lerp(s.a->sigma, s.b->sigma, s.w);
  return {sigma, sigma * lerp(s.a->r, s.b->r, s.w), sigma * lerp(s.a->g, s.b->g, s.w),
          sigma * lerp(s.a->b, s.b->b, s.w)};
}

// kernels/compositing.cl in float32: exp(-x) and the emitted fraction (1 − e^−x)/x, from a series
// and an exp-free decay below 0.1, one exp above; the fraction's slope in x; T·e^−x (one fused
// multiply-add below 0.1).
inline float decay_and_fraction(float x, float& fraction) {
  if (x < 0.1f) {
    fraction = 1.0f - x * (0.5f - x * (1.0f / 6 - x * (1.0f / 24 - x * (1.0f / 120))));
    return 1.0f - x * fraction;
  }
  const float decay = std::exp(-x);
  fraction = (1.0f - decay) / x;
  return decay;
}

inline float fraction_slope(float x, float decay, float fraction) {
  if (x >= 0.1f) return (decay - fraction) / x;
  return -0.5f +
         x * (1.0f / 3 + x * (-1.0f / 8 + x * (1.0f / 30 + x * (-1.0f / 144 + x * (1.0f / 840)))));
}

inline float attenuate(float T, float x, float fraction, float decay) {
  return x < 0.1f ? std::fma(-T, x * fraction, T) : T * decay;
}

// A sample's optics at density d: the piecewise-linear TF (tf_at, carrying the cursor) or the
// identity TF (tf.cl: σ = a·d, E = σ·b·d).
inline Optics sample_optics(const Prepared& p, float d, int& cursor) {
  if (!p.identity) return optics(tf_at(p.tf, d, cursor));
  const float sigma = p.id_a * d, e = sigma * p.id_b * d;
  return {sigma, e, e, e};
}

// What a primal march leaves: the transmittance, the emitted colour (compensated sums), and one
// past the last sample taken.
struct Radiance {
  float T = 1, cr = 0, cg = 0, cb = 0;
  unsigned end = 0;
};

// kernels/primal.cl's midpoint march: stops after the sample that takes T below min_t.
// The absorption model sums the optical depth (compensated) and stops once it passes
// −log(min_t), then T = e^−τ (primal.cl's march_threshold and march_finish).
inline Radiance primal_march(const Prepared& p, const Ray& ray) {
  Radiance r;
  float kr = 0, kg = 0, kb = 0;
  int cursor = 0;
  if (p.absorption) {
    float tau = 0, k = 0;
    const float stop = p.min_t > 0 ? -std::log(p.min_t) : INFINITY;
    for (unsigned i = 0; i < ray.n; ++i) {
      const float t = ray.t0 + (float(i) + 0.5f) * ray.dt;
      const Cell c = cell_at(p, ray.u0 + t * ray.du);
      float v[8];
      load_corners(p.vol, c, v);
      kahan(tau, k, sample_optics(p, interpolate(v, c), cursor).sigma * ray.dt);
      r.end = i + 1;
      if (tau > stop) break;
    }
    r.T = std::exp(-tau);
    return r;
  }
  for (unsigned i = 0; i < ray.n; ++i) {
    const float t = ray.t0 + (float(i) + 0.5f) * ray.dt;
    const Cell c = cell_at(p, ray.u0 + t * ray.du);
    float v[8];
    load_corners(p.vol, c, v);
    const Optics o = sample_optics(p, interpolate(v, c), cursor);
    const float tau = o.sigma * ray.dt;
    float fraction;
    const float decay = decay_and_fraction(tau, fraction);
    const float weight = r.T * ray.dt * fraction;
    kahan(r.cr, kr, weight * o.er);
    kahan(r.cg, kg, weight * o.eg);
    kahan(r.cb, kb, weight * o.eb);
    r.T = attenuate(r.T, tau, fraction, decay);
    r.end = i + 1;
    if (r.T < p.min_t) break;
  }
  return r;
}

// The pixel (over the background) and dL/d pixel, for the adjoint march.
struct PixelAdjoint {
  float total_r, total_g, total_b, t_end;
  float gr, gg, gb, ga;
  unsigned end;
};

// The cell the adjoint march is in: its corners' densities (read once per cell) and the gradient
// gathered for them, added to `grad` when the march leaves the cell.
struct CellCache {
  Cell cell{-1, 0, 0, 0, 0, 0, 0};
  float v[8] = {}, g[8] = {};  // read only once a cell is entered; zero for the compiler

  void enter(const Cell& c, const float* vol, float* grad) {
    if (c.base != cell.base) {
      flush(grad);
      cell = c;
      load_corners(vol, c, v);
      std::fill(g, g + 8, 0.f);
    }
    cell.fx = c.fx, cell.fy = c.fy, cell.fz = c.fz;
  }
  // dL/d density gd at the current fractions, into the corners by their trilinear weights.
  void add(float gd) {
    const float gx0 = gd * (1 - cell.fx), gx1 = gd * cell.fx;
    const float wy0z0 = (1 - cell.fy) * (1 - cell.fz), wy1z0 = cell.fy * (1 - cell.fz);
    const float wy0z1 = (1 - cell.fy) * cell.fz, wy1z1 = cell.fy * cell.fz;
    g[0] += gx0 * wy0z0;
    g[1] += gx1 * wy0z0;
    g[2] += gx0 * wy1z0;
    g[3] += gx1 * wy1z0;
    g[4] += gx0 * wy0z1;
    g[5] += gx1 * wy0z1;
    g[6] += gx0 * wy1z1;
    g[7] += gx1 * wy1z1;
  }
  void flush(float* grad) {
    if (cell.base < 0) return;
    for (int k = 0; k < 8; ++k)
      if (g[k] != 0) grad[cell.corner(k)] += g[k];
  }
};

// kernels/adjoint_midpoint.cl: the primal's samples again, front to back, up to where the primal
// stopped. With C the pixel, p_i the prefix through sample i (summed as the primal summed C),
// w_i = T_i·dt·f(τ_i): ∂C/∂σ_i = T_i·dt²·f'(τ_i)·E_i − dt·(C − p_i), ∂α/∂σ_i = dt·T_end, and
// ∂C/∂E_i = w_i; then through the TF's slope to the density and the trilinear weights to the
// voxels. Returns the samples taken.
unsigned adjoint_march(const Prepared& p, const Ray& ray, const PixelAdjoint& ar, float* grad) {
  float T = 1, pr = 0, pg = 0, pb = 0, kr = 0, kg = 0, kb = 0;
  int cursor = 0;
  const float dt = ray.dt;
  CellCache cache;
  for (unsigned i = 0; i < ar.end; ++i) {
    const float t = ray.t0 + (float(i) + 0.5f) * dt;
    cache.enter(cell_at(p, ray.u0 + t * ray.du), p.vol, grad);
    const TfAt s = tf_at(p.tf, interpolate(cache.v, cache.cell), cursor);
    const Optics o = optics(s);
    const float dsigma = (s.b->sigma - s.a->sigma) * s.dw;
    // E = σ·c: E' = σ'·c + σ·c'
    const float der = dsigma * lerp(s.a->r, s.b->r, s.w) + o.sigma * (s.b->r - s.a->r) * s.dw;
    const float deg = dsigma * lerp(s.a->g, s.b->g, s.w) + o.sigma * (s.b->g - s.a->g) * s.dw;
    const float deb = dsigma * lerp(s.a->b, s.b->b, s.w) + o.sigma * (s.b->b - s.a->b) * s.dw;
    const float tau = o.sigma * dt;
    float fraction;
    const float decay = decay_and_fraction(tau, fraction);
    const float weight = T * dt * fraction;
    kahan(pr, kr, weight * o.er);
    kahan(pg, kg, weight * o.eg);
    kahan(pb, kb, weight * o.eb);
    const float slope = T * dt * dt * fraction_slope(tau, decay, fraction);
    const float gsigma = ar.gr * (slope * o.er - dt * (ar.total_r - pr)) +
                         ar.gg * (slope * o.eg - dt * (ar.total_g - pg)) +
                         ar.gb * (slope * o.eb - dt * (ar.total_b - pb)) + ar.ga * dt * ar.t_end;
    T = attenuate(T, tau, fraction, decay);
    const float gd = gsigma * dsigma + weight * (ar.gr * der + ar.gg * deg + ar.gb * deb);
    cache.add(gd);
  }
  cache.flush(grad);
  return ar.end;
}

}  // namespace

std::size_t native_render(const Scene& scene, double step_voxels, std::vector<float>& image) {
  const Prepared p = prepare(scene, step_voxels, true);
  const int rows = int(p.views.size()) * p.H;
  const int channels = p.absorption ? 1 : 4;
  image.assign(std::size_t(rows) * p.W * channels, 0.f);
  std::size_t total = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : total)
  for (int row = 0; row < rows; ++row) {
    const int view = row / p.H, y = row % p.H;
    for (int x = 0; x < p.W; ++x) {
      Ray ray;
      Radiance r;
      if (ray_at(p, view, x, y, ray)) r = primal_march(p, ray);
      total += r.end;
      float* out = &image[(std::size_t(row) * p.W + x) * channels];
      if (p.absorption) {
        out[0] = p.bg.x * r.T;
        continue;
      }
      out[0] = r.cr + r.T * p.bg.x;
      out[1] = r.cg + r.T * p.bg.y;
      out[2] = r.cb + r.T * p.bg.z;
      out[3] = 1 - r.T;
    }
  }
  return total;
}

std::size_t native_gradient(const Scene& scene, double step_voxels,
                            const std::vector<float>& target, std::vector<float>& grad,
                            double& loss) {
  const Prepared p = prepare(scene, step_voxels, false);
  const int rows = int(p.views.size()) * p.H;
  const std::size_t elements = std::size_t(rows) * p.W * 4;
  if (target.size() != elements)
    throw std::runtime_error("the target's size differs from the image's");
  const std::ptrdiff_t voxels = std::ptrdiff_t(p.nx) * p.ny * p.nz;
  grad.assign(voxels, 0.f);
  const float norm = float(1.0 / double(elements));
  // Thread 0 adds into `grad`, the others into their own copies (first touched by their owner),
  // summed at the end: on 2 threads at 128³ that took ~25 % less time than `omp atomic` adds into
  // one array (a compare-and-swap loop per float add, even with the cell cache's one add per
  // corner and cell visit).
  std::vector<std::vector<float>> copies(omp_get_max_threads());
  double loss_sum = 0;
  std::size_t total = 0;
#pragma omp parallel reduction(+ : loss_sum, total)
  {
    const int id = omp_get_thread_num();
    float* g = grad.data();
    if (id > 0) {
      copies[id].assign(voxels, 0.f);
      g = copies[id].data();
    }
#pragma omp for schedule(dynamic, 4)
    for (int row = 0; row < rows; ++row) {
      const int view = row / p.H, y = row % p.H;
      for (int x = 0; x < p.W; ++x) {
        Ray ray;
        Radiance r;
        const bool hit = ray_at(p, view, x, y, ray);
        if (hit) r = primal_march(p, ray);
        // The pixel, its loss terms and dL/d pixel (kernels/loss.cl: mean squared error).
        const float value[4] = {r.cr + r.T * p.bg.x, r.cg + r.T * p.bg.y, r.cb + r.T * p.bg.z,
                                1 - r.T};
        const float* tgt = &target[(std::size_t(row) * p.W + x) * 4];
        float gp[4], pixel_loss = 0;
        for (int c = 0; c < 4; ++c) {
          const float diff = value[c] - tgt[c];
          pixel_loss += diff * diff * norm;
          gp[c] = 2 * diff * norm;
        }
        loss_sum += double(pixel_loss);
        if (hit) {
          const PixelAdjoint ar{value[0], value[1], value[2], r.T,  gp[0],
                                gp[1],    gp[2],    gp[3],    r.end};
          total += adjoint_march(p, ray, ar, g);
        }
      }
    }
  }
  std::vector<const float*> others;
  for (const std::vector<float>& c : copies)
    if (!c.empty()) others.push_back(c.data());
  if (!others.empty()) {
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < voxels; ++i) {
      float sum = grad[i];
      for (const float* c : others) sum += c[i];
      grad[i] = sum;
    }
  }
  loss = loss_sum;
  return total;
}

}  // namespace ivr::bench
