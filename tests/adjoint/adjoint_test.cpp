// adjoint_test.cpp — reverse-mode gradients against central finite differences of the float64
// render, for every TF kind and both optical models (density, TF parameters, background).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "adjoint/adjoint_support.hpp"
#include "ivr/adjoint.hpp"

namespace ivr::test {
namespace {

class AdjointVsFiniteDifferences : public ::testing::TestWithParam<std::tuple<TfKind, Model>> {};

TEST_P(AdjointVsFiniteDifferences, DensityTfAndBackground) {
  const auto [kind, model] = GetParam();
  const Scene s = two_view_scene(model, kind);
  const Image target = perturbed_target(s);
  AdjointOptions o;
  o.precision = Precision::f64;
  o.tf = o.background = true;
  const AdjointGradient g = adjoint(device(), s, target, o);
  EXPECT_NEAR(g.loss, image_loss(render(device(), s, {Precision::f64}), target, Loss::mse),
              1e-6 * g.loss);  // the float32 image's rounding

  // Voxel densities are float32 in the scene, so the difference step must be representable:
  // h = 2^-12 keeps d ± h exact; the loss is smooth enough there for ~1e-6 agreement.
  double scale = 0;
  for (float v : g.density) scale = std::max(scale, double(std::abs(v)));
  ASSERT_GT(scale, 0);
  for (std::size_t i : {0ul, 7ul, 31ul, 64ul, 119ul}) {
    const double fd = central_difference(s, target, 1.0 / 4096,
                                         [&](Scene& x, double h) { return nudge_voxel(x, i, h); });
    EXPECT_NEAR(g.density[i], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << "voxel " << i;
  }

  // TF parameters (rows x columns) and background.
  const auto shape = tf_gradient_shape(s.tf);
  ASSERT_EQ(g.tf.size(), shape[0] * shape[1]);
  double tf_scale = 0;
  for (double v : g.tf) tf_scale = std::max(tf_scale, std::abs(v));
  for (std::size_t r = 0; r < shape[0]; ++r)
    for (std::size_t c = 0; c < shape[1]; ++c) {
      const double fd = central_difference(
          s, target, 1e-6, [&](Scene& x, double h) { return nudge_tf(x, r, c, h); });
      EXPECT_NEAR(g.tf[r * shape[1] + c], fd, 1e-6 * tf_scale + 1e-6 * std::abs(fd))
          << "tf row " << r << " column " << c;
    }
  const std::size_t nb = model == Model::absorption ? 1 : 3;
  ASSERT_EQ(g.background.size(), nb);
  for (std::size_t c = 0; c < nb; ++c) {
    const double fd = central_difference(
        s, target, 1e-6, [&](Scene& x, double h) { return nudge_background(x, int(c), h); });
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
