// domain_tomo_test.cpp — CGLS, SIRT and LSQR over slabs (tomo_domain, lib/brick/domain_tomo.cpp):
// workers on threads, each solving for its slab of the volume, give one process's iterates
// (assembled with domain_assemble), with non-negativity restarts, Tikhonov and TV, in both
// precisions; the shared planes agree bit for bit between neighbours; bad input is refused; over
// several devices of one process (each a slab) the whole iterate is one device's.
#include <gtest/gtest.h>

#include <cmath>
#include <iomanip>
#include <optional>
#include <random>
#include <sstream>

#include "brick_support.hpp"
#include "domain_support.hpp"
#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "ivr/tomo.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

Scene tomo_scene() {
  Scene s;
  s.volume.nx = 10, s.volume.ny = 7, s.volume.nz = 12;
  set_default_box(s);
  s.model = Model::absorption;
  Camera c;
  c.eye = {0.4, 0.9, 1.8}, c.fov_y = 45, c.width = 9, c.height = 8;
  Camera inside = c;
  inside.eye = {0.05, -0.05, 0.1}, inside.target = {1, 0.2, -0.3};
  Camera below = c;
  below.eye = {-0.3, 0.2, -1.9};
  // Down z (every ray crosses every slab) and along x (each ray in one slab, some on its planes).
  s.cameras = {c, inside, below, ortho({0, 0, 2}, {0, 1, 0}, 9, 8, s.box_max.y - s.box_min.y),
               ortho({-2, 0.0, 0}, {0, 1, 0}, 9, 8, 0.9)};
  return s;
}

struct Solved {
  std::vector<double> volume;  // this worker's planes
  std::vector<double> residuals;
  int bricks = 0;
};

Solved solved(const TomoResult& r) {
  Solved out;
  out.volume =
      r.volume_f64.empty() ? std::vector<double>(r.volume.begin(), r.volume.end()) : r.volume_f64;
  for (const TomoIteration& it : r.history) out.residuals.push_back(it.residual);
  out.bricks = r.bricks;
  return out;
}

// N x of random densities in [0, 1) (seeded), each line perturbed by up to 5 %: projections no
// volume fits exactly.
std::vector<double> perturbed_lines(const Projector& N, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> truth(N.voxel_count());
  for (double& v : truth) v = u(rng);
  std::vector<double> lines = N.project(truth);
  for (std::size_t i = 0; i < lines.size(); ++i) lines[i] *= 1.0 + 0.05 * std::sin(double(i));
  return lines;
}

