// stability.cpp — the stability suite: docs/design.md's hard cases (near-opaque walls and media,
// 1e5 samples per ray, rays grazing faces and edges, axis-aligned rays, a camera inside, one-voxel
// and anisotropic volumes, density jumps and TF kinks, an all-zero volume) through every
// integrator and both models: the forward error against the continuous float64 reference
// (reference/), the float32 gradient's error against the float64 one (density, TF, background;
// the measure of docs/design.md's DiffDVR experiment), with the render and gradient times.
// Checked before timing: no NaN or Inf in any image or gradient (the contract on hard cases).
#include <algorithm>
#include <cmath>
#include <random>

#include "../accuracy_suite.hpp"
#include "../runner/suite.hpp"
#include "reference/reference.hpp"

namespace ivr::bench {

namespace {

struct HardCase {
  std::string name, what;
  Scene scene;
  double step;  // voxels
};

Camera camera(glm::dvec3 eye, int size, double fov = 30) {
  Camera c;
  c.eye = eye;
  c.width = c.height = size;
  c.fov_y = fov;
  return c;
}

Camera ortho(glm::dvec3 eye, glm::dvec3 target, glm::dvec3 up, int size, double height) {
  Camera c;
  c.eye = eye;
  c.target = target;
  c.up = up;
  c.projection = Projection::orthographic;
  c.ortho_height = height;
  c.width = c.height = size;
  return c;
}

// A smooth medium of n³ voxels (values in [lo, hi]) under a three-point TF scaled by `extinction`.
Scene medium(int n, double lo, double hi, double extinction, unsigned seed = 11) {
  Scene s;
  s.volume.nx = s.volume.ny = s.volume.nz = n;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> phase(0, 6.28);
  const double a = phase(rng), b = phase(rng), c = phase(rng);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const double v = 0.5 + 0.25 * std::sin(0.9 * x + a) * std::cos(0.7 * y + b) +
                         0.25 * std::sin(0.8 * z + c);
        s.volume.data.push_back(float(lo + (hi - lo) * v));
      }
  set_default_box(s);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.1, 0.2, 0.3}, 0.1 * extinction},
                 {0.25, {0.9, 0.6, 0.2}, 1.0 * extinction},
                 {1.5, {0.3, 0.8, 1.0}, 3.0 * extinction}};
  s.background = glm::dvec3(0.3, 0.5, 0.7);
  s.cameras = {camera({0.3, 0.25, 2.0}, 12, 25)};
  s.integrator.min_transmittance = 0;
  return s;
}

