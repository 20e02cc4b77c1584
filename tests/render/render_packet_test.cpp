// render_packet_test.cpp — the CPU packet render (kernels/render_packet.cl: 16 or 8 rays per
// work-item in vector lanes) against the one-ray-per-work-item kernel (render.cl,
// $IVR_PACKET=0): the same image bit for bit and the same sample counts, over edge cases of the
// packet (image widths not a multiple of the lanes, rays that miss, early termination, cameras
// inside the volume, orthographic views, one- and two-point TFs, densities exactly on the TF's
// points); and gradients whose primal march it made (lib/adjoint/adjoint.cpp) bit for bit those of the
// adjoint kernel's own march — its remaining radiance, C minus the prefix, needs that.
#include <gtest/gtest.h>

#include <cmath>

#include "test_support.hpp"

namespace ivr::test {
namespace {

struct Rendered {
  Image image;
  RenderStats stats;
};

Rendered render_with(const Scene& scene, bool packet, double step) {
  const ScopedEnv env("IVR_PACKET", packet ? "1" : "0");
  Rendered r;
  r.image = render_at(scene, Precision::f32, step, &r.stats);
  return r;
}

void expect_same(const Scene& scene, double step, const std::string& what) {
  const Rendered a = render_with(scene, true, step), b = render_with(scene, false, step);
  if (device().info().type == "cpu") {
    EXPECT_NE(a.stats.variant.find("packet"), std::string::npos) << what << ": " << a.stats.variant;
  }
  EXPECT_EQ(b.stats.variant.find("packet"), std::string::npos) << what;
  EXPECT_EQ(a.stats.samples, b.stats.samples) << what;
  ASSERT_EQ(a.image.pixels.size(), b.image.pixels.size()) << what;
  double worst = 0;
  for (std::size_t i = 0; i < a.image.pixels.size(); ++i) {
    ASSERT_TRUE(std::isfinite(a.image.pixels[i])) << what << " element " << i;
    worst = std::max(worst, double(std::abs(a.image.pixels[i] - b.image.pixels[i])));
  }
  EXPECT_EQ(worst, 0.0) << what;  // bit for bit (render.cl's scalar exp in every lane)
}

TEST(RenderPacket, SameImageAsOneRayPerWorkItem) {
  for (const char* lanes : {"16", "8"}) {
    const ScopedEnv width("IVR_PACKET_LANES", lanes);
    Scene s = calibration_scene(24, 8);
    s.cameras[0].width = 37;  // 4 packets and a partial one per row
    s.cameras[0].height = 23;
    Camera side = s.cameras[0];
    side.eye = {0.2, -1.4, 0.3};
    Camera inside = s.cameras[0];  // inside the box: rays start in the volume
    inside.eye = {0.1, 0.05, -0.1};
    inside.fov_y = 90;
    Camera ortho_view = ortho({0, 0, 2}, {0, 1, 0}, 37, 23, 1.6);  // wider than the box: misses
    s.cameras = {s.cameras[0], side, inside, ortho_view};
    for (double step : {0.5, 0.3})
      expect_same(s, step, "calibration, step " + std::to_string(step));

    Scene opaque = s;  // most rays terminate early, at different samples in a packet
    for (TfPoint& p : opaque.tf.points) p.extinction *= 40;
    expect_same(opaque, 0.5, "early termination");
    opaque.integrator.min_transmittance = 0;
    expect_same(opaque, 0.5, "no early termination");
  }
}

TEST(RenderPacket, TransferFunctionEdgeCases) {
  Scene s = calibration_scene(16, 8);
  s.cameras[0].width = 19;
  s.cameras[0].height = 11;
  // Densities exactly on the points: a volume of the points' densities and values between.
  for (std::size_t i = 0; i < s.volume.data.size(); ++i)
    s.volume.data[i] = float(std::vector<double>{0.35, 0.55, 0.8, 0.45, 1.0}[i % 5]);
  expect_same(s, 0.5, "densities on the points");
  Scene two = s;
  two.tf.points = {{0.2, {1, 0.5, 0.2}, 4}, {0.9, {0.2, 0.4, 1}, 12}};
  expect_same(two, 0.5, "two points");
  Scene one = s;
  one.tf.points = {{0.5, {0.3, 0.6, 0.9}, 3}};
  expect_same(one, 0.5, "one point");
}

AdjointGradient gradient_with(const Scene& scene, const Image& target, bool packet) {
  const ScopedEnv env("IVR_PACKET", packet ? "1" : "0");
  AdjointOptions o;
  o.step = 0.5;
  o.tf = o.background = true;
  o.empty_space = EmptySpace::off;
  o.deterministic = true;  // the density gradient's sums in fixed point: comparable bit for bit
  return adjoint(device(), scene, target, o);
}

TEST(RenderPacket, GradientFromThePacketPrimalIsTheSame) {
  Scene s = calibration_scene(16, 8);
  s.cameras[0].width = 21;
  s.cameras[0].height = 13;
  Camera side = s.cameras[0];
  side.eye = {0.2, -1.4, 0.3};
  s.cameras.push_back(side);
  Scene wall = s;  // an opaque wall: behind it C minus the prefix must be exactly the background
  for (int z = 6; z < 9; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) wall.volume.data[(std::size_t(z) * 16 + y) * 16 + x] = 1.f;
  for (TfPoint& p : wall.tf.points) p.extinction *= 50;
  Scene no_stop = wall;
  no_stop.integrator.min_transmittance = 0;
  for (const auto& [scene, what] : {std::pair{s, "calibration"}, std::pair{wall, "opaque wall"},
                                    std::pair{no_stop, "opaque wall, no early termination"}}) {
    Image target = render_at(scene, Precision::f32, 0.5);
    for (std::size_t i = 0; i < target.pixels.size(); ++i)
      target.pixels[i] -= 0.1f + 0.05f * float(i % 4);
    const AdjointGradient a = gradient_with(scene, target, true), b = gradient_with(scene, target, false);
    EXPECT_EQ(a.loss, b.loss) << what;
    EXPECT_EQ(a.samples, b.samples) << what;
    EXPECT_EQ(a.density, b.density) << what;
    EXPECT_EQ(a.background, b.background) << what;
    // The TF rows keep float atomics, whose order varies from run to run: to their rounding.
    ASSERT_EQ(a.tf.size(), b.tf.size()) << what;
    double tf_largest = 0;
    for (double g : b.tf) tf_largest = std::max(tf_largest, std::abs(g));
    for (std::size_t i = 0; i < a.tf.size(); ++i)
      EXPECT_NEAR(a.tf[i], b.tf[i], 1e-6 * tf_largest) << what << " tf " << i;
    double largest = 0;
    for (float g : a.density) largest = std::max(largest, double(std::abs(g)));
    EXPECT_GT(largest, 0) << what;
  }
}

}  // namespace
}  // namespace ivr::test