TEST(DomainTomo, CglsEqualsOneProcess) {
  const Scene s = tomo_scene();
  std::vector<Precision> precisions{Precision::f32};
  if (device().info().fp64) precisions.push_back(Precision::f64);
  for (const Precision p : precisions) {
    const Projector N(device(), s, p);
    const std::vector<double> lines = perturbed_lines(N, 9);
    for (bool nonneg : {false, true}) {
      TomoOptions o;
      o.precision = p;
      o.iterations = 6;
      o.nonneg = nonneg;
      o.tikhonov = nonneg ? 0.0 : 1e-3;
      const TomoResult one = tomo(device(), s, lines, o);
      const std::vector<double> want = solved(one).volume;
      const TomoResult host = [&] {  // in bricks: the host CGLS
        ScopedEnv brick("IVR_VOLUME_BRICK", "6");
        return tomo(device(), s, lines, o);
      }();
      ASSERT_GT(host.bricks, 1);

      const std::vector<double> want_host = solved(host).volume;
      double scale = 0;
      for (double v : want) scale = std::max(scale, std::abs(v));
      ASSERT_GT(scale, 0.0);
      for (int ranks : {1, 2, 5}) {
        const std::string what = std::string(p == Precision::f64 ? "f64" : "f32") +
                                 (nonneg ? " nonneg " : " tikhonov ") + std::to_string(ranks) +
                                 " workers";
        const std::vector<Solved> parts =
            on_workers<Solved>(ranks, [&](int, const DomainPart& part, Device& d) {
              return solved(tomo_domain(d, s, lines, part, o));
            });
        std::vector<std::vector<double>> slabs;
        for (int w = 0; w < ranks; ++w) {
          const Slab slab = domain_slab(s.volume.nz, w, ranks);
          ASSERT_EQ(parts[w].volume.size(), std::size_t(s.volume.nx * s.volume.ny) * slab.planes())
              << what;
          EXPECT_EQ(parts[w].residuals, parts[0].residuals) << what << " worker " << w;
          slabs.push_back(parts[w].volume);
        }
        // Neighbours hold the plane they share alike.
        const std::size_t plane = std::size_t(s.volume.nx) * s.volume.ny;
        for (int w = 0; w + 1 < ranks; ++w)
          for (std::size_t i = 0; i < plane; ++i)
            ASSERT_EQ(slabs[w][slabs[w].size() - plane + i], slabs[w + 1][i]) << what;
        const std::vector<double> got =
            domain_assemble(s.volume.nx, s.volume.ny, s.volume.nz, slabs);
        ASSERT_EQ(got.size(), want.size());
        // Against one process's host CGLS over bricks and its in-core device solver (the same
        // iteration, its sums in other orders; float32 iterates round differently).
        for (const bool device_solver : {false, true}) {
          const std::vector<double>& ref = device_solver ? want : want_host;
          const double tol = p == Precision::f64 ? 1e-10 : 1e-3;
          double worst = 0;
          for (std::size_t i = 0; i < got.size(); ++i)
            worst = std::max(worst, std::abs(got[i] - ref[i]));
          EXPECT_LE(worst, tol * scale) << what << (device_solver ? " device" : " host");
          std::ostringstream measured;
          measured << std::scientific << std::setprecision(2) << worst / scale;
          RecordProperty(what + (device_solver ? " device" : " host"), measured.str());
        }
        ASSERT_EQ(parts[0].residuals.size(), one.history.size()) << what;
        for (std::size_t k = 0; k < one.history.size(); ++k)
          EXPECT_NEAR(parts[0].residuals[k], host.history[k].residual,
                      (p == Precision::f64 ? 1e-10 : 1e-4) * host.history[k].residual + 1e-12)
              << what << " iteration " << k + 1;
      }
    }
  }
}

// `o` solved by 3 workers over slabs against one process — its in-core device solver, or
// (`host`) its host solver over bricks of 6 cells, the same code on the whole grid: the iterates
// assembled within 1e-10 of its largest entry (float64; float32 1e-3), every worker's residual
// history the same and within 1e-10 of the one process's.
void expect_slabs_equal_one_process(const Scene& s, const std::vector<double>& lines,
                                    const TomoOptions& o, const std::string& what,
                                    bool host = false) {
  const Precision p = o.precision;
  const TomoResult one = [&] {
    std::optional<ScopedEnv> brick;
    if (host) brick.emplace("IVR_VOLUME_BRICK", "6");
    return tomo(device(), s, lines, o);
  }();
  ASSERT_EQ(one.bricks > 1, host) << what;
  const std::vector<Solved> parts = on_workers<Solved>(3, [&](int, const DomainPart& part, Device& d) {
    return solved(tomo_domain(d, s, lines, part, o));
  });
  std::vector<std::vector<double>> slabs;
  for (const Solved& w : parts) {
    EXPECT_EQ(w.residuals, parts[0].residuals) << what;
    slabs.push_back(w.volume);
  }
  const std::vector<double> got = domain_assemble(s.volume.nx, s.volume.ny, s.volume.nz, slabs);
  const std::vector<double> want = solved(one).volume;
  ASSERT_EQ(got.size(), want.size()) << what;
  double scale = 0, worst = 0;
  for (std::size_t i = 0; i < want.size(); ++i)
    scale = std::max(scale, std::abs(want[i])), worst = std::max(worst, std::abs(got[i] - want[i]));
  ASSERT_GT(scale, 0.0);
  EXPECT_LE(worst, (p == Precision::f64 ? 1e-10 : 1e-3) * scale) << what;
  ASSERT_EQ(parts[0].residuals.size(), one.history.size()) << what;
  for (std::size_t k = 0; k < one.history.size(); ++k)
    EXPECT_NEAR(parts[0].residuals[k], one.history[k].residual,
                (p == Precision::f64 ? 1e-10 : 1e-4) * one.history[k].residual + 1e-12)
        << what << " iteration " << k + 1;
}

