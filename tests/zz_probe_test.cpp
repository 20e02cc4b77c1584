#include <gtest/gtest.h>
#include <cstdio>
#include "reference/compare.hpp"
#include "reference/reference.hpp"
#include "test_support.hpp"
namespace ivr {
namespace {
TransferFunction make_tf(TfKind kind) {
  TransferFunction tf;
  tf.kind = kind;
  switch (kind) {
    case TfKind::identity:
      tf.extinction_scale = 6;
      tf.color_scale = 1.5;
      break;
    case TfKind::piecewise_linear:  // the data spans [0, 1]: both constant ends are exercised
      tf.points = {{0.1, {0.1, 0.1, 0.3}, 0.5}, {0.35, {0.9, 0.4, 0.1}, 5},
                   {0.6, {0.2, 0.8, 0.3}, 2}, {0.85, {1, 1, 1}, 9}};
      break;
    case TfKind::table:
      tf.range = {0.1, 0.9};
      tf.entries = {{0.1, 0.2, 0.9, 1}, {0.8, 0.2, 0.1, 6}, {0.3, 0.9, 0.3, 3},
                    {0.9, 0.9, 0.2, 8}, {1.0, 0.5, 0.5, 4}};
      break;
    case TfKind::gaussian:
      tf.gaussians = {{0.3, 0.12, {1, 0.3, 0.1}, 6}, {0.7, 0.1, {0.2, 0.5, 1}, 8}};
      break;
  }
  return tf;
}

// Three views of one anisotropic 9x7x5 volume; W != H so that the aspect ratio matters.
Scene smooth_scene(TfKind kind, Model model, Projection projection) {
  Scene s;
  s.volume = reference::smooth_volume(9, 7, 5, 11);
  s.volume.spacing = {1.0, 1.3, 1.7};
  set_default_box(s);
  s.model = model;
  s.tf = make_tf(kind);
  if (model == Model::emission_absorption) s.background = glm::dvec3(0.1, 0.2, 0.3);
  const glm::dvec3 eyes[3] = {{0.4, 0.5, 2.3}, {-2.2, 0.3, 0.6}, {1.2, -1.6, -1.3}};
  for (const glm::dvec3& eye : eyes) {
    Camera c;
    c.eye = eye;
    c.target = {0.02, -0.03, 0.01};
    c.fov_y = 38;
    c.projection = projection;
    c.ortho_height = 1.3;
    c.width = 10;
    c.height = 8;
    s.cameras.push_back(c);
  }
  s.integrator.min_transmittance = 0;
  return s;
}

}

TEST(Probe, P) {
  Scene s = smooth_scene(TfKind::identity, Model::absorption, Projection::orthographic);
  const auto want = reference::render(s, 0.0005 * reference::min_voxel_edge(s));
  for (double step : {0.25, 0.125, 0.0625, 0.01}) {
    RenderOptions o; o.precision = Precision::f64; o.step = step;
    Image img = render(test::device(), s, o);
    double mx = 0; size_t wi = 0;
    for (size_t i = 0; i < want.size(); ++i) { double e = std::abs(img.pixels[i] - want[i]); if (e > mx) mx = e, wi = i; }
    std::printf("step %g max %.3e at view %zu y %zu x %zu got %.8f want %.8f\n", step, mx, wi / 80, wi / 10 % 8, wi % 10, img.pixels[wi], want[wi]);
  }
}
}
