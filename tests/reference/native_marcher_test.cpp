// native_marcher_test.cpp — the native CPU baseline (bench/native_marcher) against ivr: its render
// and hand-written adjoint gradient agree with the kernels', and the adjoint with central
// differences of its own render.
#include "reference/native_marcher.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "adjoint/adjoint_support.hpp"
#include "ivr/calibrate.hpp"

namespace ivr::test {
namespace {

constexpr double kStep = 0.5;

// The mean squared error of two equal-sized float images, in float64.
double mse(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.size(); ++i) sum += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  return sum / double(a.size());
}

// A target the scene does not render: the ivr render of a volume moved by up to ±30 %.
Image target_for(const Scene& s) {
  Scene t = s;
  for (std::size_t i = 0; i < t.volume.data.size(); ++i)
    t.volume.data[i] = float(std::min(1.0, t.volume.data[i] * (1.0 + 0.3 * std::sin(double(i)))));
  return render_at(t, Precision::f32, kStep);
}

// native_gradient against ivr::gradient (float32, density only, no empty-space skipping so that
// both take the same samples): per entry within 1e-4 of the largest plus 1e-7, loss within 1e-6.
void expect_gradient_matches_ivr(const Scene& s) {
  const Image target = target_for(s);
  AdjointOptions o;
  o.precision = Precision::f32;
  o.step = kStep;
  o.empty_space = EmptySpace::off;
  const AdjointGradient want = adjoint(device(), s, target, o);
  std::vector<float> got;
  double loss = 0;
  const std::size_t samples = bench::native_gradient(s, kStep, target.pixels, got, loss);

  ASSERT_EQ(got.size(), want.density.size());
  EXPECT_NEAR(loss, want.loss, 1e-6 * want.loss);
  EXPECT_NEAR(double(samples), double(want.samples), 1e-4 * double(want.samples));
  const double scale = max_abs(want.density);
  ASSERT_GT(scale, 0);
  std::size_t bad = 0, worst = 0;
  double worst_error = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_TRUE(std::isfinite(got[i])) << "voxel " << i;
    const double e = std::abs(double(got[i]) - want.density[i]);
    if (e > 1e-4 * scale + 1e-7) ++bad;
    if (e > worst_error) worst_error = e, worst = i;
  }
  EXPECT_EQ(bad, 0u) << "largest error " << worst_error << " at voxel " << worst << " (native "
                     << got[worst] << ", ivr " << want.density[worst] << ", largest entry " << scale
                     << ")";
}

TEST(NativeMarcher, RenderMatchesIvr) {
  const Scene s = calibration_scene(32, 48);
  const Image want = render_at(s, Precision::f32, kStep);
  std::vector<float> got;
  const std::size_t samples = bench::native_render(s, kStep, got);
  EXPECT_GT(samples, 0u);
  ASSERT_EQ(got.size(), want.pixels.size());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < got.size(); ++i)
    if (!(std::abs(got[i] - want.pixels[i]) <= 1e-5 + 1e-4 * std::abs(want.pixels[i]))) {
      if (bad++ < 5)
        ADD_FAILURE() << "element " << i << ": native " << got[i] << ", ivr " << want.pixels[i];
    }
  EXPECT_EQ(bad, 0u);
}

TEST(NativeMarcher, GradientMatchesIvr) {
  expect_gradient_matches_ivr(calibration_scene(32, 48));
}

// Early termination: extinction ×20 stops most rays inside the volume (σ·dt up to ~9); the
// stopping decision has zero derivative and the adjoint march ends where the primal did.
TEST(NativeMarcher, GradientMatchesIvrWithEarlyTermination) {
  Scene s = calibration_scene(32, 48);
  for (TfPoint& p : s.tf.points) p.extinction *= 20;
  s.integrator.min_transmittance = 1e-3;
  Scene unstopped = s;
  unstopped.integrator.min_transmittance = 0;
  std::vector<float> image;
  const std::size_t stopped = bench::native_render(s, kStep, image);
  const std::size_t full = bench::native_render(unstopped, kStep, image);
  ASSERT_LT(double(stopped), 0.8 * double(full)) << "rays must stop early for this test";
  expect_gradient_matches_ivr(s);
}

// The directional derivative of the native loss along a smooth random direction: central
// differences of native_render (float32 images, losses in float64) against ⟨grad, direction⟩.
// Early termination off: where a ray stops is a discontinuity of the loss.
TEST(NativeMarcher, GradientMatchesCentralDifferences) {
  Scene s = calibration_scene(32, 48);
  s.integrator.min_transmittance = 0;
  const std::vector<float> target = target_for(s).pixels;
  std::vector<float> grad;
  double loss = 0;
  bench::native_gradient(s, kStep, target, grad, loss);

  const Volume& v = s.volume;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> phase(0, 2 * M_PI), freq(0.5, 2.0);
  const double ax = phase(rng), ay = phase(rng), az = phase(rng);
  const double fx = freq(rng), fy = freq(rng), fz = freq(rng);
  std::vector<double> direction(v.voxel_count());
  for (int z = 0; z < v.nz; ++z)
    for (int y = 0; y < v.ny; ++y)
      for (int x = 0; x < v.nx; ++x)
        direction[(std::size_t(z) * v.ny + y) * v.nx + x] =
            std::sin(2 * M_PI * fx * x / v.nx + ax) * std::cos(2 * M_PI * fy * y / v.ny + ay) *
            std::sin(2 * M_PI * fz * z / v.nz + az);

  // The losses either side, and the increments the float32 voxels actually received.
  const double h = 2e-3;
  auto loss_at = [&](double sign, std::vector<double>& applied) {
    Scene moved = s;
    applied.resize(direction.size());
    for (std::size_t i = 0; i < direction.size(); ++i) {
      moved.volume.data[i] = float(v.data[i] + sign * h * direction[i]);
      applied[i] = double(moved.volume.data[i]) - v.data[i];
    }
    std::vector<float> image;
    bench::native_render(moved, kStep, image);
    return mse(image, target);
  };
  std::vector<double> up, down;
  const double fd = loss_at(+1, up) - loss_at(-1, down);
  double want = 0;  // <grad, the step between the two volumes>
  for (std::size_t i = 0; i < grad.size(); ++i) want += double(grad[i]) * (up[i] - down[i]);
  EXPECT_GT(std::abs(want), 0);
  EXPECT_NEAR(fd, want, 0.02 * std::abs(want)) << "loss " << loss;
}

}  // namespace
}  // namespace ivr::test
