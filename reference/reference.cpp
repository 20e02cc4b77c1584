// reference.cpp — the double-precision CPU reference: written from docs/design.md alone, sharing no
// code with kernels/*.cl or lib/render/render.cpp, so that agreement between the two means something.
#include "reference/reference.hpp"
#include "reference/sample_count.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <glm/geometric.hpp>
#include <limits>
#include <stdexcept>
#include <thread>

namespace ivr::reference {
namespace {

constexpr double kPi = 3.14159265358979323846;

double lerp(double a, double b, double w) {
  return a + (b - a) * w;
}

}  // namespace

double min_voxel_edge(const ivr::Scene& scene) {
  const glm::dvec3 h = (scene.box_max - scene.box_min) /
                       glm::dvec3(scene.volume.nx, scene.volume.ny, scene.volume.nz);
  return std::min(h.x, std::min(h.y, h.z));
}

double density(const ivr::Scene& scene, glm::dvec3 p) {
  const ivr::Volume& v = scene.volume;
  for (int a = 0; a < 3; ++a)
    if (!(p[a] >= scene.box_min[a] && p[a] <= scene.box_max[a])) return 0.0;
  const int n[3] = {v.nx, v.ny, v.nz};
  int i0[3], i1[3];
  double w[3];
  for (int a = 0; a < 3; ++a) {
    const double h = (scene.box_max[a] - scene.box_min[a]) / n[a];
    // Continuous index with centres at integers; the border half-voxel clamps to the edge centre.
    double u = (p[a] - scene.box_min[a]) / h - 0.5;
    u = std::min(std::max(u, 0.0), double(n[a] - 1));
    const double f = std::floor(u);
    i0[a] = int(f);
    i1[a] = std::min(i0[a] + 1, n[a] - 1);
    w[a] = u - f;
  }
  double sum = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const int bx = corner & 1, by = (corner >> 1) & 1, bz = (corner >> 2) & 1;
    const double weight = (bx ? w[0] : 1 - w[0]) * (by ? w[1] : 1 - w[1]) * (bz ? w[2] : 1 - w[2]);
    if (weight == 0) continue;
    sum += weight * double(v.at(bx ? i1[0] : i0[0], by ? i1[1] : i0[1], bz ? i1[2] : i0[2]));
  }
  return sum;
}

void ray(const ivr::Camera& c, int x, int y, glm::dvec3* origin, glm::dvec3* dir) {
  const glm::dvec3 forward = glm::normalize(c.target - c.eye);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
  const glm::dvec3 up = glm::cross(right, forward);
  const double aspect = double(c.width) / double(c.height);
  const double sx = 2.0 * (x + 0.5) / c.width - 1.0;
  const double sy = 1.0 - 2.0 * (y + 0.5) / c.height;
  if (c.projection == ivr::Projection::orthographic) {
    const double half = c.ortho_height / 2;
    *origin = c.eye + sx * half * aspect * right + sy * half * up;
    *dir = forward;
  } else {
    const double t = std::tan(c.fov_y * kPi / 360.0);
    *origin = c.eye;
    *dir = glm::normalize(forward + sx * t * aspect * right + sy * t * up);
  }
}

TfSample transfer(const ivr::TransferFunction& tf, double d) {
  TfSample s;
  switch (tf.kind) {
    case ivr::TfKind::identity:
      s.sigma = tf.extinction_scale * d;
      s.emission = glm::dvec3(s.sigma * tf.color_scale * d);
      break;
    case ivr::TfKind::piecewise_linear: {
      const auto& p = tf.points;
      if (p.empty()) break;
      glm::dvec3 colour;
      if (d <= p.front().density) {
        colour = p.front().color;
        s.sigma = p.front().extinction;
      } else if (d >= p.back().density) {
        colour = p.back().color;
        s.sigma = p.back().extinction;
      } else {
        // p[i].density <= d < p[i+1].density, so the interval has positive width.
        std::size_t i = 0;
        while (!(d < p[i + 1].density)) ++i;
        const double w = (d - p[i].density) / (p[i + 1].density - p[i].density);
        colour = p[i].color + (p[i + 1].color - p[i].color) * w;
        s.sigma = lerp(p[i].extinction, p[i + 1].extinction, w);
      }
      s.emission = s.sigma * colour;
      break;
    }
    case ivr::TfKind::table: {
      const auto& e = tf.entries;
      if (e.empty()) break;
      const int r = int(e.size());
      double u = r == 1 ? 0.0 : (d - tf.range.x) / (tf.range.y - tf.range.x) * (r - 1);
      u = std::min(std::max(u, 0.0), double(r - 1));
      const int i = std::min(int(std::floor(u)), r - 1);
      const int j = std::min(i + 1, r - 1);
      const double w = u - i;
      const glm::dvec4 row = e[i] + (e[j] - e[i]) * w;
      s.sigma = row.w;
      s.emission = s.sigma * glm::dvec3(row.x, row.y, row.z);
      break;
    }
    case ivr::TfKind::gaussian:
      for (const auto& g : tf.gaussians) {
        const double z = (d - g.mean) / g.width;
        const double eg = g.extinction * std::exp(-0.5 * z * z);
        s.sigma += eg;
        s.emission += eg * g.color;
      }
      break;
  }
  return s;
}