std::vector<HardCase> hard_cases() {
  std::vector<HardCase> out;
  {  // A wall two voxels thick: σΔ = 100 per sample at step 0.5 (h = 1/8).
    Scene s = medium(8, 0.05, 0.2, 4.0);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        for (int z : {3, 4}) s.volume.data[(std::size_t(z) * 8 + y) * 8 + x] = 1.f;
    s.tf.points[2].extinction = 4.0 + (100 / (0.5 / 8) - 4.0) / 0.6;  // σ(1)·Δ = 100
    out.push_back({"opaque_wall", "σΔ = 100 in a wall two voxels thick", s, 0.5});
  }
  {  // Total optical depth ~1e3 along the rays.
    Scene s = medium(8, 0.1, 0.9, 150.0);
    out.push_back({"depth_1e3", "smooth medium, optical depth ~1e3 per ray", s, 0.25});
  }
  {  // >= 1e5 samples per ray.
    Scene s = medium(6, 0.1, 0.9, 1.0);
    s.cameras = {camera({0.1, 0.05, 2.0}, 4, 10)};
    out.push_back({"tiny_steps", ">= 1e5 samples per ray", s, 6.0 / 1e5 * 0.9});
  }
  {  // Rays grazing the +x face (1e-6 inside and outside) and the +x+y edge.
    Scene s = medium(8, 0.1, 0.9, 3.0);
    s.cameras = {ortho({0.5 - 1e-6, 0, 2}, {0.5 - 1e-6, 0, 0}, {0, 1, 0}, 8, 0.3),
                 ortho({0.5 + 1e-6, 0, 2}, {0.5 + 1e-6, 0, 0}, {0, 1, 0}, 8, 0.3),
                 camera({1.6, 1.6, 0.3}, 8, 6)};
    s.cameras[2].target = {0.5, 0.5, 0};
    out.push_back({"grazing", "rays 1e-6 inside/outside a face, and across an edge", s, 0.5});
  }
  {  // Rays along the axes from three sides, orthographic and perspective.
    Scene s = medium(7, 0.1, 0.9, 3.0);
    s.cameras = {ortho({2, 0, 0}, {0, 0, 0}, {0, 1, 0}, 7, 0.5),
                 ortho({0, 2, 0}, {0, 0, 0}, {0, 0, 1}, 7, 0.5), camera({0, 0, 2}, 7, 10)};
    out.push_back({"axis_aligned", "rays along the axes (and along centre planes)", s, 0.23});
  }
  {  // Camera inside the volume.
    Scene s = medium(7, 0.1, 0.9, 3.0);
    s.cameras = {camera({0.1, -0.05, 0.15}, 12, 60)};
    s.cameras[0].target = {-0.3, 0.1, -1};
    out.push_back({"camera_inside", "the eye inside the box", s, 0.3});
  }
  {  // One voxel in an anisotropic box.
    Scene s = medium(1, 0.6, 0.6, 3.0);
    s.box_min = {-0.2, -0.5, -0.1};
    s.box_max = {0.3, 0.4, 0.6};
    s.cameras = {camera({0.6, 0.4, 2.0}, 12, 35)};
    out.push_back({"one_voxel", "a single voxel in an anisotropic box", s, 0.3});
  }
  {  // Anisotropic volume and spacing.
    Scene s = medium(8, 0.1, 0.9, 3.0);
    s.volume = Volume{};
    s.volume.nx = 11, s.volume.ny = 5, s.volume.nz = 7;
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.1f, 0.9f);
    for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) s.volume.data.push_back(u(rng));
    s.volume.spacing = {1.0, 2.5, 0.6};
    set_default_box(s);
    s.cameras = {camera({1.2, 0.8, 1.5}, 12, 35)};
    out.push_back({"anisotropic", "11x5x7 voxels of spacing (1, 2.5, 0.6), random data", s, 0.4});
  }
  {  // A half-empty volume with a dense block and a hot voxel, through a TF with a jump and kinks.
    Scene s = medium(10, 0.0, 0.0, 1.0);
    for (int z = 0; z < 10; ++z)
      for (int y = 0; y < 10; ++y)
        for (int x = 0; x < 10; ++x) {
          float& d = s.volume.data[(std::size_t(z) * 10 + y) * 10 + x];
          d = x >= 5 ? 0.7f : 0.f;
          if (x == 2 && y == 5 && z == 5) d = 1.f;
        }
    s.tf.points = {{0.0, {0, 0, 0}, 0},      {0.3, {0.2, 0.4, 1}, 2}, {0.3, {0.9, 0.3, 0.1}, 15},
                   {0.6, {1, 0.8, 0.2}, 30}, {0.8, {1, 1, 1}, 8},     {1.0, {1, 1, 1}, 40}};
    s.cameras = {camera({1.4, 0.6, 1.2}, 12, 40)};
    out.push_back({"jumps_kinks", "density jumps, a hot voxel, a TF jump and kinks", s, 0.3});
  }
  {  // All zero.
    Scene s = medium(6, 0.0, 0.0, 3.0);
    s.tf.points[0].extinction = 0;
    out.push_back({"all_zero", "every voxel 0 (σ(0) = 0): the background exactly", s, 0.5});
  }
  return out;
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

// max |a − b| / max |b| (0 for two zero vectors), and the count of non-finite elements of a.
double relative_to_largest(const std::vector<double>& a, const std::vector<double>& b,
                           std::size_t* bad) {
  double e = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!std::isfinite(a[i])) ++*bad;
    e = std::max(e, std::abs(a[i] - b[i]));
  }
  const double s = max_abs(b);
  return s > 0 ? e / s : (e > 0 ? INFINITY : 0.0);
}

// Absorption images of the opaque cases would underflow float32 (I ~ e^−1000): their
// extinctions are scaled to an optical depth of at most 60 per ray.
void limit_absorption_depth(Scene& s) {
  s.background = glm::dvec3(1.0);
  double depth = 0;
  for (const Camera& c : s.cameras)
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        glm::dvec3 o, d;
        reference::ray(c, x, y, &o, &d);
        depth = std::max(depth, reference::optical_depth(s, o, d));
      }
  if (depth > 60)
    for (TfPoint& p : s.tf.points) p.extinction *= 60 / depth;
}

