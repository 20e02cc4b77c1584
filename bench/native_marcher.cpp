// native_marcher.cpp — plain C++/OpenMP float32 ray marcher: the native CPU limit ivr is measured
// against (same camera, clipping, trilinear, piecewise-linear TF and compositing as the kernel).
#include "native_marcher.hpp"

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

struct Point {
  float d, r, g, b, sigma;
};

inline void slab(float o, float d, float lo, float hi, float& t0, float& t1) {
  if (d != 0) {
    const float inv = 1 / d, ta = (lo - o) * inv, tb = (hi - o) * inv;
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  } else if (o < lo || o > hi) {
    t1 = -1;
  }
}

inline void kahan(float& sum, float& error, float x) {
  const float y = x - error, t = sum + y;
  error = (t - sum) - y;
  sum = t;
}

inline float lerp(float a, float b, float t) {
  return a + (b - a) * t;
}

// As kernels/geometry.cl's trilinear_at: clamped to the edge centres, one base address and the
// neighbours' offsets (0 on the clamped upper edge).
inline float trilinear(const float* vol, int nx, int ny, int nz, V3 u) {
  u.x = std::clamp(u.x, 0.f, float(nx - 1));
  u.y = std::clamp(u.y, 0.f, float(ny - 1));
  u.z = std::clamp(u.z, 0.f, float(nz - 1));
  const int x0 = int(u.x), y0 = int(u.y), z0 = int(u.z);
  const float fx = u.x - x0, fy = u.y - y0, fz = u.z - z0;
  const std::ptrdiff_t sxy = std::ptrdiff_t(nx) * ny;
  const std::ptrdiff_t ox = x0 + 1 < nx ? 1 : 0, oy = y0 + 1 < ny ? nx : 0,
                       oz = z0 + 1 < nz ? sxy : 0;
  const float* p = vol + (z0 * sxy + std::ptrdiff_t(y0) * nx + x0);
  const float c00 = lerp(p[0], p[ox], fx), c10 = lerp(p[oy], p[oy + ox], fx);
  const float c01 = lerp(p[oz], p[oz + ox], fx), c11 = lerp(p[oz + oy], p[oz + oy + ox], fx);
  return lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz);
}

}  // namespace

std::size_t native_render(const Scene& scene, double step_voxels, std::vector<float>& image) {
  if (scene.model != Model::emission_absorption || scene.tf.kind != TfKind::piecewise_linear)
    throw std::runtime_error(
        "the native baseline renders emission_absorption with piecewise_linear only");
  std::vector<Point> tf;
  for (const TfPoint& p : scene.tf.points)
    tf.push_back({float(p.density), float(p.color.x), float(p.color.y), float(p.color.z),
                  float(p.extinction)});
  const int n_points = int(tf.size());
  const Volume& vol = scene.volume;
  const glm::dvec3 h = scene.voxel_size();
  const float step = float(step_voxels * std::min(h.x, std::min(h.y, h.z)));
  const V3 bmin = v3(scene.box_min), bmax = v3(scene.box_max), inv_h = v3(1.0 / h);
  const V3 bg = v3(scene.effective_background());
  const float min_t = float(scene.integrator.min_transmittance);
  const int W = scene.cameras[0].width, H = scene.cameras[0].height,
            views = int(scene.cameras.size());
  image.assign(std::size_t(views) * W * H * 4, 0.f);
  std::size_t total = 0;

  for (int v = 0; v < views; ++v) {
    const Camera& c = scene.cameras[v];
    const glm::dvec3 fwd = glm::normalize(c.target - c.eye),
                     right = glm::normalize(glm::cross(fwd, c.up));
    const glm::dvec3 up = glm::cross(right, fwd);
    const double half = std::tan(0.5 * c.fov_y * M_PI / 180.0);
    const V3 eye = v3(c.eye), f = v3(fwd), r = v3(half * double(W) / H * right), u = v3(half * up);
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : total)
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        const float sx = 2.f * (x + 0.5f) / W - 1.f, sy = 1.f - 2.f * (y + 0.5f) / H;
        V3 dir = f + sx * r + sy * u;
        dir = (1.f / std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z)) * dir;
        float t0 = 0, t1 = INFINITY;
        slab(eye.x, dir.x, bmin.x, bmax.x, t0, t1);
        slab(eye.y, dir.y, bmin.y, bmax.y, t0, t1);
        slab(eye.z, dir.z, bmin.z, bmax.z, t0, t1);
        float T = 1, cr = 0, cg = 0, cb = 0, kr = 0, kg = 0, kb = 0;
        if (t0 < t1) {
          const float length = t1 - t0;
          const unsigned n = std::max(1u, unsigned(std::ceil(length / step)));
          const float dt = length / float(n);
          const V3 u0 = mul(eye - bmin, inv_h) + V3{-0.5f, -0.5f, -0.5f}, du = mul(dir, inv_h);
          int segment = 0;  // the TF search's cursor, carried along the ray as in kernels/tf.cl
          for (unsigned i = 0; i < n; ++i) {
            const float t = t0 + (float(i) + 0.5f) * dt;
            const float d = trilinear(vol.data.data(), vol.nx, vol.ny, vol.nz, u0 + t * du);
            const Point* a = &tf[0];
            const Point* b = &tf[0];
            float w = 0;
            if (d >= tf[n_points - 1].d) {
              a = b = &tf[n_points - 1];
            } else if (d > tf[0].d) {
              int k = segment;
              while (k > 0 && tf[k].d > d) --k;
              while (tf[k + 1].d <= d) ++k;
              segment = k;
              a = &tf[k];
              b = &tf[k + 1];
              w = (d - a->d) / (b->d - a->d);
            }
            const float sigma = lerp(a->sigma, b->sigma, w);
            const float tau = sigma * dt;
            // The kernel's float32 arithmetic (kernels/render.cl, decay_and_fraction): a series and
            // exp(-tau) = 1 - tau·frac below 0.1, one exp above.
            float decay, frac;
            if (tau < 0.1f) {
              frac =
                  1.0f - tau * (0.5f - tau * (1.0f / 6 - tau * (1.0f / 24 - tau * (1.0f / 120))));
              decay = 1.0f - tau * frac;
            } else {
              decay = std::exp(-tau);
              frac = (1.0f - decay) / tau;
            }
            const float k = T * dt * frac * sigma;
            // Compensated sums and a fused-multiply-add attenuation, as kernels/compositing.cl.
            kahan(cr, kr, k * lerp(a->r, b->r, w));
            kahan(cg, kg, k * lerp(a->g, b->g, w));
            kahan(cb, kb, k * lerp(a->b, b->b, w));
            T = tau < 0.1f ? std::fma(-T, tau * frac, T) : T * decay;
            ++total;
            if (T < min_t) break;
          }
        }
        float* out = &image[((std::size_t(v) * H + y) * W + x) * 4];
        out[0] = cr + T * bg.x;
        out[1] = cg + T * bg.y;
        out[2] = cb + T * bg.z;
        out[3] = 1 - T;
      }
    }
  }
  return total;
}

}  // namespace ivr::bench