bool clip_to_box(const glm::dvec3& lo, const glm::dvec3& hi, const glm::dvec3& o,
                 const glm::dvec3& d, double* t0, double* t1, double from, double to) {
  double a = from, b = to;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if (o[k] < lo[k] || o[k] > hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - o[k]) / d[k], tb = (hi[k] - o[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    a = std::max(a, ta);
    b = std::min(b, tb);
  }
  if (!(a < b)) return false;
  *t0 = a;
  *t1 = b;
  return true;
}

std::vector<double> centre_plane_cuts(const ivr::Scene& scene, const glm::dvec3& o,
                                      const glm::dvec3& dir, double t0, double t1) {
  std::vector<double> cuts{t0, t1};
  const int n[3] = {scene.volume.nx, scene.volume.ny, scene.volume.nz};
  for (int a = 0; a < 3; ++a) {
    if (dir[a] == 0.0) continue;
    const double h = (scene.box_max[a] - scene.box_min[a]) / n[a];
    for (int i = 0; i < n[a]; ++i) {
      const double t = (scene.box_min[a] + (i + 0.5) * h - o[a]) / dir[a];
      if (t > t0 && t < t1) cuts.push_back(t);
    }
  }
  std::sort(cuts.begin(), cuts.end());
  return cuts;
}

namespace {

// Integrates one ray. The interval is split where the ray crosses a plane through voxel centres:
// between those the trilinear density is a cubic in t, so the midpoint rule sees a smooth
// integrand on every piece (TF kinks aside) and converges cleanly at second order.
void integrate_ray(const ivr::Scene& scene, const glm::dvec3& o, const glm::dvec3& dir, double lo,
                   double hi, double step, bool early, double* out) {
  const bool ea = scene.model == ivr::Model::emission_absorption;
  const glm::dvec3 bg = scene.effective_background();
  double t0, t1;
  if (!clip_to_box(scene.box_min, scene.box_max, o, dir, &t0, &t1, lo, hi)) {
    if (ea) {
      out[0] = bg.x, out[1] = bg.y, out[2] = bg.z, out[3] = 0.0;
    } else {
      out[0] = bg.x;
    }
    return;
  }
  const std::vector<double> cuts = centre_plane_cuts(scene, o, dir, t0, t1);

  const double t_min = early ? scene.integrator.min_transmittance : 0.0;
  double tau = 0.0;
  glm::dvec3 radiance(0.0);
  bool stop = false;
  for (std::size_t p = 0; p + 1 < cuts.size() && !stop; ++p) {
    const double len = cuts[p + 1] - cuts[p];
    if (len <= 0) continue;
    // The slack keeps a piece that is an exact multiple of the step from gaining a sliver.
    const long m = std::max(1L, long(std::ceil(len / step * (1 - 1e-12))));
    const double dt = len / double(m);
    for (long i = 0; i < m; ++i) {
      const double t = cuts[p] + (i + 0.5) * dt;
      const TfSample s = transfer(scene.tf, density(scene, o + t * dir));
      if (ea) radiance += std::exp(-(tau + 0.5 * s.sigma * dt)) * s.emission * dt;
      tau += s.sigma * dt;
      if (t_min > 0 && std::exp(-tau) < t_min) {
        stop = true;
        break;
      }
    }
  }
  const double transmittance = std::exp(-tau);
  if (ea) {
    const glm::dvec3 c = radiance + transmittance * bg;
    out[0] = c.x, out[1] = c.y, out[2] = c.z, out[3] = 1.0 - transmittance;
  } else {
    out[0] = bg.x * transmittance;  // I_in = background (one value for absorption)
  }
}

// The midpoint rule of docs/design.md's `midpoint` integrator itself: [t0, t1] cut into n equal
// segments (the sample count, sample_count.hpp; 0: the ray misses the box), σ and c at each
// midpoint, exact compositing of each segment (C += T·(1 − e^{−σΔ})·c, T ·= e^{−σΔ}); with `early` the ray stops after the sample
// that takes T below min_transmittance.
void march_midpoint(const ivr::Scene& scene, const glm::dvec3& o, const glm::dvec3& dir, double lo,
                    double hi, unsigned n, bool early, double* out) {
  const bool ea = scene.model == ivr::Model::emission_absorption;
  const glm::dvec3 bg = scene.effective_background();
  double t0, t1, transmittance = 1.0;
  glm::dvec3 radiance(0.0);
  if (n > 0 && clip_to_box(scene.box_min, scene.box_max, o, dir, &t0, &t1, lo, hi)) {
    const double dt = (t1 - t0) / double(n);
    for (unsigned i = 0; i < n; ++i) {
      const TfSample s = transfer(scene.tf, density(scene, o + (t0 + (i + 0.5) * dt) * dir));
      const double decay = std::exp(-s.sigma * dt);
      // emission = c·σ: the segment's share T·(1 − e^{−σΔ})·c (σ = 0: no emission either).
      if (ea && s.sigma > 0) radiance += transmittance * (1.0 - decay) * (s.emission / s.sigma);
      transmittance *= decay;
      if (early && transmittance < scene.integrator.min_transmittance) break;
    }
  }
  if (ea) {
    const glm::dvec3 c = radiance + transmittance * bg;
    out[0] = c.x, out[1] = c.y, out[2] = c.z, out[3] = 1.0 - transmittance;
  } else {
    out[0] = bg.x * transmittance;
  }
}

template <class Integrate>
std::vector<double> render_rows(const ivr::Scene& scene, Integrate&& integrate) {
  if (scene.has_ray_list()) {  // one value (or four) per ray, in order
    const std::size_t n = scene.rays.count(), c = std::size_t(scene.channels());
    std::vector<double> image(n * c);
    auto work = [&](std::size_t first, std::size_t stride) {
      for (std::size_t i = first; i < n; i += stride) {
        const double* q = scene.rays.values.data() + i * ivr::RayList::kColumns;
        integrate(glm::dvec3(q[0], q[1], q[2]), glm::dvec3(q[3], q[4], q[5]), q[6], q[7],
                  Pixel{0, int(i), 0}, &image[i * c]);
      }
    };
    std::thread other(work, 1, 2);
    work(0, 2);
    other.join();
    return image;
  }
  if (scene.cameras.empty()) return {};
  const int w = scene.cameras[0].width, h = scene.cameras[0].height, c = scene.channels();
  const int views = int(scene.cameras.size());
  std::vector<double> image(std::size_t(views) * h * w * c);
  const int rows = views * h;
  auto work = [&](int first, int stride) {
    for (int r = first; r < rows; r += stride) {
      const int v = r / h, y = r % h;
      for (int x = 0; x < w; ++x) {
        glm::dvec3 o, d;
        ray(scene.cameras[v], x, y, &o, &d);
        integrate(o, d, 0.0, std::numeric_limits<double>::infinity(), Pixel{v, x, y},
                  &image[((std::size_t(v) * h + y) * w + x) * c]);
      }
    }
  };
  // Rows interleaved over two threads: the machine has two cores and fine steps are costly.
  std::thread other(work, 1, 2);
  work(0, 2);
  other.join();
  return image;
}

}  // namespace

std::vector<double> render_midpoint(const ivr::Scene& scene, double step_world,
                                    bool early_termination) {
  if (!(step_world > 0))
    throw std::invalid_argument("reference::render_midpoint: step must be > 0");
  return render_rows(scene, [&](const glm::dvec3& o, const glm::dvec3& d, double lo, double hi,
                                Pixel p, double* out) {
    const unsigned n =
        scene.has_ray_list()
            ? ray_sample_count(scene.rays.values.data() + std::size_t(p.x) * ivr::RayList::kColumns,
                               scene.box_min, scene.box_max, step_world)
            : sample_count(scene, p.view, p.x, p.y, step_world);
    march_midpoint(scene, o, d, lo, hi, n, early_termination, out);
  });
}

std::vector<double> render(const ivr::Scene& scene, double step_world, bool early_termination) {
  if (!(step_world > 0)) throw std::invalid_argument("reference::render: step must be > 0");
  return render_rows(scene, [&](const glm::dvec3& o, const glm::dvec3& d, double lo, double hi,
                                Pixel, double* out) {
    integrate_ray(scene, o, d, lo, hi, step_world, early_termination, out);
  });
}

}  // namespace ivr::reference
