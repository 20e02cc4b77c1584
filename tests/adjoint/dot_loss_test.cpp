// dot_loss_test.cpp — the dot loss (sum of target * image; docs/design.md, Losses): its value is
// the weighted sum of the render, its gradient in both modes is the vector-Jacobian product
// (central differences of that sum), it is the mse gradient when the weights are 2 (I - T) / n,
// and what cannot use it says so.
#include <gtest/gtest.h>

#include <random>

#include "adjoint_support.hpp"
#include "ivr/gradient.hpp"
#include "ivr/reconstruct.hpp"
#include "ivr/session.hpp"

namespace ivr::test {
namespace {

// Weights of the image's shape, in [-1, 1] from a fixed seed: an autograd backward's dL/dimage.
Image weights_for(const Scene& s, unsigned seed = 11) {
  const Camera& c = s.cameras.front();
  Image w{int(s.cameras.size()), c.height, c.width, s.channels(), {}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  w.pixels.resize(std::size_t(w.views) * w.height * w.width * w.channels);
  for (float& v : w.pixels) v = u(rng);
  return w;
}

TEST(DotLoss, ValueIsTheWeightedSumOfTheRender) {
  const Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image w = weights_for(s);
  const Image image = render(device(), s, {Precision::f64});
  double want = 0;
  for (std::size_t i = 0; i < w.pixels.size(); ++i)
    want += double(image.pixels[i]) * double(w.pixels[i]);
  const double got = loss_of(s, w, 0, Loss::dot);
  // The render's pixels are stored as float32: their rounding bounds the difference.
  double bound = 0;
  for (std::size_t i = 0; i < w.pixels.size(); ++i)
    bound += 6e-8 * std::abs(double(image.pixels[i]) * double(w.pixels[i]));
  EXPECT_NEAR(got, want, bound + 1e-12);
  EXPECT_DOUBLE_EQ(image_loss(image, w, Loss::dot), want);
}

// Every group a forward or adjoint pass computes, against central differences of sum(w * I).
class DotLossModes : public ::testing::TestWithParam<Mode> {};

TEST_P(DotLossModes, GradientIsTheVectorJacobianProduct) {
  for (const Model model : {Model::emission_absorption, Model::absorption}) {
    Scene s = two_view_scene(model, TfKind::piecewise_linear);
    const Image w = weights_for(s);
    GradientOptions o;
    o.precision = Precision::f64;
    o.mode = GetParam();
    o.loss = Loss::dot;
    const Gradient g = gradient(device(), s, w, {"tf", "background", "voxels:3,17,40-42", "camera"},
                                o);
    ASSERT_EQ(g.groups.size(), 4u);
    EXPECT_EQ(g.plan.mode, GetParam());
    const char* what = model == Model::absorption ? "absorption" : "emission_absorption";
    // TF: every row's colour and extinction columns (a control point's density is forward only).
    const std::vector<std::size_t> shape = tf_gradient_shape(s.tf);
    for (std::size_t r = 0; r < shape[0]; ++r)
      for (std::size_t c = 0; c < 4; ++c) {
        const double h = 1e-5 * std::max(1.0, std::abs(tf_parameter(s.tf, r, c)));
        const double fd = central_difference(
            s, w, h, [&](Scene& x, double d) { return nudge_tf(x, r, c, d); }, 0, Loss::dot);
        EXPECT_NEAR(g.groups[0].values[r * shape[1] + c], fd, 1e-6 + 1e-5 * std::abs(fd))
            << what << " tf " << r << "," << c;
      }
    const int channels = model == Model::absorption ? 1 : 3;
    for (int c = 0; c < channels; ++c) {
      const double fd = central_difference(
          s, w, 1e-5, [&](Scene& x, double d) { return nudge_background(x, c, d); }, 0, Loss::dot);
      EXPECT_NEAR(g.groups[1].values[std::size_t(c)], fd, 1e-6 + 1e-5 * std::abs(fd))
          << what << " background " << c;
    }
    const std::size_t voxels[] = {3, 17, 40, 41, 42};
    for (std::size_t k = 0; k < 5; ++k) {
      const double fd = central_difference(
          s, w, 1e-3, [&](Scene& x, double d) { return nudge_voxel(x, voxels[k], d); }, 0,
          Loss::dot);
      EXPECT_NEAR(g.groups[2].values[k], fd, 1e-5 + 1e-4 * std::abs(fd))
          << what << " voxel " << voxels[k];
    }
    // The camera: eye, target, field of view of view 1.
    for (int column = 0; column < 7; ++column) {
      const double fd = central_difference(
          s, w, 1e-5,
          [&](Scene& x, double d) {
            Camera& c = x.cameras[1];
            if (column < 3)
              c.eye[column] += d;
            else if (column < 6)
              c.target[column - 3] += d;
            else
              c.fov_y += d;
            return d;
          },
          0, Loss::dot);
      EXPECT_NEAR(g.groups[3].values[7 + std::size_t(column)], fd, 1e-5 + 1e-4 * std::abs(fd))
          << what << " camera column " << column;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, DotLossModes, ::testing::Values(Mode::forward, Mode::adjoint),
                         [](const auto& info) {
                           return std::string(info.param == Mode::forward ? "forward" : "adjoint");
                         });

// With weights 2 (I - T) / n the dot loss's gradient is the mse gradient, for every voxel.
TEST(DotLoss, WeightsOfTheMseGiveTheMseDensityGradient) {
  const Scene s = two_view_scene(Model::emission_absorption, TfKind::gaussian);
  const Image target = perturbed_target(s);
  AdjointOptions o;
  o.precision = Precision::f64;
  o.tf = true;
  const AdjointGradient mse = adjoint(device(), s, target, o);
  const Image image = render(device(), s, {Precision::f64});
  Image w = target;
  const double n = double(w.pixels.size());
  for (std::size_t i = 0; i < w.pixels.size(); ++i)
    w.pixels[i] = float(2 * (double(image.pixels[i]) - double(target.pixels[i])) / n);
  o.loss = Loss::dot;
  const AdjointGradient dot = adjoint(device(), s, w, o);
  // The weights are float32 roundings of the mse's own dL/dpixel: relative 1e-6 of the largest.
  EXPECT_LE(relative_error(dot.density, mse.density), 2e-6);
  EXPECT_LE(relative_error(dot.tf, mse.tf), 2e-6);
  EXPECT_GT(max_abs(dot.density), 0);
}

// A session's loss of arrays and its gradient take the dot loss too.
TEST(DotLoss, SessionLossAndGradient) {
  const Scene s = two_view_scene(Model::emission_absorption, TfKind::piecewise_linear);
  const Image w = weights_for(s);
  Session session(device(), s, {Precision::f64});
  const std::vector<double> image = session.render().to_doubles();
  DeviceArray weights(device(), {w.views, w.height, w.width, w.channels}, DType::f64);
  std::vector<double> wd(w.pixels.begin(), w.pixels.end());
  weights.upload(wd.data(), wd.size());
  double want = 0;
  for (std::size_t i = 0; i < wd.size(); ++i) want += image[i] * wd[i];
  const double got = session.loss(session.render(), weights, Loss::dot).to_doubles()[0];
  EXPECT_NEAR(got, want, 1e-12 * (1 + std::abs(want)));
  GradientRequest request;
  request.loss = Loss::dot;
  request.wrt = {"background"};
  const SessionGradient g = session.gradient(weights, request);
  EXPECT_NEAR(g.loss.to_doubles()[0], want, 1e-10 * (1 + std::abs(want)));
  const double fd = central_difference(
      s, w, 1e-5, [&](Scene& x, double d) { return nudge_background(x, 0, d); }, 0, Loss::dot);
  EXPECT_NEAR(g["background"].to_doubles()[0], fd, 1e-6 + 1e-5 * std::abs(fd));
}

TEST(DotLoss, ReconstructRefusesIt) {
  ReconstructOptions o;
  o.loss = Loss::dot;
  try {
    validate_reconstruct(o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument);
    EXPECT_TRUE(has(e.what(), "vector-Jacobian product")) << e.what();
  }
}

}  // namespace
}  // namespace ivr::test
