// bricked_fixed_test.cpp — the deterministic (fixed-point) density gradient out of core and over
// slabs (lib/brick/bricked_fixed.cpp): the same bits on every run, near the float gradient and the
// in-core fixed-point one, a second pass where the a-priori scale fails or is far too loose, and
// the TF gradient untouched.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "brick_support.hpp"
#include "domain_support.hpp"
#include "ivr/domain.hpp"
#include "ivr/gradient.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// Fixed point rounds each contribution to 2^−S: within this of the float sums, relative to the
// largest entry (the a-priori scale keeps at least 24 bits of the largest contribution).
double fixed_tolerance(Precision p) {
  return p == Precision::f64 ? 1e-7 : 1e-5;
}

bool int64_atomics() {
  return has_int64_atomics(device().impl());
}

GradientOptions adjoint_options(Precision p) {
  GradientOptions o;
  o.precision = p;
  o.mode = Mode::adjoint;
  return o;
}

Image target_of(const Scene& s) {
  Image target = render(device(), s);
  for (float& v : target.pixels) v = 0.8f * v + 0.05f;
  return target;
}

// How many entries of `got` differ from `want` in their bits (0: the same gradient).
std::size_t differing(const std::vector<double>& want, const std::vector<double>& got) {
  if (want.size() != got.size()) return std::max(want.size(), got.size());
  std::size_t n = 0;
  for (std::size_t i = 0; i < want.size(); ++i)
    n += std::memcmp(&want[i], &got[i], sizeof(double)) != 0;
  return n;
}

// Each contribution is its integer before any sum, the scale and cap are the in-core ones and the
// sums run on across the bricks (kernels/adjoint_scatter.cl), and the exact scheme's pieces are cut
// in the whole volume's coordinates (kernels/exact.cl): out of core the fixed-point gradient is
// the in-core one bit for bit, for every scheme, both models, bricks of one cell to many, rays on
// the bricks' faces (bricked_scene's orthographic views).
TEST(BrickedFixed, DensityGradientOutOfCoreIsTheInCoreOneBitForBit) {
  if (!int64_atomics()) GTEST_SKIP() << "no cl_khr_int64_base_atomics: float sums";
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Scheme scheme :
         {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact})
      for (Precision p : {Precision::f64, Precision::f32}) {
        if (p == Precision::f64 && !device().info().fp64) continue;
        if (model == Model::absorption && scheme == Scheme::preintegrated) continue;
        if (model == Model::emission_absorption && scheme == Scheme::exact) continue;
        const Scene s = bricked_scene(model, scheme);
        const Image target = target_of(s);
        GradientOptions o = adjoint_options(p);
        const Gradient floats = gradient(device(), s, target, {"density", "tf"}, o);
        o.deterministic = true;
        const Gradient in_core = gradient(device(), s, target, {"density", "tf"}, o);
        ASSERT_TRUE(in_core.deterministic);
        ASSERT_EQ(in_core.bricks, 1);
        expect_close_values(floats.groups[0].values, in_core.groups[0].values, fixed_tolerance(p),
                            "in core against the float sums");
        for (const char* edge : {"1", "3", "4"}) {
          const std::string what =
              std::string(model == Model::absorption ? "absorption " : "emission ") +
              scheme_name(scheme) + " " + name(p) + ", bricks of " + edge;
          ScopedEnv brick("IVR_VOLUME_BRICK", edge);
          const Gradient a = gradient(device(), s, target, {"density", "tf"}, o);
          EXPECT_GT(a.bricks, 1) << what;
          EXPECT_TRUE(a.deterministic) << what;
          EXPECT_EQ(differing(in_core.groups[0].values, a.groups[0].values), 0u)
              << what << ": voxels whose bits differ from the in-core fixed point";
          // The TF gradient keeps its float sums (within the float comparison's tolerance).
          expect_close_values(floats.groups[1].values, a.groups[1].values,
                              p == Precision::f64 ? 1e-12 : 1e-5, what + " tf");
        }
      }
}