// SIRT and LSQR over slabs (lib/tomo/host_solvers.hpp: the same host iterations as out of core
// and over views): 3 workers give one process's in-core device iterate, with Tikhonov and x ≥ 0.
TEST(DomainTomo, SirtAndLsqrEqualOneProcess) {
  const Scene s = tomo_scene();
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const Projector N(device(), s, p);
  const std::vector<double> lines = perturbed_lines(N, 7);
  for (const Solver solver : {Solver::sirt, Solver::lsqr})
    for (bool nonneg : {false, true}) {
      TomoOptions o;
      o.solver = solver;
      o.precision = p;
      o.iterations = 6;
      o.nonneg = nonneg;
      o.tikhonov = nonneg ? 0.0 : 1e-3;
      expect_slabs_equal_one_process(
          s, lines, o, std::string(solver_name(solver)) + (nonneg ? " nonneg" : " tikhonov"));
    }
}

// TV over slabs: each worker holds the TV rows (forward differences) of the planes it owns — a
// shared plane's are the upper worker's, whose next plane it holds — their sums over the workers
// and their parts of the shared planes joined (as the back-projection's), with the lagged
// diffusivity reweighted every 2 iterations: every solver equals one process's host TV (over
// bricks; the device's TV kernels round otherwise: BrickedTomo.SolversEqualTheInCoreSolvers).
TEST(DomainTomo, TvEqualsOneProcess) {
  const Scene s = tomo_scene();
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const Projector N(device(), s, p);
  const std::vector<double> lines = perturbed_lines(N, 11);
  for (const Solver solver : {Solver::cgls, Solver::sirt, Solver::lsqr}) {
    TomoOptions o;
    o.solver = solver;
    o.precision = p;
    o.iterations = 6;
    o.tv = 0.05;
    o.tv_reweight = 2;
    o.nonneg = solver == Solver::sirt;
    expect_slabs_equal_one_process(s, lines, o, std::string(solver_name(solver)) + " tv", true);
  }
}

TEST(DomainTomo, BadInputIsRefused) {
  const Scene s = tomo_scene();
  const std::vector<double> lines(Projector(device(), s).ray_count(), 0.1);
  DomainPart part;
  part.ranks = 2;  // no all_gather
  EXPECT_THROW(tomo_domain(device(), s, lines, part), Error);
  part.ranks = 1;
  try {
    tomo_domain(device(), s, std::vector<double>(lines.size() - 1, 0.1), part);
    ADD_FAILURE() << "short projections ran";
  } catch (const Error& e) {
    EXPECT_TRUE(has(e.what(), "projections")) << e.what();
  }
  EXPECT_THROW(domain_assemble(10, 7, 12, {std::vector<double>(10 * 7 * 12 - 1)}), Error);
}

