// scene.cpp — default box, built-in synthetic volumes and scene validation.
#include "ivr/scene.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <glm/geometric.hpp>
#include <sstream>

#include "ivr/error.hpp"
#include "ivr/phantom.hpp"
#include "scene/scene.hpp"

namespace ivr {

namespace {

constexpr int kMaxImageSide = 16384;
constexpr double kMaxSamplesPerRay = 1e9;

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  throw Error(Status::invalid_argument, where + ": " + what);
}

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void validate_camera(const Camera& c, const std::string& w) {
  if (!finite(c.eye) || !finite(c.target) || !finite(c.up))
    fail(w, "eye, target and up must be finite");
  const glm::dvec3 view = c.target - c.eye;
  const double dist = glm::length(view);
  if (!(dist > 1e-12 * (1.0 + glm::length(c.eye))))
    fail(w, "eye equals target, so there is no view direction");
  if (!(glm::length(c.up) > 0)) fail(w, "up is the zero vector");
  const double sine = glm::length(glm::cross(view / dist, glm::normalize(c.up)));
  if (!(sine > 1e-9)) fail(w, "up is parallel to the view direction (target - eye)");
  if (c.projection == Projection::perspective) {
    if (!std::isfinite(c.fov_y) || !(c.fov_y > 0) || !(c.fov_y < 180))
      fail(w, "fov_y must be in (0, 180) degrees, got " + number_text(c.fov_y));
  } else if (!std::isfinite(c.ortho_height) || !(c.ortho_height > 0)) {
    fail(w, "ortho_height must be > 0, got " + number_text(c.ortho_height));
  }
  if (c.width < 1 || c.height < 1 || c.width > kMaxImageSide || c.height > kMaxImageSide)
    fail(w, "image size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                " is outside 1.." + std::to_string(kMaxImageSide) + " per side");
}

// The schemes that integrate exactly need what they are exact for.
void validate_scheme(const Scene& s, Scheme scheme) {
  const bool piecewise_linear_tf = s.tf.kind != TfKind::gaussian;
  if (scheme == Scheme::exact && s.model != Model::absorption)
    fail("integrator.scheme",
         "'exact' integrates the absorption model only (this scene is emission_absorption); use "
         "'preintegrated', 'trapezoid' or 'midpoint'");
  if ((scheme == Scheme::exact || scheme == Scheme::preintegrated) && !piecewise_linear_tf)
    fail("integrator.scheme", std::string("'") + scheme_name(scheme) +
                                  "' needs a transfer function piecewise linear in density "
                                  "(identity, piecewise_linear or table), not gaussian");
}

}  // namespace

const char* scheme_name(Scheme scheme) {
  switch (scheme) {
    case Scheme::midpoint:
      return "midpoint";
    case Scheme::trapezoid:
      return "trapezoid";
    case Scheme::exact:
      return "exact";
    case Scheme::preintegrated:
      return "preintegrated";
  }
  return "?";
}

Scheme parse_scheme(const std::string& name, const std::string& where) {
  for (Scheme s : {Scheme::midpoint, Scheme::trapezoid, Scheme::exact, Scheme::preintegrated})
    if (name == scheme_name(s)) return s;
  fail(where, "unknown scheme '" + name + "' (known: midpoint, trapezoid, exact, preintegrated)");
}

void validate_tf(const TransferFunction& tf) {
  auto check_sigma = [](const std::string& where, double sigma) {
    if (!std::isfinite(sigma) || sigma < 0)
      fail(where, "extinction must be finite and >= 0, got " + number_text(sigma));
  };
  auto check_color = [](const std::string& where, const glm::dvec3& c) {
    if (!finite(c)) fail(where, "color must be finite");
  };
  switch (tf.kind) {
    case TfKind::identity:
      check_sigma("tf.extinction_scale", tf.extinction_scale);
      if (!std::isfinite(tf.color_scale)) fail("tf.color_scale", "must be finite");
      break;
    case TfKind::piecewise_linear:
      if (tf.points.empty())
        fail("tf.points", "a piecewise_linear transfer function needs at least one point");
      for (std::size_t i = 0; i < tf.points.size(); ++i) {
        const std::string w = "tf.points[" + std::to_string(i) + "]";
        if (!std::isfinite(tf.points[i].density)) fail(w, "density must be finite");
        if (i > 0 && tf.points[i].density < tf.points[i - 1].density)
          fail(w, "points must be sorted by density (" + number_text(tf.points[i].density) + " < " +
                      number_text(tf.points[i - 1].density) + ")");
        check_sigma(w, tf.points[i].extinction);
        check_color(w, tf.points[i].color);
      }
      break;
    case TfKind::table:
      if (tf.entries.empty())
        fail("tf.entries", "a table transfer function needs at least one entry");
      if (!std::isfinite(tf.range.x) || !std::isfinite(tf.range.y) || !(tf.range.y > tf.range.x))
        fail("tf.range", "must be [lo, hi] with lo < hi, got [" + number_text(tf.range.x) + ", " +
                             number_text(tf.range.y) + "]");
      for (std::size_t i = 0; i < tf.entries.size(); ++i) {
        const std::string w = "tf.entries[" + std::to_string(i) + "]";
        check_color(w, glm::dvec3(tf.entries[i]));
        check_sigma(w, tf.entries[i].w);
      }
      break;
    case TfKind::gaussian:
      if (tf.gaussians.empty())
        fail("tf.gaussians", "a gaussian transfer function needs at least one Gaussian");
      for (std::size_t i = 0; i < tf.gaussians.size(); ++i) {
        const std::string w = "tf.gaussians[" + std::to_string(i) + "]";
        const TfGaussian& g = tf.gaussians[i];
        if (!std::isfinite(g.mean)) fail(w, "mean must be finite");
        if (!std::isfinite(g.width) || !(g.width > 0))
          fail(w, "width must be > 0, got " + number_text(g.width));
        check_sigma(w, g.extinction);
        check_color(w, g.color);
      }
      break;
  }
}

void set_default_box(Scene& scene) {
  const Volume& v = scene.volume;
  const glm::dvec3 extent = glm::dvec3(v.nx, v.ny, v.nz) * v.spacing;
  const double longest = std::max(extent.x, std::max(extent.y, extent.z));
  if (!(longest > 0) || !std::isfinite(longest))
    fail("volume", "spacing must be positive and finite to derive the default box");
  scene.box_max = 0.5 * extent / longest;
  scene.box_min = -scene.box_max;
}

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void validate(const Scene& s) {
  validate_with(s, s.integrator);
}

void validate_geometry(const Scene& s) {
  const Volume& v = s.volume;
  if (v.nx < 1 || v.ny < 1 || v.nz < 1)
    fail("volume", "dims must be >= 1, got " + std::to_string(v.nx) + "x" + std::to_string(v.ny) +
                       "x" + std::to_string(v.nz));
  if (!finite(s.box_min) || !finite(s.box_max) || !(s.box_max.x > s.box_min.x) ||
      !(s.box_max.y > s.box_min.y) || !(s.box_max.z > s.box_min.z))
    fail("box", "max must exceed min on every axis");
  if (s.has_ray_list()) {
    if (!s.cameras.empty())
      fail("rays", "a scene has cameras or a ray list, not both (" +
                       std::to_string(s.cameras.size()) + " cameras given)");
    if (s.rays.values.size() % RayList::kColumns != 0)
      fail("rays", "holds " + std::to_string(s.rays.values.size()) +
                       " values, not a multiple of 8 (make one with ivr::make_ray_list)");
    // make_ray_list's checks, on whatever the caller put in (a row must come through unchanged).
    const RayList again = make_ray_list(s.rays.values.data(), s.rays.count(), 8);
    for (std::size_t i = 0; i < again.values.size(); ++i)
      if (again.values[i] != s.rays.values[i])
        fail("rays[" + std::to_string(i / 8) + "]",
             "its direction is not unit length (make the list with ivr::make_ray_list)");
    return;
  }
  if (s.cameras.empty()) fail("cameras", "a scene needs at least one camera");
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    const std::string w = "cameras[" + std::to_string(i) + "]";
    validate_camera(s.cameras[i], w);
    if (s.cameras[i].width != s.cameras[0].width || s.cameras[i].height != s.cameras[0].height)
      fail(w, "all cameras must share width and height (" + std::to_string(s.cameras[i].width) +
                  "x" + std::to_string(s.cameras[i].height) + " vs " +
                  std::to_string(s.cameras[0].width) + "x" + std::to_string(s.cameras[0].height) +
                  ")");
  }
}