// A scale the bound set too fine (rays over the cap) or too coarse (fewer than 24 bits kept) is
// corrected by a second pass at the scale the largest segment calls for: the same bits either way.
TEST(BrickedFixed, SecondPassCorrectsTheScale) {
  if (!int64_atomics()) GTEST_SKIP() << "no cl_khr_int64_base_atomics: float sums";
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const Scene s = bricked_scene(Model::absorption, Scheme::midpoint);
  const Image target = target_of(s);
  GradientOptions o = adjoint_options(p);
  const Gradient floats = gradient(device(), s, target, {"density"}, o);
  o.deterministic = true;
  ScopedEnv brick("IVR_VOLUME_BRICK", "3");
  std::vector<std::vector<double>> got;
  for (const char* shift : {"-40", "40"}) {
    ScopedEnv bound("IVR_FIXED_BOUND_SHIFT", shift);
    const Gradient g = gradient(device(), s, target, {"density"}, o);
    EXPECT_TRUE(g.deterministic) << shift;
    expect_close_values(floats.groups[0].values, g.groups[0].values, fixed_tolerance(p),
                        std::string("bound shifted by 2^") + shift);
    got.push_back(g.groups[0].values);
  }
  EXPECT_EQ(got[0], got[1]) << "the second passes' scales differ";
}

// Over slabs every worker takes the in-core scale and the planes two workers hold are summed as
// integers by their owner: with the rays' states passed, the joined gradient is one process's
// in-core fixed point bit for bit (midpoint without a halo of its own, trapezoid with one, the
// exact scheme's pieces in global coordinates; both precisions). Over independent segments (each
// slab's segment of a ray from transmittance 1) it repeats bit for bit and lies near one process's.
TEST(BrickedFixed, OverSlabsIsOneProcesssBitForBit) {
  if (!int64_atomics()) GTEST_SKIP() << "no cl_khr_int64_base_atomics: float sums";
  for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::exact})
    for (Precision p : {Precision::f64, Precision::f32}) {
      if (p == Precision::f64 && !device().info().fp64) continue;
      Scene s = bricked_scene(
          scheme == Scheme::exact ? Model::absorption : Model::emission_absorption, scheme);
      s.integrator.min_transmittance = 0;  // (segments: one process's march)
      const Image target = target_of(s);
      GradientOptions o = adjoint_options(p);
      const Gradient floats = gradient(device(), s, target, {"density"}, o);
      o.deterministic = true;
      const Gradient in_core = gradient(device(), s, target, {"density"}, o);
      for (SlabMarch march : {SlabMarch::states, SlabMarch::segments}) {
        const std::string what = std::string(scheme_name(scheme)) + " " + name(p) +
                                 (march == SlabMarch::states ? " states" : " segments");
        std::vector<std::vector<double>> joined;
        for (int run = 0; run < 2; ++run) {
          const std::vector<Gradient> parts = on_workers<Gradient>(3, [&](int w, DomainPart part,
                                                                          Device& d) {
            part.march = march;
            return gradient_domain(d, domain_share(s, w, 3), target, part, o, nullptr, {"density"});
          });
          std::vector<std::vector<double>> slabs;
          for (const Gradient& g : parts) {
            EXPECT_TRUE(g.deterministic) << what;
            slabs.push_back(g.groups.at(0).values);
          }
          joined.push_back(domain_join(11, 9, 13, slabs));
        }
        EXPECT_EQ(joined[0], joined[1]) << what << ": not the same bits";
        if (march == SlabMarch::states)
          EXPECT_EQ(differing(in_core.groups[0].values, joined[0]), 0u)
              << what << ": voxels whose bits differ from one process's in-core fixed point";
        expect_close_values(floats.groups[0].values, joined[0], fixed_tolerance(p), what);
      }
    }
}

}  // namespace
}  // namespace ivr::test
