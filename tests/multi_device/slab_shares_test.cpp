// slab_shares_test.cpp — slabs sized by weight (domain_slab with shares; docs/scaling.md): the
// split's closed forms and its largest-remainder bound over random weights, slabs joined by their
// sizes, and several devices' weighted slabs (here separate contexts on the test device) equal to
// one device's render and gradients, the weights visibly moving the slabs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "brick/brick_support.hpp"
#include "brick/domain_support.hpp"
#include "ivr/domain.hpp"
#include "ivr/gradient.hpp"
#include "ivr/render.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

std::vector<Slab> slabs_of(int nz, const std::vector<double>& shares) {
  std::vector<Slab> out;
  for (int r = 0; r < int(shares.size()); ++r)
    out.push_back(domain_slab(nz, r, int(shares.size()), shares));
  return out;
}

void expect_slabs(int nz, const std::vector<double>& shares,
                  const std::vector<std::array<int, 2>>& want) {
  const std::vector<Slab> got = slabs_of(nz, shares);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t r = 0; r < want.size(); ++r) {
    EXPECT_EQ(got[r].first, want[r][0]) << "nz " << nz << ", worker " << r;
    EXPECT_EQ(got[r].last, want[r][1]) << "nz " << nz << ", worker " << r;
  }
}

// Closed forms (the cells nz − 1 split by largest remainder), equal weights the equal split, and
// over random weights: the slabs tile the planes, each worker at least one cell, and each within
// one cell of its quota wherever every quota is at least one.
TEST(SlabShares, ClosedFormsAndRandomWeights) {
  expect_slabs(13, {1, 3}, {{{0, 3}, {3, 12}}});            // quotas 3, 9
  expect_slabs(12, {1, 3}, {{{0, 3}, {3, 11}}});            // 2.75, 8.25: the .75 takes the one left
  expect_slabs(13, {1, 1, 2}, {{{0, 3}, {3, 6}, {6, 12}}});  // 3, 3, 6
  expect_slabs(4, {1, 1000}, {{{0, 1}, {1, 3}}});           // one cell each first
  for (int nz : {2, 7, 13, 100}) {  // equal weights: the near-equal runs, as without weights
    for (int ranks = 1; ranks <= std::min(nz - 1, 5); ++ranks)
      for (int r = 0; r < ranks; ++r) {
        const Slab a = domain_slab(nz, r, ranks), b = domain_slab(nz, r, ranks, std::vector<double>(std::size_t(ranks), 2.5));
        EXPECT_EQ(a.first, b.first);
        EXPECT_EQ(a.last, b.last);
        const Slab c = domain_slab(nz, r, ranks, {});
        EXPECT_EQ(a.first, c.first);
        EXPECT_EQ(a.last, c.last);
      }
  }
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> planes(2, 300), workers(1, 6);
  std::uniform_real_distribution<double> weight(-3, 3);
  for (int trial = 0; trial < 300; ++trial) {
    const int nz = planes(rng);
    const int ranks = std::min(workers(rng), nz - 1);
    std::vector<double> w(static_cast<std::size_t>(ranks));
    double total = 0;
    for (double& x : w) total += (x = std::pow(10.0, weight(rng)));
    const std::vector<Slab> s = slabs_of(nz, w);
    bool floor_each = false;
    for (double x : w) floor_each = floor_each || (nz - 1) * x / total < 1;
    int at = 0;
    for (int r = 0; r < ranks; ++r) {
      EXPECT_EQ(s[std::size_t(r)].first, at) << "trial " << trial;
      const int cells = s[std::size_t(r)].last - s[std::size_t(r)].first;
      EXPECT_GE(cells, 1) << "trial " << trial;
      if (!floor_each)
        EXPECT_LT(std::abs(cells - (nz - 1) * w[std::size_t(r)] / total), 1.0)
            << "trial " << trial << ", worker " << r;
      at = s[std::size_t(r)].last;
    }
    EXPECT_EQ(at, nz - 1) << "trial " << trial;
  }
  expect_error([] { domain_slab(13, 0, 2, {1}); }, Status::invalid_argument, "1 shares for 2 workers");
  expect_error([] { domain_slab(13, 1, 2, {1, 0}); }, Status::invalid_argument, "shares[1]");
  expect_error([] { domain_slab(13, 0, 2, {1, std::numeric_limits<double>::quiet_NaN()}); },
               Status::invalid_argument, "shares[1]");
  expect_error([] { domain_slab(3, 0, 3, {1, 2, 3}); }, Status::invalid_argument,
               "at most one worker per cell");
}

