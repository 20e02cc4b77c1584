// phantom.cpp — tomography test volumes: Kak & Slaney's 3D Shepp–Logan head and random
// ellipsoids, sampled exactly (inside or not) at voxel centres.
#include "ivr/phantom.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <thread>

#include "ivr/error.hpp"

namespace ivr {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxPhantomSide = 1024;

[[noreturn]] void fail(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

// Voxel i of n along an axis over [-1, 1] sits at its cell centre.
double centre(int i, int n) {
  return -1.0 + (2.0 * i + 1.0) / n;
}

// First and last voxel index whose centre may lie in [lo, hi], widened by one voxel so that
// rounding in the bound never drops a voxel the exact test would keep.
void index_range(double lo, double hi, int n, int* first, int* last) {
  *first = std::max(0, int(std::floor((lo + 1.0) * n / 2.0 - 0.5)) - 1);
  *last = std::min(n - 1, int(std::ceil((hi + 1.0) * n / 2.0 - 0.5)) + 1);
}

void check(const Ellipsoid& e, std::size_t k) {
  const bool finite = std::isfinite(e.x0) && std::isfinite(e.y0) && std::isfinite(e.z0) &&
                      std::isfinite(e.phi_degrees) && std::isfinite(e.value);
  if (!finite || !(e.a > 0 && e.b > 0 && e.c > 0) || !std::isfinite(e.a * e.b * e.c))
    fail("phantom: ellipsoid " + std::to_string(k) +
         " needs finite fields and semi-axes a, b, c > 0");
}

// Sums every ellipsoid at the points of fine slice k of an fx × fy × fz grid over [-1, 1]³ into
// `slice` (fx·fy values, zeroed first).
void sample_fine_slice(const std::vector<Ellipsoid>& ellipsoids, int fx, int fy, int fz, int k,
                       std::vector<double>& slice) {
  std::fill(slice.begin(), slice.end(), 0.0);
  const double z = centre(k, fz);
  for (const Ellipsoid& e : ellipsoids) {
    const double dz = (z - e.z0) / e.c;
    const double q = 1.0 - dz * dz;  // the cross-section is (x'/a)² + (y'/b)² <= q
    if (q < 0) continue;
    const double phi = e.phi_degrees * kPi / 180.0, cs = std::cos(phi), sn = std::sin(phi);
    // Half-extents of the rotated ellipse of the cross-section along x and y.
    const double ex = std::sqrt(q * ((e.a * cs) * (e.a * cs) + (e.b * sn) * (e.b * sn)));
    const double ey = std::sqrt(q * ((e.a * sn) * (e.a * sn) + (e.b * cs) * (e.b * cs)));
    int i0, i1, j0, j1;
    index_range(e.x0 - ex, e.x0 + ex, fx, &i0, &i1);
    index_range(e.y0 - ey, e.y0 + ey, fy, &j0, &j1);
    for (int j = j0; j <= j1; ++j) {
      const double dy = centre(j, fy) - e.y0;
      for (int i = i0; i <= i1; ++i) {
        const double dx = centre(i, fx) - e.x0;
        // The point relative to the centre, rotated by −phi about z.
        const double xr = (cs * dx + sn * dy) / e.a, yr = (-sn * dx + cs * dy) / e.b;
        if (xr * xr + yr * yr + dz * dz <= 1.0) slice[std::size_t(j) * fx + i] += e.value;
      }
    }
  }
}

// Slices [z_begin, z_end) of v: each voxel the mean over its s³ sub-cell centres (s = 1: its
// centre), accumulated in double so that each voxel is the float nearest the value (1.02 in the
// brain), not an artefact of float additions.
void sample_slices(const std::vector<Ellipsoid>& ellipsoids, Volume& v, int s, int z_begin,
                   int z_end, std::vector<double>& fine, std::vector<double>& sum) {
  const int nx = v.nx, ny = v.ny, fx = nx * s, fy = ny * s;
  const double inv = 1.0 / (double(s) * s * s);
  for (int k = z_begin; k < z_end; ++k) {
    std::fill(sum.begin(), sum.end(), 0.0);
    for (int kk = 0; kk < s; ++kk) {
      sample_fine_slice(ellipsoids, fx, fy, v.nz * s, k * s + kk, fine);
      for (int j = 0; j < fy; ++j)
        for (int i = 0; i < fx; ++i)
          sum[std::size_t(j / s) * nx + i / s] += fine[std::size_t(j) * fx + i];
    }
    float* out = v.data.data() + std::size_t(k) * nx * ny;
    for (std::size_t p = 0; p < sum.size(); ++p) out[p] = float(sum[p] * inv);
  }
}

}  // namespace

Volume phantom_from_ellipsoids(const std::vector<Ellipsoid>& ellipsoids, int nx, int ny, int nz,
                               int supersample) {
  if (supersample < 1 || supersample > 16)
    fail("phantom: supersample must be in 1..16, got " + std::to_string(supersample));
  if (nx < 1 || ny < 1 || nz < 1 || double(nx) * ny * nz > 2147483647.0)
    fail("phantom: dims must be >= 1 and hold at most 2^31 voxels, got " + std::to_string(nx) +
         "x" + std::to_string(ny) + "x" + std::to_string(nz));
  for (std::size_t k = 0; k < ellipsoids.size(); ++k) check(ellipsoids[k], k);
  Volume v;
  v.nx = nx;
  v.ny = ny;
  v.nz = nz;
  v.data.resize(v.voxel_count());
  // Slabs of slices on every core; small volumes on one thread. Buffers are allocated before
  // any thread starts, so nothing inside a thread can throw.
  const std::size_t cores = std::max(1u, std::thread::hardware_concurrency());
  const int threads = int(std::min<std::size_t>(
      {cores, std::size_t(nz), std::max<std::size_t>(1, v.voxel_count() >> 18)}));
  const int s = supersample;
  std::vector<std::vector<double>> sums(threads, std::vector<double>(std::size_t(nx) * ny));
  std::vector<std::vector<double>> fine(threads, std::vector<double>(std::size_t(nx) * ny * s * s));
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t)
    pool.emplace_back([&, t] {
      sample_slices(ellipsoids, v, s, nz * t / threads, nz * (t + 1) / threads, fine[t], sums[t]);
    });
  sample_slices(ellipsoids, v, s, 0, nz / threads, fine[0], sums[0]);
  for (std::thread& th : pool) th.join();
  return v;
}

