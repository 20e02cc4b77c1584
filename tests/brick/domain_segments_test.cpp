// domain_segments_test.cpp — domain-parallel over independent segments (SlabMarch::segments,
// lib/brick/domain_segments.cpp): workers on threads march their slabs' segments of every ray at
// once, composite them after one exchange, and give one process's image and density, TF and
// background gradients (early termination off; with it on, within its threshold).
#include <gtest/gtest.h>

#include "brick_support.hpp"
#include "domain_support.hpp"
#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

DomainPart over_segments(const DomainPart& part) {
  DomainPart p = part;
  p.march = SlabMarch::segments;
  return p;
}

std::string label(Model model, Scheme scheme, Precision p, int ranks, int edge) {
  return std::string(model == Model::absorption ? "absorption " : "emission ") +
         scheme_name(scheme) + " " + name(p) + ", " + std::to_string(ranks) + " workers, bricks " +
         std::to_string(edge);
}

// Every scheme and model: the workers' segments composited equal the unsplit march, with slabs of
// several bricks (rays meet a slab's bricks in turn) and of one, and rays from inside the volume.
TEST(DomainSegments, RenderEqualsOneProcessForEveryScheme) {
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Scheme scheme :
         {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact}) {
      if (scheme == Scheme::exact && model != Model::absorption) continue;  // absorption only
      Scene s = bricked_scene(model, scheme);
      s.integrator.min_transmittance = 0;  // (early termination: below)
      for (Precision p : {Precision::f64, Precision::f32}) {
        if (p == Precision::f64 && !device().info().fp64) continue;
        if (p == Precision::f32 && scheme != Scheme::midpoint) continue;  // (CI time)
        RenderOptions o;
        o.precision = p;
        const Image one = render(device(), s, o);
        for (const std::pair<int, int>& c : {std::pair<int, int>{2, 3}, std::pair<int, int>{4, 0}}) {
          const int ranks = c.first;
          o.volume_brick = c.second;
          const std::string what = label(model, scheme, p, ranks, c.second);
          std::vector<DomainStats> ds(ranks);
          std::vector<RenderStats> st(ranks);
          const std::vector<Image> images =
              on_workers<Image>(ranks, [&](int w, const DomainPart& part, Device& d) {
                return render_domain(d, domain_share(s, w, ranks), over_segments(part), o, &st[w],
                                     &ds[w]);
              });
          expect_same(one, images[0], p == Precision::f64 ? 1e-12 : 1e-5, what);
          for (int w = 0; w < ranks; ++w) {
            EXPECT_EQ(images[w].pixels, images[0].pixels) << what << ": worker " << w;
            EXPECT_EQ(images[w].pixels_f64, images[0].pixels_f64) << what << ": worker " << w;
            // One exchange of the segments, whatever the slabs; every worker sent some.
            EXPECT_EQ(ds[w].exchanges, 1) << what << ": worker " << w;
            EXPECT_GT(ds[w].sent_bytes, 0u) << what << ": worker " << w;
            EXPECT_EQ(st[w].samples, st[0].samples) << what;
          }
        }
      }
    }
}

// A ray list (rays from inside and outside the volume, ends inside the box and infinite) over
// three workers.
TEST(DomainSegments, RayListEqualsOneProcess) {
  if (!device().info().fp64) GTEST_SKIP() << "no float64 on this device";
  Scene s = bricked_scene(Model::emission_absorption, Scheme::trapezoid);
  s.integrator.min_transmittance = 0;
  const std::vector<double> rows = random_ray_rows(97, 3);
  s.rays = make_ray_list(rows.data(), 97, 8);
  s.cameras.clear();
  RenderOptions o;
  o.precision = Precision::f64;
  const Image one = render(device(), s, o);
  const std::vector<Image> images =
      on_workers<Image>(3, [&](int w, const DomainPart& part, Device& d) {
        return render_domain(d, domain_share(s, w, 3), over_segments(part), o);
      });
  expect_same(one, images[0], 1e-12, "ray list, 3 workers");
  // The rays' own columns (one pass of 8 forward lanes a ray), their segments' tangents
  // composited, against one process's.
  Image target = one;
  for (float& v : target.pixels) v = 0.8f * v + 0.05f;
  GradientOptions go;
  go.precision = Precision::f64;
  const Gradient g1 = gradient(device(), s, target, {"rays"}, go);
  const std::vector<Gradient> parts =
      on_workers<Gradient>(3, [&](int w, const DomainPart& part, Device& d) {
        return gradient_domain(d, domain_share(s, w, 3), target, over_segments(part), go, nullptr,
                               {"rays"});
      });
  expect_close_values(g1.groups.at(0).values, parts[0].groups.at(0).values, 1e-10,
                      "ray list's rays, 3 workers");
}