// A weighted worker's share holds its planes; domain_assemble and domain_join place each slab by
// its size (consecutive slabs share a plane), and slabs that do not tile the planes are refused.
TEST(SlabShares, SharesJoinByTheirSizes) {
  Scene s;
  s.volume.nx = 3, s.volume.ny = 2, s.volume.nz = 13;
  set_default_box(s);
  for (std::size_t i = 0; i < s.volume.voxel_count(); ++i) s.volume.data.push_back(float(i));
  const std::size_t plane = 6;
  const std::vector<double> w = {1, 3};
  std::vector<std::vector<double>> slabs;
  for (int r = 0; r < 2; ++r) {
    const Scene part = domain_share(s, r, 2, w);
    const Slab slab = domain_slab(13, r, 2, w);
    ASSERT_EQ(part.volume.data.size(), plane * std::size_t(slab.planes()));
    EXPECT_EQ(part.volume.data.front(), float(plane * std::size_t(slab.first)));
    slabs.emplace_back(part.volume.data.begin(), part.volume.data.end());
  }
  EXPECT_EQ(slabs[0].size(), 4 * plane);  // planes 0..3
  EXPECT_EQ(slabs[1].size(), 10 * plane);  // planes 3..12
  const std::vector<double> whole = domain_assemble(3, 2, 13, slabs);
  const std::vector<double> joined = domain_join(3, 2, 13, slabs);
  for (std::size_t i = 0; i < whole.size(); ++i) {
    EXPECT_EQ(whole[i], double(i)) << i;
    EXPECT_EQ(joined[i], (i / plane == 3 ? 2.0 : 1.0) * double(i)) << i;  // the shared plane summed
  }
  expect_error([&] { domain_assemble(3, 2, 13, {slabs[0], std::vector<double>(9 * plane)}); },
               Status::invalid_argument, "worker 1");  // planes 3..11: short of the last
  expect_error([&] { domain_join(3, 2, 13, {std::vector<double>(13 * plane), slabs[1]}); },
               Status::invalid_argument, "worker 0");  // the first takes every plane
  expect_error([&] { domain_join(3, 2, 13, {std::vector<double>(4 * plane + 1), slabs[1]}); },
               Status::invalid_argument, "it needs 2 to 12 whole planes of 6 values");
}

// Two devices weighted 1:5 (slabs of 2 and 10 of the 12 cells) against one device: the image and
// the density and TF gradients, over states and segments; the weights move the slabs — bricks of
// 5 cells inside them number 2 + 4 per xy-column over equal slabs of 6, 1 + 2 over 2 and 10.
TEST(SlabShares, DevicesByWeightEqualOneDevice) {
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const double tol = p == Precision::f64 ? 1e-10 : 1e-4;
  const auto devices = device_contexts(2);
  for (SlabMarch march : {SlabMarch::states, SlabMarch::segments}) {
    Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);  // 11 × 9 × 13
    if (march == SlabMarch::segments) s.integrator.min_transmittance = 0;
    const std::string what = march == SlabMarch::states ? "states" : "segments";
    RenderOptions ro;
    ro.precision = p;
    const Image one = render(device(), s, ro);
    ro.volume_brick = 5;  // (x: 10 cells, 2 bricks; y: 8 cells, 2 bricks)
    RenderStats equal, weighted;
    const Image even = render_domain(pointers_to(devices), s, march, ro, &equal);
    ro.shares = {1, 5};
    const Image many = render_domain(pointers_to(devices), s, march, ro, &weighted);
    expect_same(one, even, tol, what + ", equal");
    expect_same(one, many, tol, what + ", 1:5");
    EXPECT_EQ(equal.bricks, 4 * (2 + 2)) << what;
    EXPECT_EQ(weighted.bricks, 4 * (1 + 2)) << what;

    const Image target = dimmed(one);
    GradientOptions go;
    go.precision = p;
    go.mode = Mode::adjoint;
    const std::vector<std::string> groups = {"density", "tf"};
    const Gradient g1 = gradient(device(), s, target, groups, go);
    go.shares = {5, 1};
    const Gradient gm = gradient_domain(pointers_to(devices), s, target, march, go, nullptr, groups);
    EXPECT_NEAR(gm.loss, g1.loss, tol * g1.loss) << what;
    ASSERT_EQ(gm.groups.size(), groups.size()) << what;
    for (std::size_t k = 0; k < groups.size(); ++k)
      expect_close_values(g1.groups[k].values, gm.groups[k].values, tol, what + " " + groups[k]);
  }
  RenderOptions bad;
  bad.shares = {1, 2, 3};
  expect_error([&] {
    render_domain(pointers_to(devices), bricked_scene(Model::emission_absorption, Scheme::midpoint),
                  SlabMarch::states, bad);
  }, Status::invalid_argument, "3 weights for 2 devices");
}

}  // namespace
}  // namespace ivr::test
