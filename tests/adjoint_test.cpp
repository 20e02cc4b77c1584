// adjoint_test.cpp — reverse-mode gradients against central finite differences of the float64
// render, for every TF kind and both optical models (density, TF parameters, background).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ivr/gradient.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A smooth random 6x5x4 volume in a non-cubic box, two perspective views, 6x5 images.
Scene small_scene(Model model, TfKind kind) {
  Scene s;
  s.volume.nx = 6;
  s.volume.ny = 5;
  s.volume.nz = 4;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.15, 0.85);
  for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) s.volume.data.push_back(float(u(rng)));
  set_default_box(s);
  s.model = model;
  s.tf.kind = kind;
  s.tf.extinction_scale = 3;
  s.tf.color_scale = 0.8;
  s.tf.points = {{0.1, {0.2, 0.3, 0.9}, 1.0}, {0.45, {0.9, 0.5, 0.1}, 4.0}, {0.8, {1, 1, 0.8}, 2.0}};
  s.tf.range = {0.1, 0.9};
  s.tf.entries = {{0.1, 0.2, 0.9, 0.5}, {0.9, 0.6, 0.2, 3.0}, {0.3, 0.8, 0.4, 1.5}, {1, 1, 1, 4}};
  s.tf.gaussians = {{0.35, 0.15, {0.9, 0.3, 0.2}, 3.0}, {0.7, 0.1, {0.2, 0.6, 1.0}, 5.0}};
  s.background = glm::dvec3(0.3, 0.2, 0.1);
  Camera a, b;
  a.eye = {0.3, 0.4, 1.6};
  b.eye = {-1.4, 0.2, 0.5};
  a.width = b.width = 6;
  a.height = b.height = 5;
  a.fov_y = b.fov_y = 35;
  s.cameras = {a, b};
  s.integrator.step = 0.7;
  s.integrator.min_transmittance = 0;
  return s;
}

// A fixed target: the scene rendered with perturbed densities, so the loss gradient is not zero.
Image target_for(const Scene& s) {
  Scene t = s;
  for (std::size_t i = 0; i < t.volume.data.size(); ++i)
    t.volume.data[i] = float(std::min(1.0, t.volume.data[i] * (1.0 + 0.3 * std::sin(double(i)))));
  return render(device(), t, {Precision::f64});
}

// The float64 loss, reduced on the device from float64 pixels (a render's image is float32,
// whose rounding would swamp the differences).
double loss_of(const Scene& s, const Image& target) {
  GradientOptions o;
  o.precision = Precision::f64;
  o.density = false;
  return gradient(device(), s, target, o).loss;
}

// Central difference of the float64 loss in one scalar of the scene.
template <class Set>
double central_difference(Scene s, const Image& target, double h, Set set) {
  Scene plus = s, minus = s;
  set(plus, +h);
  set(minus, -h);
  return (loss_of(plus, target) - loss_of(minus, target)) / (2 * h);
}

class AdjointVsFiniteDifferences : public ::testing::TestWithParam<std::tuple<TfKind, Model>> {};

TEST_P(AdjointVsFiniteDifferences, DensityTfAndBackground) {
  const auto [kind, model] = GetParam();
  const Scene s = small_scene(model, kind);
  const Image target = target_for(s);
  GradientOptions o;
  o.precision = Precision::f64;
  o.tf = o.background = true;
  const Gradient g = gradient(device(), s, target, o);
  EXPECT_NEAR(g.loss, image_loss(render(device(), s, {Precision::f64}), target, Loss::mse),
              1e-6 * g.loss);  // the float32 image's rounding

  // Voxel densities are float32 in the scene, so the difference step must be representable:
  // h = 2^-12 keeps d ± h exact; the loss is smooth enough there for ~1e-6 agreement.
  double scale = 0;
  for (float v : g.density) scale = std::max(scale, double(std::abs(v)));
  ASSERT_GT(scale, 0);
  for (std::size_t i : {0ul, 7ul, 31ul, 64ul, 119ul}) {
    const double fd = central_difference(s, target, 1.0 / 4096, [&](Scene& x, double h) {
      x.volume.data[i] = float(double(x.volume.data[i]) + h);
    });
    EXPECT_NEAR(g.density[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << "voxel " << i;
  }

  // TF parameters (rows x columns) and background.
  const auto shape = tf_gradient_shape(s.tf);
  ASSERT_EQ(g.tf.size(), shape[0] * shape[1]);
  double tf_scale = 0;
  for (double v : g.tf) tf_scale = std::max(tf_scale, std::abs(v));
  for (std::size_t r = 0; r < shape[0]; ++r)
    for (std::size_t c = 0; c < shape[1]; ++c) {
      const double fd = central_difference(s, target, 1e-6, [&](Scene& x, double h) {
        TransferFunction& tf = x.tf;
        switch (tf.kind) {
          case TfKind::identity: (c == 0 ? tf.extinction_scale : tf.color_scale) += h; break;
          case TfKind::piecewise_linear:
            (c < 3 ? tf.points[r].color[int(c)] : tf.points[r].extinction) += h;
            break;
          case TfKind::table: tf.entries[r][int(c)] += h; break;
          case TfKind::gaussian: {
            TfGaussian& gg = tf.gaussians[r];
            double* p[6] = {&gg.color.x, &gg.color.y, &gg.color.z, &gg.extinction, &gg.mean, &gg.width};
            *p[c] += h;
          } break;
        }
      });
      EXPECT_NEAR(g.tf[r * shape[1] + c], fd, 1e-6 * tf_scale + 1e-6 * std::abs(fd))
          << "tf row " << r << " column " << c;
    }
  const std::size_t nb = model == Model::absorption ? 1 : 3;
  ASSERT_EQ(g.background.size(), nb);
  for (std::size_t c = 0; c < nb; ++c) {
    const double fd = central_difference(s, target, 1e-6, [&](Scene& x, double h) {
      glm::dvec3 b = x.effective_background();
      if (nb == 1) b += h;
      else b[int(c)] += h;
      x.background = b;
    });
    EXPECT_NEAR(g.background[c], fd, 1e-7 + 1e-6 * std::abs(fd)) << "background " << c;
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, AdjointVsFiniteDifferences,
    ::testing::Combine(::testing::Values(TfKind::identity, TfKind::piecewise_linear, TfKind::table,
                                         TfKind::gaussian),
                       ::testing::Values(Model::absorption, Model::emission_absorption)));

}  // namespace
}  // namespace ivr::test