// A stop said by one worker alone (a signal seen by one MPI rank first) stops every worker after
// the same iteration, over slabs and over views, instead of leaving the others waiting.
TEST(DomainTomo, OneWorkersStopStopsEveryWorker) {
  const Scene s = tomo_scene();
  const Projector N(device(), s, Precision::f32);
  const std::vector<double> lines = perturbed_lines(N, 9);
  TomoOptions o;
  o.iterations = 6;
  const auto stop_on_last = [](int w, int ranks) {
    return w == ranks - 1 ? TomoProgress([](const TomoIteration& it) { return it.iteration < 2; })
                          : TomoProgress{};
  };
  const std::vector<TomoResult> slabs =
      on_workers<TomoResult>(3, [&](int w, const DomainPart& part, Device& d) {
        return tomo_domain(d, s, lines, part, o, stop_on_last(w, 3));
      });
  WorkerSum sums(2);  // (over views the workers meet in sums)
  const std::vector<TomoResult> views =
      on_workers<TomoResult>(2, [&](int w, const DomainPart&, Device& d) {
        const auto [first, count] = view_shares(s.cameras.size(), 2)[std::size_t(w)];
        const std::size_t per_view = lines.size() / s.cameras.size();
        const std::vector<double> mine(lines.begin() + first * per_view,
                                       lines.begin() + (first + count) * per_view);
        return tomo_shared(d, scene_share(s, first, count), mine, o, sums.of(w),
                           stop_on_last(w, 2));
      });
  for (const auto* run : {&slabs, &views})
    for (std::size_t w = 0; w < run->size(); ++w) {
      const std::string what = (run == &slabs ? "slabs, worker " : "views, worker ") +
                               std::to_string(w);
      EXPECT_EQ((*run)[w].history.size(), 2u) << what;
      EXPECT_EQ((*run)[w].stop_reason, "interrupted") << what;
    }
}

// Several devices of one process, each its slab (tomo_domain over devices; here contexts on the
// test device): the whole iterate and the residuals are one device's; a progress that says stop
// after iteration 3 is asked on one device and stops every device there.
TEST(DomainTomo, SeveralDevicesEqualOneDevice) {
  const Scene s = tomo_scene();
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const double tol = p == Precision::f64 ? 1e-10 : 1e-4;
  const Projector N(device(), s, p);
  const std::vector<double> lines = perturbed_lines(N, 9);
  TomoOptions o;
  o.precision = p;
  o.iterations = 6;
  o.nonneg = true;
  const Solved one = solved(tomo(device(), s, lines, o));
  // (2 devices weighted 1:3 too: slabs of 3 and 8 of the 11 cells, domain_slab)
  for (const auto& [count, shares] : std::vector<std::pair<int, std::vector<double>>>{
           {2, {}}, {3, {}}, {2, {1, 3}}}) {
    const std::string what = std::to_string(count) + " devices" + (shares.empty() ? "" : ", 1:3");
    const auto devices = device_contexts(count);
    TomoOptions weighted = o;
    weighted.shares = shares;
    const TomoResult many = tomo_domain(pointers_to(devices), s, lines, weighted);
    const Solved got = solved(many);
    expect_close_values(one.volume, got.volume, tol, what);
    ASSERT_EQ(got.residuals.size(), one.residuals.size()) << what;
    for (std::size_t k = 0; k < got.residuals.size(); ++k)
      EXPECT_NEAR(got.residuals[k], one.residuals[k], tol) << what << " iteration " << k + 1;
    EXPECT_EQ(many.stop_reason, "iterations") << what;
    EXPECT_GE(many.bricks, count) << what;
  }
  TomoOptions three = o;
  three.iterations = 3;
  const Solved want = solved(tomo(device(), s, lines, three));
  int calls = 0;
  const auto devices = device_contexts(3);
  const TomoResult stopped =
      tomo_domain(pointers_to(devices), s, lines, o, [&](const TomoIteration& it) {
        ++calls;
        return it.iteration < 3;
      });
  EXPECT_EQ(calls, 3);  // on device 0 alone
  EXPECT_EQ(stopped.stop_reason, "interrupted");
  EXPECT_EQ(stopped.history.size(), 3u);
  expect_close_values(want.volume, solved(stopped).volume, tol, "stopped after 3");
  expect_error([&] { tomo_domain(std::vector<Device*>{}, s, lines, o); }, Status::invalid_argument,
               "none given");
}

}  // namespace
}  // namespace ivr::test
