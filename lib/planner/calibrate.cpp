// calibrate.cpp — measures a device's cost model for the planner: a render, an adjoint gradient
// and forward passes of 1..32 TF and background lanes and of 1, 4, 16 voxel lanes (camera and voxel
// lanes march one ray per work-item where the others march packets) of one scene, medians of
// repeated runs, each forward cost fit by least squares as base + per_lane · lanes renders.
#include "ivr/calibrate.hpp"

#include <algorithm>
#include <vector>

#include "ivr/error.hpp"
#include "ivr/adjoint.hpp"
#include "ivr/jacobian.hpp"
#include "ivr/volume_io.hpp"

namespace ivr {

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Least squares of forward / render = base + per_lane · L (both kept positive).
void fit_lanes(const std::vector<int>& lanes, const std::vector<double>& renders, double* base,
               double* per_lane) {
  double sl = 0, sll = 0, sf = 0, slf = 0;
  const double n = double(lanes.size());
  for (std::size_t k = 0; k < lanes.size(); ++k) {
    const double l = double(lanes[k]), f = renders[k];
    sl += l;
    sll += l * l;
    sf += f;
    slf += l * f;
  }
  *per_lane = std::max((n * slf - sl * sf) / (n * sll - sl * sl), 1e-3);
  *base = std::max((sf - *per_lane * sl) / n, 1e-3);
}

}  // namespace

Scene calibration_scene(int volume, int image) {
  Scene s;
  s.volume = synthetic_volume("marschner_lobb", volume, volume, volume);
  set_default_box(s);
  s.model = Model::emission_absorption;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0, 0, 0}, 0},
                 {0.35, {0.1, 0.3, 0.9}, 2},
                 {0.55, {0.9, 0.6, 0.2}, 10},
                 {0.8, {1, 1, 0.9}, 30}};
  s.background = glm::dvec3(0.05);
  Camera c;
  c.eye = {1.1, 0.8, 1.5};
  c.fov_y = 38;
  c.width = c.height = image;
  s.cameras = {c};
  return s;
}

Calibration calibrate(Device& device, const CalibrateOptions& o) {
  if (o.volume < 4 || o.image < 4 || o.repeats < 1)
    throw Error(Status::invalid_argument,
                "calibration needs a volume and image of at least 4 and "
                "at least one repeat");
  const Scene scene = calibration_scene(o.volume, o.image);
  // A target the render misses by 10 %: against its own image every gradient is 0, and the
  // adjoint would skip its scatter (a corner adds only where its gradient is nonzero).
  Image target = render(device, scene, {o.precision});
  for (float& v : target.pixels) v *= 0.9f;
  for (double& v : target.pixels_f64) v *= 0.9;
  // Parameters that cycle through the TF's rows and columns and the background: typical lanes.
  std::vector<Parameter> pool = parameters_of(scene, "tf");
  for (const Parameter& p : parameters_of(scene, "tf_points")) pool.push_back(p);
  for (const Parameter& p : parameters_of(scene, "background")) pool.push_back(p);

  // Voxels from the middle of the volume (where the view sees them): camera-like, per-ray lanes.
  std::vector<Parameter> voxels;
  for (int k = 0; k < 16; ++k) {
    const std::int64_t n = o.volume, x = n / 4 + (k * 7) % (n / 2), y = n / 4 + (k * 5) % (n / 2),
                       z = n / 4 + (k * 3) % (n / 2);
    voxels.push_back({ParameterGroup::voxel, (z * n + y) * n + x, 0});
  }
  const std::vector<int> ray_lanes = {1, 4, 16};

  Calibration c;
  std::vector<double> render_s, adjoint_s;
  std::vector<std::vector<double>> forward_s(6), ray_s(ray_lanes.size());
  RenderStats stats;
  for (int r = 0; r < o.repeats + 1; ++r) {  // the first round compiles and warms up
    render(device, scene, {o.precision}, &stats);
    AdjointOptions go;
    go.precision = o.precision;
    const AdjointGradient g = adjoint(device, scene, target, go);
    for (int k = 0; k < 6; ++k) {
      std::vector<Parameter> params;
      for (int i = 0; i < (1 << k); ++i) params.push_back(pool[std::size_t(i) % pool.size()]);
      JacobianOptions to;
      to.precision = o.precision;
      const Jacobian t = jacobian(device, scene, params, &target, to);
      if (r > 0) forward_s[std::size_t(k)].push_back(t.kernel_seconds);
    }
    for (std::size_t k = 0; k < ray_lanes.size(); ++k) {
      JacobianOptions to;
      to.precision = o.precision;
      const std::vector<Parameter> params(voxels.begin(), voxels.begin() + ray_lanes[k]);
      const Jacobian t = jacobian(device, scene, params, &target, to);
      if (r > 0) ray_s[k].push_back(t.kernel_seconds);
    }
    if (r > 0) {
      render_s.push_back(stats.kernel_seconds);
      adjoint_s.push_back(g.kernel_seconds);
    }
  }
  c.render_seconds = median(render_s);
  c.adjoint_seconds = median(adjoint_s);
  c.samples = stats.samples;
  std::vector<double> renders;
  for (int k = 0; k < 6; ++k) {
    const double f = median(forward_s[std::size_t(k)]);
    c.lanes.push_back(1 << k);
    c.forward_seconds.push_back(f);
    renders.push_back(f / c.render_seconds);
  }
  fit_lanes(c.lanes, renders, &c.model.forward_base, &c.model.forward_per_lane);
  renders.clear();
  for (std::size_t k = 0; k < ray_lanes.size(); ++k) {
    c.ray_lanes.push_back(ray_lanes[k]);
    c.forward_ray_seconds.push_back(median(ray_s[k]));
    renders.push_back(c.forward_ray_seconds.back() / c.render_seconds);
  }
  fit_lanes(c.ray_lanes, renders, &c.model.forward_ray_base, &c.model.forward_ray_per_lane);
  c.model.adjoint = c.adjoint_seconds / c.render_seconds;
  c.model.seconds_per_sample = c.render_seconds / double(std::max<std::uint64_t>(c.samples, 1));
  c.model.source = "calibration";
  return c;
}

}  // namespace ivr
