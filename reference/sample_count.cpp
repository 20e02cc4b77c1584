// sample_count.cpp — ivr's sample count (docs/integrators.md) on the host, operation for operation as
// kernels/sample_count.cl: float32 inputs, products summed only through std::fma (so no compiler
// contraction can change a bit), correctly rounded division and sqrt.
#include "reference/sample_count.hpp"

// The sums of products are explicit std::fma; nothing else may be fused, whatever -march says.
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

namespace ivr::reference {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Of c and its neighbours, the one with the smallest |residual| (kernels/sample_count.cl's
// IVR_NEAREST_OF_THREE), twice.
template <class Residual>
float nearest_of_three(float c, Residual residual) {
  for (int pass = 0; pass < 2; ++pass) {
    const float lo = std::nextafter(c, -kInf), hi = std::nextafter(c, kInf);
    const float rc = std::fabs(residual(c)), rl = std::fabs(residual(lo)),
                rh = std::fabs(residual(hi));
    if (rl < rc && rl <= rh)
      c = lo;
    else if (rh < rc)
      c = hi;
    else
      break;
  }
  return c;
}

}  // namespace

float count_divide(float a, float b, CountArithmetic kind) {
  if (kind == CountArithmetic::correctly_rounded) return a / b;  // IEEE binary32
  const float q = std::nextafter(a / b, kInf);
  if (kind == CountArithmetic::one_ulp_high || b == 0.f || !std::isfinite(q) || q == 0.f) return q;
  return nearest_of_three(q, [&](float c) { return std::fma(-c, b, a); });
}

float count_sqrt(float a, CountArithmetic kind) {
  if (kind == CountArithmetic::correctly_rounded) return std::sqrt(a);
  const float s = std::nextafter(std::sqrt(a), kInf);
  if (kind == CountArithmetic::one_ulp_high || !(a > 0.f) || !std::isfinite(s)) return s;
  return nearest_of_three(s, [&](float c) { return std::fma(-c, c, a); });
}

namespace {

void slab(CountArithmetic ar, float o, float d, float lo, float hi, float* t0, float* t1) {
  if (d != 0.f) {
    const float ta = count_divide(lo - o, d, ar), tb = count_divide(hi - o, d, ar);
    const float enter = ta < tb ? ta : tb, leave = ta < tb ? tb : ta;
    if (enter > *t0) *t0 = enter;
    if (leave < *t1) *t1 = leave;
  } else if (o < lo || o > hi) {
    *t1 = -1.f;
  }
}

}  // namespace

PackedCamera packed_camera(const ivr::Camera& c) {
  // docs/design.md's camera basis, in double as the library packs it, then rounded once.
  const glm::dvec3 fwd = glm::normalize(c.target - c.eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, c.up));
  const glm::dvec3 up = glm::cross(right, fwd);
  const double aspect = double(c.width) / double(c.height);
  const bool ortho = c.projection == ivr::Projection::orthographic;
  const double half = ortho ? 0.5 * c.ortho_height : std::tan(0.5 * c.fov_y * M_PI / 180.0);
  const glm::dvec3 r = half * aspect * right, u = half * up;
  const double v[13] = {c.eye.x, c.eye.y, c.eye.z, fwd.x, fwd.y, fwd.z, r.x,
                        r.y,     r.z,     u.x,     u.y,   u.z,   ortho ? 1.0 : 0.0};
  PackedCamera out;
  for (int k = 0; k < 13; ++k) out[k] = float(v[k]);
  return out;
}

unsigned sample_count(const PackedCamera& cam, int x, int y, int width, int height,
                      const glm::dvec3& box_min, const glm::dvec3& box_max, double step_world,
                      CountArithmetic arithmetic) {
  const CountArithmetic ar = arithmetic;
  const float sx = count_divide(float(2 * x + 1 - width), float(width), ar);
  const float sy = count_divide(float(height - 2 * y - 1), float(height), ar);
  const bool ortho = cam[12] != 0.f;
  float o[3], d[3];
  for (int k = 0; k < 3; ++k) {
    const float eye = cam[k], fwd = cam[3 + k], right = cam[6 + k], up = cam[9 + k];
    o[k] = ortho ? std::fma(sy, up, std::fma(sx, right, eye)) : eye;
    d[k] = ortho ? fwd : std::fma(sy, up, std::fma(sx, right, fwd));
  }
  if (!ortho) {
    const float dz2 = d[2] * d[2];
    const float norm = count_sqrt(std::fma(d[0], d[0], std::fma(d[1], d[1], dz2)), ar);
    for (float& dk : d) dk = count_divide(dk, norm, ar);
  }
  float t0 = 0.f, t1 = kInf;
  for (int k = 0; k < 3; ++k) slab(ar, o[k], d[k], float(box_min[k]), float(box_max[k]), &t0, &t1);
  if (!(t0 < t1)) return 0;
  const float q = count_divide(t1 - t0, float(step_world), ar);
  return q < 4294967040.f ? std::max(1u, unsigned(std::ceil(q))) : 4294967040u;
}

unsigned ray_sample_count(const double* ray, const glm::dvec3& box_min, const glm::dvec3& box_max,
                          double step_world) {
  const CountArithmetic ar = CountArithmetic::correctly_rounded;
  float t0 = float(ray[6]), t1 = float(ray[7]);
  for (int k = 0; k < 3; ++k)
    slab(ar, float(ray[k]), float(ray[3 + k]), float(box_min[k]), float(box_max[k]), &t0, &t1);
  if (!(t0 < t1)) return 0;
  const float q = count_divide(t1 - t0, float(step_world), ar);
  return q < 4294967040.f ? std::max(1u, unsigned(std::ceil(q))) : 4294967040u;
}

unsigned sample_count(const ivr::Scene& scene, int view, int x, int y, double step_world) {
  const ivr::Camera& c = scene.cameras[std::size_t(view)];
  return sample_count(packed_camera(c), x, y, c.width, c.height, scene.box_min, scene.box_max,
                      step_world);
}

}  // namespace ivr::reference