// With early termination on, a segment stops where its own transmittance falls below the
// threshold, so a ray goes on where the unsplit march stopped: the images differ by less than the
// threshold times the brightest emission plus the background (the radiance behind).
TEST(DomainSegments, EarlyTerminationStaysWithinItsThreshold) {
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  s.integrator.min_transmittance = 1e-3;
  RenderOptions o;
  o.precision = p;
  const Image one = render(device(), s, o);
  const std::vector<Image> images =
      on_workers<Image>(3, [&](int w, const DomainPart& part, Device& d) {
        return render_domain(d, domain_share(s, w, 3), over_segments(part), o);
      });
  double worst = 0;
  for (std::size_t i = 0; i < one.pixels.size(); ++i)
    worst = std::max(worst, std::abs(double(one.pixels[i]) - double(images[0].pixels[i])));
  EXPECT_LE(worst, 1e-3 * (1.0 + 0.3) + 1e-6);  // (emission ≤ 1 a channel, background ≤ 0.3)
  EXPECT_GT(worst, 0.0) << "no ray stopped early: the test's threshold does not bite";
}

// The density, TF and background gradients: each worker's adjoint starts its segments from the
// composited transmittance and radiance in front of them.
TEST(DomainSegments, GradientEqualsOneProcess) {
  for (Scheme scheme :
       {Scheme::midpoint, Scheme::exact, Scheme::trapezoid, Scheme::preintegrated})
    for (Model model : {Model::emission_absorption, Model::absorption}) {
      if (scheme == Scheme::exact && model != Model::absorption) continue;
      if (scheme == Scheme::preintegrated && model == Model::absorption) continue;  // (CI time)
      const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
      Scene s = bricked_scene(model, scheme);
      s.integrator.min_transmittance = 0;
      Image target = render(device(), s);
      for (float& v : target.pixels) v = 0.8f * v + 0.05f;
      GradientOptions o;
      o.precision = p;
      o.mode = Mode::adjoint;
      const std::vector<std::string> groups = {"density", "tf", "background"};
      const Gradient one = gradient(device(), s, target, groups, o);
      const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
      for (int ranks : {2, 3}) {
        const std::string what = label(model, scheme, p, ranks, 0);
        // (Two workers with slabs of several bricks, three with one brick each.)
        ScopedEnv brick("IVR_VOLUME_BRICK", ranks == 2 ? "3" : "");
        const std::vector<Gradient> parts =
            on_workers<Gradient>(ranks, [&](int w, const DomainPart& part, Device& d) {
              return gradient_domain(d, domain_share(s, w, ranks), target, over_segments(part), o,
                                     nullptr, groups);
            });
        std::vector<std::vector<double>> slabs;
        std::vector<double> tf(one.groups[1].values.size(), 0.0);  // the workers' parts summed
        for (int w = 0; w < ranks; ++w) {
          ASSERT_EQ(parts[w].groups.size(), 3u) << what;
          slabs.push_back(parts[w].groups[0].values);
          ASSERT_EQ(parts[w].groups[1].values.size(), tf.size()) << what;
          for (std::size_t i = 0; i < tf.size(); ++i) tf[i] += parts[w].groups[1].values[i];
          EXPECT_NEAR(parts[w].loss, one.loss, tol * std::abs(one.loss) + 1e-15) << what;
          EXPECT_EQ(parts[w].groups[2].values, parts[0].groups[2].values) << what;
        }
        expect_close_values(one.groups[0].values,
                            domain_join(s.volume.nx, s.volume.ny, s.volume.nz, slabs), tol,
                            what + " density");
        expect_close_values(one.groups[1].values, tf, tol, what + " tf");
        expect_close_values(one.groups[2].values, parts[0].groups[2].values, tol,
                            what + " background");
      }
    }
}

}  // namespace
}  // namespace ivr::test
