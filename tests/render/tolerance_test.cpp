// tolerance_test.cpp — error-targeted stepping: the step chosen for a tolerance keeps the image's
// relative RMS error against the continuous integral below it, is not smaller than needed by more
// than 4×, is the step renders and gradients then use, and bad tolerances are clear errors.
#include "ivr/tolerance.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "reference/reference.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// A smooth blob with a sharper rim through a TF with kinks, two perspective views.
Scene blob_scene(Model model, Scheme scheme) {
  Scene s;
  const int n = 24;
  s.volume.nx = s.volume.ny = s.volume.nz = n;
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        auto c = [&](int i) { return 2.0 * (i + 0.5) / n - 1.0; };
        const double r = std::sqrt(c(x) * c(x) + 1.3 * c(y) * c(y) + 0.8 * c(z) * c(z));
        s.volume.data.push_back(
            float(0.9 * std::exp(-3 * r * r) + 0.3 / (1 + std::exp((r - 0.7) / 0.05))));
      }
  set_default_box(s);
  s.model = model;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.1, {0.2, 0.3, 0.9}, 0.0}, {0.4, {0.9, 0.6, 0.2}, 12.0}, {1.0, {1, 1, 1}, 30.0}};
  s.background = glm::dvec3(0.1, 0.1, 0.15);
  Camera a, b;
  a.eye = {1.3, 0.6, 1.5};
  b.eye = {-1.6, -0.4, 0.6};
  a.width = a.height = b.width = b.height = 40;
  s.cameras = {a, b};
  s.integrator.scheme = scheme;
  s.integrator.min_transmittance = 0;
  return s;
}

double relative_rms(const std::vector<float>& got, const std::vector<double>& want) {
  double d = 0, n = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    d += (double(got[i]) - want[i]) * (double(got[i]) - want[i]);
    n += want[i] * want[i];
  }
  return std::sqrt(d / n);
}

TEST(Tolerance, ErrorBelowTheToleranceAndStepWithinFourTimesOfNeeded) {
  for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated})
    for (Model model : {Model::emission_absorption, Model::absorption}) {
      const Scene s = blob_scene(model, scheme);
      const std::vector<double> exact = reference::render_continuous(s);
      for (double tolerance : {1e-2, 1e-3}) {
        SCOPED_TRACE(std::string(scheme_name(scheme)) +
                     (model == Model::absorption ? " absorption" : " emission") + " tolerance " +
                     std::to_string(tolerance));
        const StepChoice c = choose_step(device(), s, tolerance);
        EXPECT_TRUE(c.reached);
        EXPECT_GT(c.pilots, 0);
        const auto error_at = [&](double step) {
          return relative_rms(render_at(s, Precision::f32, step).pixels, exact);
        };
        const double e = error_at(c.step);
        EXPECT_LT(e, tolerance) << "step " << c.step;
        // The step needed: the largest that still meets the tolerance (on a 1.25× ladder).
        double needed = c.step;
        while (needed < kToleranceMaxStep && error_at(needed * 1.25) < tolerance) needed *= 1.25;
        EXPECT_LE(needed, 4 * c.step) << "chosen " << c.step << ", needed " << needed;
        std::printf("[ measured ] %s %s tolerance %g: step %.3f (needed %.3f), error %.2e\n",
                    scheme_name(scheme), model == Model::absorption ? "absorption" : "emission",
                    tolerance, c.step, needed, e);
      }
    }
}

TEST(Tolerance, RendersAndGradientsUseTheChosenStep) {
  Scene s = blob_scene(Model::emission_absorption, Scheme::midpoint);
  s.integrator.tolerance = 1e-3;
  const StepChoice c = choose_step(device(), s, 1e-3);
  RenderStats stats;
  const Image image = render(device(), s, {}, &stats);
  EXPECT_DOUBLE_EQ(stats.step, c.step);
  EXPECT_DOUBLE_EQ(stats.estimated_error, c.estimated_error);
  EXPECT_EQ(stats.scheme, "midpoint");
  // The same image as a render at that step; an explicit step overrides the tolerance.
  const Image fixed = render_at(s, Precision::f32, c.step);
  EXPECT_EQ(image.pixels, fixed.pixels);
  RenderStats overridden;
  render(device(), s, {Precision::f32, 0.7}, &overridden);
  EXPECT_EQ(overridden.step, 0.7);
  AdjointOptions o;
  EXPECT_DOUBLE_EQ(adjoint(device(), s, image, o).step, c.step);
  EXPECT_DOUBLE_EQ(jacobian(device(), s, parameters_of(s, "background"), &image).step, c.step);
}

TEST(Tolerance, ExactNeedsNoStepAndBadTolerancesAreErrors) {
  Scene s = blob_scene(Model::absorption, Scheme::exact);
  s.integrator.step = 0.8;
  const StepChoice c = choose_step(device(), s, 1e-4);
  EXPECT_EQ(c.step, 0.8);
  EXPECT_EQ(c.pilots, 0);
  EXPECT_THROW(choose_step(device(), s, 0), Error);
  EXPECT_THROW(choose_step(device(), s, -1e-3), Error);
  EXPECT_THROW(choose_step(device(), s, NAN), Error);
  s.integrator.tolerance = -1;
  try {
    render(device(), s);
    ADD_FAILURE() << "rendered with a negative tolerance";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("integrator.tolerance"), std::string::npos) << e.what();
  }
}

TEST(Tolerance, CommandLine) {
  const std::string dir = temp_dir("tolerance_cli");
  const std::string scene = write_file(dir + "/scene.json", R"({
    "volume": {"synthetic": "sphere", "dims": [24, 24, 24]}, "model": "emission_absorption",
    "tf": {"type": "piecewise_linear", "points": [
      {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0},
      {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
    "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 24, "height": 24}],
    "integrator": {"scheme": "trapezoid", "tolerance": 0.003}})");
  CliResult r = run_cli("render '" + scene + "' -o '" + dir + "/a.npy' --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("\"scheme\":\"trapezoid\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"tolerance\":{\"estimated_error\""), std::string::npos) << r.out;
  r = run_cli("render '" + scene + "' -o '" + dir + "/b.npy' --tolerance 0 --json");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--tolerance must be > 0"), std::string::npos) << r.err;
  r = run_cli("render '" + scene + "' -o '" + dir + "/c.npy' --scheme exact");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("'exact' integrates the absorption model only"), std::string::npos) << r.err;
  r = run_cli("render '" + scene + "' -o '" + dir + "/d.npy' --scheme simpson");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--scheme: unknown scheme 'simpson'"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace ivr::test
