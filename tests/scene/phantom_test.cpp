// phantom_test.cpp — the tomography phantoms: Shepp–Logan values at hand-checked voxels, ellipsoid
// volumes by voxel counting, the rotation's sense, seeded generation, the synthetic scene
// volumes "shepp_logan" and "zeros", and the errors.
#include "ivr/phantom.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "ivr/error.hpp"
#include "ivr/scene.hpp"

namespace ivr {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Centre of voxel i of n over [-1, 1] (the header's convention).
double centre(int i, int n) {
  return -1.0 + (2.0 * i + 1.0) / n;
}

std::size_t count_above(const Volume& v, float threshold) {
  std::size_t count = 0;
  for (float d : v.data) count += d > threshold;
  return count;
}

template <class F>
Status status_of(F&& f, std::string* message) {
  try {
    f();
  } catch (const Error& e) {
    *message = e.what();
    return e.status();
  }
  return Status::ok;
}

TEST(Phantom, SheppLoganValuesAtHandCheckedVoxels) {
  const int n = 64;
  const Volume v = phantom("shepp-logan", n);
  ASSERT_EQ(v.nx, n);
  ASSERT_EQ(v.ny, n);
  ASSERT_EQ(v.nz, n);
  ASSERT_EQ(v.data.size(), std::size_t(n) * n * n);
  EXPECT_EQ(v.spacing, glm::dvec3(1.0));
  // (0.390625, 0.296875, 0.296875): inside the brain b, (x/0.6624)² + (y/0.874)² + (z/0.88)² =
  // 0.35 + 0.12 + 0.11; z is 0.55 above the features at z = -0.25 (c ≤ 0.5) and 0.33 below those
  // at z = 0.625 (c = 0.1): 2.0 - 0.98.
  EXPECT_FLOAT_EQ(v.at(44, 41, 41), 1.02f) << centre(44, n);
  // (0.0156, 0.8906, 0.0156): (y/0.92)² = 0.94 inside the skull a, y/0.874 = 1.02 outside b.
  EXPECT_FLOAT_EQ(v.at(32, 60, 32), 2.0f);
  // (0.0156, 0.1094, 0.6094): inside j, centred (0, 0.1, 0.625), semi-axes 0.056, 0.056, 0.1
  // (0.08 + 0.03 + 0.02 of 1); i is 0.2 away in y: 2.0 - 0.98 - 0.02.
  EXPECT_FLOAT_EQ(v.at(32, 35, 51), 1.0f);
  // (-0.3281, 0.2969, -0.2344): inside c (centre (-0.22, 0, -0.25), 108°), whose frame puts it
  // at (0.316, 0.011, 0.016) against semi-axes (0.41, 0.16, 0.21); the opposite rotation would
  // put it at y' = -0.19, outside: 2.0 - 0.98 - 0.02.
  EXPECT_FLOAT_EQ(v.at(21, 41, 24), 1.0f);
  // Outside the skull: the corners, and x = ±0.984 > 0.69 on the centre line.
  EXPECT_EQ(v.at(0, 0, 0), 0.0f);
  EXPECT_EQ(v.at(n - 1, n - 1, n - 1), 0.0f);
  EXPECT_EQ(v.at(n - 1, 32, 32), 0.0f);
  EXPECT_EQ(v.at(0, 32, 32), 0.0f);
  for (float d : v.data) ASSERT_TRUE(d >= 0.0f && d <= 2.0f) << d;
  // Everything lies inside the skull: the non-zero voxels fill its volume, 4/3 π abc (n/2)³.
  const double skull = 4.0 / 3.0 * kPi * 0.69 * 0.92 * 0.9 * std::pow(n / 2.0, 3);
  EXPECT_NEAR(double(count_above(v, 0.0f)), skull, 0.02 * skull);
}

TEST(Phantom, EllipsoidVolumeFromVoxelCount) {
  const int n = 64;
  const Ellipsoid e{0.1, -0.05, 0.02, 0.5, 0.3, 0.4, 30, 1.0};
  const Volume v = phantom_from_ellipsoids({e}, n);
  const double expected = 4.0 / 3.0 * kPi * e.a * e.b * e.c * std::pow(n / 2.0, 3);
  EXPECT_NEAR(double(count_above(v, 0.5f)), expected, 0.03 * expected);
  for (float d : v.data) ASSERT_TRUE(d == 0.0f || d == 1.0f) << d;
  // Overlapping ellipsoids add up.
  const Volume twice = phantom_from_ellipsoids({e, e}, n);
  for (std::size_t i = 0; i < v.data.size(); ++i) ASSERT_EQ(twice.data[i], 2 * v.data[i]) << i;
}

// Cell averages: a voxel wholly inside keeps the value, edge voxels fall in between, and the sum
// approaches the ellipsoid's analytic volume faster than point samples do.
TEST(Phantom, SupersampledVoxelsAreCellAverages) {
  const Ellipsoid e{0.05, -0.1, 0.02, 0.61, 0.43, 0.52, 20, 1.0};
  const int n = 24;
  const Volume point = phantom_from_ellipsoids({e}, n);
  EXPECT_EQ(phantom_from_ellipsoids({e}, n, 1).data, point.data);
  const Volume avg = phantom_from_ellipsoids({e}, n, 8);
  const double exact = 4.0 / 3.0 * kPi * e.a * e.b * e.c * std::pow(n / 2.0, 3);
  double sum_point = 0, sum_avg = 0;
  int partial = 0;
  for (std::size_t i = 0; i < avg.data.size(); ++i) {
    sum_point += point.data[i];
    sum_avg += avg.data[i];
    ASSERT_GE(avg.data[i], 0.0f);
    ASSERT_LE(avg.data[i], 1.0f);
    partial += avg.data[i] > 0 && avg.data[i] < 1;
  }
  EXPECT_GT(partial, 100);
  EXPECT_NEAR(sum_avg, exact, 0.005 * exact);
  EXPECT_LT(std::abs(sum_avg - exact), std::abs(sum_point - exact) + 1e-9);
  EXPECT_EQ(avg.at(n / 2, n / 2, n / 2), 1.0f);  // deep inside
  EXPECT_EQ(avg.at(0, 0, 0), 0.0f);              // far outside
  EXPECT_THROW(phantom_from_ellipsoids({e}, n, 0), Error);
  EXPECT_THROW(phantom("shepp-logan", 8, 1, 17), Error);
}

TEST(Phantom, RotationIsCounterClockwiseAboutZ) {
  // Long axis 0.8 at +30° from x: (0.51, 0.29, 0.01) is at x' = 0.59, y' = -0.004 (inside); its
  // mirror (0.51, -0.29, 0.01) is at y' = -0.51 against b = 0.2 (outside).
  const int n = 100;
  const Volume v = phantom_from_ellipsoids({{0, 0, 0, 0.8, 0.2, 0.2, 30, 1.0}}, n);
  ASSERT_NEAR(centre(75, n), 0.51, 1e-12);
  ASSERT_NEAR(centre(64, n), 0.29, 1e-12);
  EXPECT_EQ(v.at(75, 64, 50), 1.0f);
  EXPECT_EQ(v.at(75, 35, 50), 0.0f);
  // 90° swaps the roles of x and y.
  const Volume r = phantom_from_ellipsoids({{0, 0, 0, 0.8, 0.2, 0.2, 90, 1.0}}, n);
  EXPECT_EQ(r.at(50, 80, 50), 1.0f);  // (0.01, 0.61, 0.01)
  EXPECT_EQ(r.at(80, 50, 50), 0.0f);  // (0.61, 0.01, 0.01)
}

TEST(Phantom, NonCubicGridStretchesOverEachAxis) {
  const Volume v = phantom_from_ellipsoids(shepp_logan_ellipsoids(), 16, 64, 8);
  ASSERT_EQ(v.nx, 16);
  ASSERT_EQ(v.ny, 64);
  ASSERT_EQ(v.nz, 8);
  EXPECT_EQ(v.data.size(), std::size_t(16 * 64 * 8));
  // (0.0625, 0.890625, 0.125): 0.97 of the skull's quadratic form, 1.07 of the brain's.
  EXPECT_FLOAT_EQ(v.at(8, 60, 4), 2.0f);
  EXPECT_FLOAT_EQ(v.at(8, 32, 4), 1.02f);  // (0.0625, 0.015625, 0.125): brain
}

TEST(Phantom, RandomEllipsoidsAreSeededPortableAndInsideTheUnitBall) {
  // The first ellipsoid of seed 1, fixed on every platform (mt19937_64 and IEEE arithmetic only).
  const std::vector<Ellipsoid> e = random_ellipsoids(10, 1);
  ASSERT_EQ(e.size(), 10u);
  EXPECT_DOUBLE_EQ(e[0].x0, -0.035097441011721117);
  EXPECT_DOUBLE_EQ(e[0].y0, -0.51068995191459998);
  EXPECT_DOUBLE_EQ(e[0].z0, 0.083816578442515957);
  EXPECT_DOUBLE_EQ(e[0].a, 0.23156669769755131);
  EXPECT_DOUBLE_EQ(e[0].b, 0.073960576998529162);
  EXPECT_DOUBLE_EQ(e[0].c, 0.20873849869198532);
  EXPECT_DOUBLE_EQ(e[0].phi_degrees, 142.13735451116705);
  EXPECT_DOUBLE_EQ(e[0].value, 0.29947030659405666);
  for (std::uint64_t seed : {1u, 2u, 12345u})
    for (const Ellipsoid& x : random_ellipsoids(50, seed)) {
      const double r = std::sqrt(x.x0 * x.x0 + x.y0 * x.y0 + x.z0 * x.z0);
      EXPECT_LT(r + std::max({x.a, x.b, x.c}), 1.0) << "seed " << seed;
      EXPECT_GT(std::min({x.a, x.b, x.c}), 0.0);
      EXPECT_GE(x.value, 0.1);
      EXPECT_LE(x.value, 1.0);
    }
  EXPECT_TRUE(random_ellipsoids(0, 1).empty());

  const Volume a = phantom("ellipsoids", 32, 7), b = phantom("ellipsoids", 32, 7);
  const Volume c = phantom("ellipsoids", 32, 8);
  EXPECT_EQ(a.data, b.data);
  EXPECT_NE(a.data, c.data);
  EXPECT_GT(count_above(a, 0.0f), 0u);
  // Nothing outside the unit ball: the corners of the cube stay empty.
  EXPECT_EQ(a.at(0, 0, 0), 0.0f);
  EXPECT_EQ(a.at(31, 31, 31), 0.0f);
  // The seed only matters to the random phantom.
  EXPECT_EQ(phantom("shepp-logan", 16, 1).data, phantom("shepp-logan", 16, 99).data);
}

TEST(Phantom, Errors) {
  std::string msg;
  EXPECT_EQ(status_of([] { phantom("cube", 8); }, &msg), Status::invalid_argument);
  EXPECT_NE(msg.find("unknown phantom 'cube'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("shepp-logan, ellipsoids"), std::string::npos) << msg;
  EXPECT_EQ(status_of([] { phantom("shepp-logan", 0); }, &msg), Status::invalid_argument);
  EXPECT_NE(msg.find("size must be in 1..1024, got 0"), std::string::npos) << msg;
  EXPECT_EQ(status_of([] { phantom("ellipsoids", 1025); }, &msg), Status::invalid_argument);
  EXPECT_NE(msg.find("got 1025"), std::string::npos) << msg;
  EXPECT_EQ(status_of(
                [] {
                  phantom_from_ellipsoids({{0, 0, 0, 0.5, 0, 0.5, 0, 1}}, 8);
                },
                &msg),
            Status::invalid_argument);
  EXPECT_NE(msg.find("ellipsoid 0"), std::string::npos) << msg;
  EXPECT_EQ(status_of([] { phantom_from_ellipsoids({}, 0); }, &msg), Status::invalid_argument);
  EXPECT_EQ(status_of([] { random_ellipsoids(-1, 1); }, &msg), Status::invalid_argument);
  EXPECT_EQ(phantom("shepp-logan", 1).data.size(), 1u);  // the smallest size is fine
}

TEST(Phantom, SyntheticSceneVolumes) {
  EXPECT_EQ(synthetic_volume("shepp_logan", 24, 24, 24).data, phantom("shepp-logan", 24).data);
  const Volume z = synthetic_volume("zeros", 5, 6, 7);
  EXPECT_EQ(z.nx, 5);
  EXPECT_EQ(z.ny, 6);
  EXPECT_EQ(z.nz, 7);
  EXPECT_EQ(z.data, std::vector<float>(5 * 6 * 7, 0.0f));
  const Volume s = parse_volume(R"({"synthetic": "shepp_logan", "dims": [8, 8, 8]})", ".");
  EXPECT_EQ(s.data, phantom("shepp-logan", 8).data);
  std::string msg;
  EXPECT_EQ(status_of([] { synthetic_volume("cube", 4, 4, 4); }, &msg), Status::invalid_argument);
  EXPECT_NE(msg.find("known: sphere, marschner_lobb, shepp_logan, zeros"), std::string::npos)
      << msg;
}

}  // namespace
}  // namespace ivr
