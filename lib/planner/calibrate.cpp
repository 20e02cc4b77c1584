// calibrate.cpp — measures a device's cost model for the planner: a render, an adjoint gradient
// and forward passes of 1..32 lanes of one scene, medians of repeated runs, the forward costs fit
// by least squares as base + per_lane · lanes renders.
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
  const Image target = render(device, scene, {o.precision});
  // Parameters that cycle through the TF's rows and columns and the background: typical lanes.
  std::vector<Parameter> pool = parameters_of(scene, "tf");
  for (const Parameter& p : parameters_of(scene, "tf_points")) pool.push_back(p);
  for (const Parameter& p : parameters_of(scene, "background")) pool.push_back(p);

  Calibration c;
  std::vector<double> render_s, adjoint_s;
  std::vector<std::vector<double>> forward_s(6);
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
    if (r > 0) {
      render_s.push_back(stats.kernel_seconds);
      adjoint_s.push_back(g.kernel_seconds);
    }
  }
  c.render_seconds = median(render_s);
  c.adjoint_seconds = median(adjoint_s);
  c.samples = stats.samples;
  // Least squares of forward / render = base + per_lane · L over L = 1, 2, 4, ..., 32.
  double sl = 0, sll = 0, sf = 0, slf = 0;
  for (int k = 0; k < 6; ++k) {
    const double l = double(1 << k), f = median(forward_s[std::size_t(k)]) / c.render_seconds;
    c.lanes.push_back(1 << k);
    c.forward_seconds.push_back(f * c.render_seconds);
    sl += l;
    sll += l * l;
    sf += f;
    slf += l * f;
  }
  const double n = 6, per_lane = (n * slf - sl * sf) / (n * sll - sl * sl);
  c.model.forward_per_lane = std::max(per_lane, 1e-3);
  c.model.forward_base = std::max((sf - c.model.forward_per_lane * sl) / n, 1e-3);
  c.model.adjoint = c.adjoint_seconds / c.render_seconds;
  c.model.seconds_per_sample = c.render_seconds / double(std::max<std::uint64_t>(c.samples, 1));
  c.model.source = "calibration";
  return c;
}

}  // namespace ivr