Check finite_check(std::size_t bad) {
  return Check{bad == 0, "finiteness", "non-finite values", double(bad), 0};
}

void hard_case(Context& ctx, const HardCase& hc, Model model, Scheme scheme) {
  Scene s = hc.scene;
  s.model = model;
  s.integrator.scheme = scheme;
  if (model == Model::absorption) limit_absorption_depth(s);
  const std::string name = hc.name + "_" +
                           (model == Model::absorption ? "absorption" : "emission_absorption") +
                           "_" + scheme_name(scheme);
  const nlohmann::json params = {
      {"case", hc.name},
      {"what", hc.what},
      {"integrator", scheme_name(scheme)},
      {"model", model == Model::absorption ? "absorption" : "emission_absorption"},
      {"step", hc.step}};

  // The render against the continuous float64 reference.
  const std::vector<double> expected = reference::render_continuous(s);
  RenderStats stats;
  Image image;
  std::size_t bad_image = 0;
  const Measurement m = measure(
      ctx.budget,
      [&] {
        image = render(ctx.device, s, {Precision::f32, hc.step}, &stats);
        return stats.kernel_seconds;
      },
      [&] {
        for (float v : image.pixels) bad_image += std::isfinite(v) ? 0 : 1;
        return bad_image == 0;
      });
  const RelativeError fe = relative_error(image.pixels, expected);
  const double rays = double(s.cameras.size()) * s.cameras[0].width * s.cameras[0].height;
  Record r{ctx.device_key, "stability", name, "ivr", params};
  add_timing(r, m);
  r.metrics["forward_relative_rms"] = fe.rms;
  r.metrics["forward_relative_max"] = fe.max;
  r.metrics["samples_per_ray"] = double(stats.samples) / rays;
  record_checked(ctx, std::move(r), finite_check(bad_image));

  // The float32 gradient against the float64 one, against a target offset from the render (so
  // that d loss / d pixel is not 0).
  Image target = render(ctx.device, s, {Precision::f64, hc.step});
  for (std::size_t i = 0; i < target.pixels.size(); ++i)
    target.pixels[i] -= model == Model::absorption ? 0.1f : 0.15f + 0.05f * float(i % 4);
  target.pixels_f64.clear();
  AdjointOptions go;
  go.step = hc.step;
  go.tf = go.background = true;
  go.precision = Precision::f64;
  const AdjointGradient g64 = adjoint(ctx.device, s, target, go);
  go.precision = Precision::f32;
  AdjointGradient g32;
  std::size_t bad_gradient = 0;
  double ed = 0, et = 0, eb = 0;
  const Measurement mg = measure(
      ctx.budget,
      [&] {
        g32 = adjoint(ctx.device, s, target, go);
        return g32.kernel_seconds;
      },
      [&] {
        ed = relative_to_largest(std::vector<double>(g32.density.begin(), g32.density.end()),
                                 std::vector<double>(g64.density.begin(), g64.density.end()),
                                 &bad_gradient);
        et = relative_to_largest(g32.tf, g64.tf, &bad_gradient);
        eb = relative_to_largest(g32.background, g64.background, &bad_gradient);
        return bad_gradient == 0;
      });
  Record rg{ctx.device_key, "stability", name + "_gradient", "ivr", params};
  add_timing(rg, mg);
  rg.metrics["gradient_f32_vs_f64_density"] = ed;
  rg.metrics["gradient_f32_vs_f64_tf"] = et;
  rg.metrics["gradient_f32_vs_f64_background"] = eb;
  record_checked(ctx, std::move(rg), finite_check(bad_gradient));
}

}  // namespace

void stability_suite(Context& ctx) {
  std::vector<HardCase> cases = hard_cases();
  if (ctx.quick)  // a wall, grazing rays and the all-zero volume
    cases.erase(std::remove_if(cases.begin(), cases.end(),
                               [](const HardCase& c) {
                                 return c.name != "opaque_wall" && c.name != "grazing" &&
                                        c.name != "all_zero";
                               }),
                cases.end());
  for (const HardCase& hc : cases)
    for (Model model : {Model::emission_absorption, Model::absorption})
      for (Scheme scheme :
           {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact}) {
        if (scheme == Scheme::exact && model != Model::absorption) continue;
        hard_case(ctx, hc, model, scheme);
      }
}

}  // namespace ivr::bench
