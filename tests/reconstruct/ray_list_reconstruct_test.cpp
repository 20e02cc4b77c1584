// ray_list_reconstruct_test.cpp — the reconstruction loop over a ray list: densities recovered
// from the transmittances of sightlines that end inside the volume (coarse to fine, Adam), the
// loss falling by orders of magnitude and the volume approaching the truth; the TF alone in
// forward mode; a target of the wrong shape named.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ivr/reconstruct.hpp"
#include "test_support.hpp"

namespace ivr {
namespace {

using test::device;

Scene sightline_scene(std::size_t count) {
  Scene s;
  s.volume = synthetic_volume("sphere", 16, 16, 16);
  set_default_box(s);
  s.model = Model::absorption;
  s.tf.kind = TfKind::piecewise_linear;  // σ = 3·d on the sphere's [0, 1]
  s.tf.points = {{0.0, {1, 1, 1}, 0.0}, {1.0, {1, 1, 1}, 3.0}};
  s.integrator.min_transmittance = 0;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<double> points;
  for (std::size_t i = 0; i < count; ++i) {
    // Half from the centre to a random point, half across the box from face to face.
    if (i % 2)
      points.insert(points.end(), {0.0, 0.0, 0.0, u(rng), u(rng), u(rng)});
    else
      points.insert(points.end(), {u(rng), u(rng), -0.5, u(rng), u(rng), 0.5});
  }
  s.rays = make_ray_list(points.data(), count, 6);
  return s;
}

TEST(RayListReconstruct, DensitiesFromSightlines) {
  const Scene truth = sightline_scene(12000);
  const Image targets = test::render_at(truth, Precision::f32, 0);
  ASSERT_EQ(targets.width, 12000);
  ReconstructOptions o;
  o.iterations = 150;
  o.init = Init::constant;
  o.init_value = 0.3;
  Reconstruction r(device(), truth, targets, o);
  while (!r.done()) r.step();
  const std::vector<IterationRecord>& h = r.history();
  ASSERT_EQ(h.size(), 150u);
  EXPECT_EQ(h.back().views, 1);
  EXPECT_LT(h.back().loss, 1e-3 * h.front().loss);
  const Volume got = r.result().volume;
  std::vector<float> start(truth.volume.data.size(), 0.3f);
  const double error = relative_volume_error(got, truth.volume);
  Volume flat = truth.volume;
  flat.data = start;
  EXPECT_LT(error, 0.25 * relative_volume_error(flat, truth.volume)) << "error " << error;
}

TEST(RayListReconstruct, TheTfAloneAndATargetOfTheWrongShape) {
  Scene truth = sightline_scene(2000);
  const Image targets = test::render_at(truth, Precision::f32, 0);
  Scene start = truth;
  start.tf.points[1].extinction = 1.0;
  ReconstructOptions o;
  o.density = false;
  o.tf = true;
  o.iterations = 30;
  Reconstruction r(device(), start, targets, o);
  while (!r.done()) r.step();
  EXPECT_LT(r.history().back().loss, 1e-6 * r.history().front().loss);
  Image wrong = targets;
  wrong.width -= 1;
  wrong.pixels.pop_back();
  try {
    Reconstruction bad(device(), start, wrong, o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_TRUE(test::has(e.what(), "target has shape (1, 1, 1999, 1)")) << e.what();
  }
}

}  // namespace
}  // namespace ivr