void validate_with(const Scene& s, const Integrator& it) {
  validate_description(s, it);
  const Volume& v = s.volume;
  if (v.data.size() != v.voxel_count())
    fail("volume", "holds " + std::to_string(v.data.size()) + " values but dims need " +
                       std::to_string(v.voxel_count()));
  // Branch-free scan in blocks (it vectorises), then locate the culprit.
  constexpr std::size_t kBlock = 4096;
  for (std::size_t start = 0; start < v.data.size(); start += kBlock) {
    const std::size_t end = std::min(v.data.size(), start + kBlock);
    bool bad = false;
    for (std::size_t i = start; i < end; ++i) bad |= !(v.data[i] >= 0.0f && v.data[i] <= FLT_MAX);
    if (!bad) continue;
    for (std::size_t i = start; i < end; ++i)
      if (!(v.data[i] >= 0.0f && v.data[i] <= FLT_MAX)) throw bad_density(v, i, v.data[i]);
  }
}

Error bad_density(const Volume& v, std::size_t i, double value) {
  const std::size_t x = i % v.nx, y = (i / v.nx) % v.ny, z = i / (std::size_t(v.nx) * v.ny);
  return Error(Status::invalid_argument,
               "volume: density at (x, y, z) = (" + std::to_string(x) + ", " + std::to_string(y) +
                   ", " + std::to_string(z) + ") is " + number_text(value) +
                   "; densities must be finite and >= 0");
}