Volume phantom_from_ellipsoids(const std::vector<Ellipsoid>& ellipsoids, int n, int supersample) {
  return phantom_from_ellipsoids(ellipsoids, n, n, n, supersample);
}

std::vector<Ellipsoid> shepp_logan_ellipsoids() {
  // Kak & Slaney, Table 3.1 (3D), rows a–j: centre, semi-axes, phi about z, value. The book
  // prints 0.56 for row i's first semi-axis, a known typo for 0.056 (the ellipsoid would leave
  // the skull otherwise). Some re-implementations (after Koay et al. 2007) give rows e and f
  // the value 0.02; the book's 0.01 is kept here.
  return {
      {0, 0, 0, 0.69, 0.92, 0.9, 0, 2.0},                  // a: skull
      {0, 0, 0, 0.6624, 0.874, 0.88, 0, -0.98},            // b: brain
      {-0.22, 0, -0.25, 0.41, 0.16, 0.21, 108, -0.02},     // c
      {0.22, 0, -0.25, 0.31, 0.11, 0.22, 72, -0.02},       // d
      {0, 0.35, -0.25, 0.21, 0.25, 0.5, 0, 0.01},          // e
      {0, 0.1, -0.25, 0.046, 0.046, 0.046, 0, 0.01},       // f
      {-0.08, -0.65, -0.25, 0.046, 0.023, 0.02, 0, 0.01},  // g
      {0.06, -0.65, -0.25, 0.046, 0.023, 0.02, 90, 0.01},  // h
      {0.06, -0.105, 0.625, 0.056, 0.04, 0.1, 90, 0.02},   // i (book: 0.56, see above)
      {0, 0.1, 0.625, 0.056, 0.056, 0.1, 0, -0.02},        // j
  };
}

std::vector<Ellipsoid> random_ellipsoids(int count, std::uint64_t seed) {
  if (count < 0 || count > 100000)
    fail("phantom: ellipsoid count must be in 0..100000, got " + std::to_string(count));
  // mt19937_64's output sequence is fixed by the standard; the distributions of <random> are
  // not, so doubles in [0, 1) come from the top 53 bits directly.
  std::mt19937_64 rng(seed);
  const auto uniform = [&rng] { return double(rng() >> 11) * 0x1.0p-53; };
  std::vector<Ellipsoid> out;
  for (int k = 0; k < count; ++k) {
    Ellipsoid e;
    // Centre uniform in the ball of radius 0.6 (rejection from the cube), then semi-axes of at
    // most 0.7 of the room left, so |centre| + max(a, b, c) < 1: inside the unit ball whatever
    // the rotation.
    double r2;
    do {
      e.x0 = 0.6 * (2 * uniform() - 1);
      e.y0 = 0.6 * (2 * uniform() - 1);
      e.z0 = 0.6 * (2 * uniform() - 1);
      r2 = e.x0 * e.x0 + e.y0 * e.y0 + e.z0 * e.z0;
    } while (r2 > 0.36);
    const double room = 1.0 - std::sqrt(r2);
    e.a = room * (0.1 + 0.6 * uniform());
    e.b = room * (0.1 + 0.6 * uniform());
    e.c = room * (0.1 + 0.6 * uniform());
    e.phi_degrees = 180.0 * uniform();
    e.value = 0.1 + 0.9 * uniform();
    out.push_back(e);
  }
  return out;
}

Volume phantom(const std::string& name, int n, std::uint64_t seed, int supersample) {
  if (name != "shepp-logan" && name != "ellipsoids")
    fail("phantom: unknown phantom '" + name + "' (known: shepp-logan, ellipsoids)");
  if (n < 1 || n > kMaxPhantomSide)
    fail("phantom: size must be in 1.." + std::to_string(kMaxPhantomSide) + ", got " +
         std::to_string(n));
  return phantom_from_ellipsoids(
      name == "shepp-logan" ? shepp_logan_ellipsoids() : random_ellipsoids(10, seed), n,
      supersample);
}

}  // namespace ivr