void validate_description(const Scene& s, const Integrator& it) {
  validate_geometry(s);
  validate_tf(s.tf);
  if (s.background && !finite(*s.background)) fail("background", "must be finite");
  validate_scheme(s, it.scheme);
  if (!std::isfinite(it.step) || !(it.step > 0))
    fail("integrator.step", "must be > 0, got " + number_text(it.step));
  if (!std::isfinite(it.tolerance) || it.tolerance < 0)
    fail("integrator.tolerance",
         "must be > 0 (or 0: use the step), got " + number_text(it.tolerance));
  if (!std::isfinite(it.min_transmittance) || it.min_transmittance < 0 || it.min_transmittance >= 1)
    fail("integrator.min_transmittance",
         "must be in [0, 1), got " + number_text(it.min_transmittance));
  const glm::dvec3 h = s.voxel_size();
  const double diagonal = glm::length(s.box_max - s.box_min);
  const double per_ray = diagonal / (it.step * std::min(h.x, std::min(h.y, h.z)));
  if (!(per_ray <= kMaxSamplesPerRay))
    fail("integrator.step", number_text(it.step) + " would take up to " + number_text(per_ray) +
                                " samples per ray (limit " + number_text(kMaxSamplesPerRay) + ")");
}

Volume synthetic_volume(const std::string& name, int nx, int ny, int nz) {
  if (nx < 1 || ny < 1 || nz < 1 || double(nx) * ny * nz > 2147483647.0)
    fail("volume.dims", "synthetic volume dims must be >= 1 and hold at most 2^31 voxels");
  // Shepp–Logan on the same [-1, 1] cell-centre grid as the others, so non-cubic dims stretch it.
  if (name == "shepp_logan") return phantom_from_ellipsoids(shepp_logan_ellipsoids(), nx, ny, nz);
  if (name == "zeros") {  // only the grid's shape matters (ivr tomo, ivr backproject)
    Volume z;
    z.nx = nx;
    z.ny = ny;
    z.nz = nz;
    z.data.assign(z.voxel_count(), 0.0f);
    return z;
  }
  Volume v;
  v.nx = nx;
  v.ny = ny;
  v.nz = nz;
  v.data.resize(v.voxel_count());
  const double pi = 3.14159265358979323846;
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        // Cell-centre coordinates in [-1, 1].
        const double px = 2.0 * (x + 0.5) / nx - 1, py = 2.0 * (y + 0.5) / ny - 1,
                     pz = 2.0 * (z + 0.5) / nz - 1;
        double d;
        if (name == "sphere") {
          const double r = std::sqrt(px * px + py * py + pz * pz);
          const double core = 0.5 * (1 - std::tanh((r - 0.55) / 0.06));         // solid ball
          const double shell = 0.6 * std::exp(-std::pow((r - 0.8) / 0.05, 2));  // thin shell
          d = std::min(1.0, 0.45 * core + shell);
        } else if (name == "marschner_lobb") {
          const double alpha = 0.25, fm = 6.0;
          const double rho =
              std::cos(2 * pi * fm * std::cos(pi * std::sqrt(px * px + py * py) / 2));
          d = (1 - std::sin(pi * pz / 2) + alpha * (1 + rho)) / (2 * (1 + alpha));
        } else {
          fail("volume.synthetic", "unknown synthetic volume '" + name +
                                       "' (known: sphere, marschner_lobb, shepp_logan, zeros)");
        }
        v.data[(std::size_t(z) * ny + y) * nx + x] = float(std::max(0.0, d));
      }
  return v;
}

void check_target(const Scene& scene, const Image& target) {
  const ImageExtent c = image_extent(scene);
  const auto shape = [](int v, int h, int w, int ch) {
    return "(" + std::to_string(v) + ", " + std::to_string(h) + ", " + std::to_string(w) + ", " +
           std::to_string(ch) + ")";
  };
  const std::string want = shape(c.views, c.height, c.width, scene.channels());
  const std::string got = shape(target.views, target.height, target.width, target.channels);
  if (want != got || target.pixels.size() !=
                         std::size_t(target.views) * target.height * target.width * target.channels)
    throw Error(Status::invalid_argument,
                "target has shape " + got + " but the scene renders " + want);
  for (std::size_t i = 0; i < target.pixels.size(); ++i)
    if (!std::isfinite(target.pixels[i]))
      throw Error(Status::invalid_argument, "target element " + std::to_string(i) +
                                                " is not finite (" +
                                                std::to_string(target.pixels[i]) + ")");
}

}  // namespace ivr
