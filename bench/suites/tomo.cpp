// tomo.cpp — the tomography suite: throughput of the linear absorption projector and its transpose
// (parallel and cone beam), with ASTRA's FP3D / BP3D beside the parallel cases when asked for
// (--baselines astra, on a GPU); CGLS's time to a 1 % residual and every solver's convergence on
// the Shepp–Logan phantom. Checked before timing: the projection of σ = 1 against each ray's
// chord through the box (closed form), and the dot-product test ⟨N x, y⟩ = ⟨x, Nᵀ y⟩.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <random>
#include <sstream>

#include "../bench_scene.hpp"
#include "../bench_support.hpp"
#include "../runner/resident.hpp"
#include "../runner/suite.hpp"

namespace ivr::bench {

namespace {

// Each ray's chord through the box (the exact line integral of σ = 1): the orthographic rays of
// the tomography scene, clipped in double precision.
std::vector<double> chords(const Scene& scene) {
  std::vector<double> out;
  for (const Camera& c : scene.cameras) {
    const glm::dvec3 fwd = glm::normalize(c.target - c.eye),
                     right = glm::normalize(glm::cross(fwd, c.up)), up = glm::cross(right, fwd);
    const double half_h = 0.5 * c.ortho_height, half_w = half_h * c.width / c.height;
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        const double sx = 2.0 * (x + 0.5) / c.width - 1, sy = 1 - 2.0 * (y + 0.5) / c.height;
        const glm::dvec3 o = c.eye + sx * half_w * right + sy * half_h * up;
        double t0 = -INFINITY, t1 = INFINITY;
        for (int a = 0; a < 3; ++a) {
          if (fwd[a] == 0) {
            if (o[a] < scene.box_min[a] || o[a] > scene.box_max[a]) t1 = -INFINITY;
            continue;
          }
          const double ta = (scene.box_min[a] - o[a]) / fwd[a],
                       tb = (scene.box_max[a] - o[a]) / fwd[a];
          t0 = std::max(t0, std::min(ta, tb));
          t1 = std::min(t1, std::max(ta, tb));
        }
        out.push_back(std::max(0.0, t1 - t0));
      }
  }
  return out;
}

struct TomoCase {
  int n, views;
  bool cone, large;
};

// ASTRA's and ivr's results may differ by their discretisations (ASTRA samples the trilinear
// volume on the planes through voxel centres, zero outside, and back-projects by interpolating
// the detector; ivr integrates exactly, clamped at the box): a loose bound that still catches a
// flipped or transposed axis, which on asymmetric data differs by O(1).
constexpr double kAstraAgreement = 0.1;

std::uint64_t available_host_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string name;
  std::uint64_t kib = 0;
  while (in >> name >> kib) {
    if (name == "MemAvailable:") return kib * 1024;
    in.ignore(1 << 10, '\n');
  }
  return 0;
}

// Why a large case cannot run here ("" when it can). On a CPU device it would take hours (the
// 2-core PoCL figures: ~50 M ray·cells/s), and its point is the comparison with ASTRA on a GPU.
// Memory: float32 volume and lines, three of each at once on the device (the one-shot pair, the
// resident inputs and outputs); about 56 bytes per voxel and ray on the host (the suite's float64
// vectors, the checks, the baseline's case files and its process).
std::string large_case_obstacle(const Context& ctx, std::size_t voxels, std::size_t rays) {
  const DeviceInfo& info = ctx.device.info();
  const auto gib = [](double b) {
    std::ostringstream s;
    s << std::setprecision(3) << b / double(1 << 30) << " GiB";
    return s.str();
  };
  if (info.type == "cpu") return "the large cases run on GPU and accelerator devices only";
  const double device = 12.0 * double(voxels + rays), host = 56.0 * double(voxels + rays);
  if (info.global_memory && device > 0.9 * double(info.global_memory))
    return "needs ~" + gib(device) + " of device memory, the device has " +
           gib(double(info.global_memory));
  if (info.max_allocation && 4.0 * double(std::max(voxels, rays)) > double(info.max_allocation))
    return "a " + gib(4.0 * double(std::max(voxels, rays))) +
           " buffer exceeds the device's largest allocation (" + gib(double(info.max_allocation)) +
           ")";
  const std::uint64_t free_host = available_host_bytes();
  if (free_host && host > double(free_host))
    return "needs ~" + gib(host) + " of host memory, " + gib(double(free_host)) + " available";
  return "";
}

// ASTRA's FP3D / BP3D (bench/baselines/astra_project.py) on a parallel case, timed end to end from
// host arrays as ivr's one-shot N / Nᵀ are: records beside ivr's (device "cuda"), whose ratios
// Results::ratios() makes. Their check: the relative L2 difference from ivr's N and Nᵀ of random
// ellipsoids (asymmetric: a flipped axis would show), within kAstraAgreement.
void astra_baseline(Context& ctx, const Scene& scene, const Projector& P, const std::string& base,
                    const nlohmann::json& params) {
  const std::vector<std::string>& fws = ctx.baselines.frameworks;
  if (!ctx.python_baselines || std::find(fws.begin(), fws.end(), "astra") == fws.end()) return;
  if (ctx.baseline_device != "gpu") {  // nothing to run: ASTRA's 3D projectors are CUDA only
    for (const char* op : {"_project", "_backproject"}) {
      Record r{kHostDevice, "tomo", base + op, "astra", params};
      r.note =
          "skipped: ASTRA's FP3D/BP3D run on CUDA GPUs only (ivr-bench runs astra beside a "
          "GPU device)";
      ctx.results.add(std::move(r));
    }
    return;
  }
  const Volume& v = scene.volume;
  std::vector<double> volume, lines, back;
  std::string dir;
  if (ctx.baselines.usable) {  // else run_python_baselines records the skip
    volume = widen(phantom_from_ellipsoids(random_ellipsoids(10, 7), v.nx, v.ny, v.nz).data);
    lines = P.project(volume);
    back = P.backproject(lines);
    dir = write_tomo_case(ctx.work_dir + "/tomo_" + base, scene, volume, lines);
  }
  for (bool transpose : {false, true}) {
    const std::vector<double>& ref = transpose ? back : lines;
    const std::string against = std::string("ivr ") + (transpose ? "Nᵀ N" : "N") +
                                " of random ellipsoids (loose: another discretisation)";
    run_python_baselines(ctx, "tomo", base + (transpose ? "_backproject" : "_project"), params, dir,
                         transpose ? "backproject" : "project", transpose ? "volume" : "lines",
                         [&](const BaselineRun& run, Record& r) {
                           const Difference d = difference(run.output, ref);
                           r.metrics["relative_l2_vs_ivr"] = d.relative_l2;
                           r.metrics["error_max_abs_vs_ivr"] = d.max_abs;
                           return check_l2(d, against, kAstraAgreement);
                         });
  }
}

}  // namespace

// One reconstruction of the Shepp–Logan phantom from parallel views by `solver`: the wall time (of
// the whole solve, setup included), its iterations, final residual and volume error, and the
// residual history as the record's series (bench/plot_tomo.py plots it).
void solver_case(Context& ctx, const std::string& name, int n, int views, Solver solver,
                 int iterations, double tolerance) {
  const Scene scene = tomo_scene(n, views, false);
  const Projector P(ctx.device, scene);
  const std::vector<double> lines = P.project({scene.volume.data.begin(), scene.volume.data.end()});
  TomoOptions o;
  o.solver = solver;
  o.iterations = iterations;
  o.tolerance = tolerance;
  TomoResult result;
  Check check;
  Budget budget = ctx.budget;
  budget.warmup = 1;
  const Measurement m = measure(
      budget,
      [&] {
        result = tomo(ctx.device, scene, lines, o);
        return -1.0;
      },
      [&] {
        const double residual = result.history.empty() ? NAN : result.history.back().residual;
        // To a tolerance: reached it; a fixed count: below the first iteration's residual.
        const double bound = tolerance > 0               ? tolerance
                             : result.history.size() > 1 ? result.history.front().residual
                                                         : 0.0;
        check = {residual <= bound && std::isfinite(residual), "the projections p",
                 "relative residual", residual, bound};
        return check.passed;
      });
  double num = 0, den = 0;
  for (std::size_t i = 0; i < result.volume.size(); ++i) {
    const double d = double(result.volume[i]) - scene.volume.data[i];
    num += d * d;
    den += double(scene.volume.data[i]) * scene.volume.data[i];
  }
  Record r{ctx.device_key,
           "tomo",
           name,
           "ivr",
           {{"volume", n},
            {"views", views},
            {"solver", solver_name(solver)},
            {"iterations", iterations},
            {"tolerance", tolerance}}};
  add_timing(r, m);
  r.metrics["iterations_run"] = result.history.size();
  r.metrics["volume_error"] = den > 0 ? std::sqrt(num / den) : 0.0;
  r.metrics["setup_s"] = result.setup_seconds;
  r.series = nlohmann::json::array();
  for (const TomoIteration& it : result.history)
    r.series.push_back(
        {{"iteration", it.iteration}, {"residual", it.residual}, {"seconds", it.seconds}});
  record_checked(ctx, std::move(r), check);
}

void tomo_suite(Context& ctx) {
  std::vector<TomoCase> cases;
  for (int n : ctx.quick ? std::vector<int>{32} : std::vector<int>{64, 128})
    for (bool cone : {false, true}) cases.push_back({n, n / 2, cone, false});
  if (!ctx.quick) {  // issue 18's sizes, parallel beam (ASTRA's FP3D/BP3D beside them)
    cases.push_back({256, 256, false, true});
    cases.push_back({512, 128, false, true});
  }
  for (const TomoCase& tc : cases) {
    const int n = tc.n, views = tc.views;
    const bool cone = tc.cone;
    const std::string base = "v" + std::to_string(n) +
                             (views == n / 2 ? "" : "_views" + std::to_string(views)) + "_" +
                             (cone ? "cone" : "parallel");
    if (!ctx.wants(base)) continue;
    const nlohmann::json params = {{"volume", n},
                                   {"views", views},
                                   {"detector", n},
                                   {"beam", cone ? "cone" : "parallel"},
                                   {"rays", std::size_t(views) * n * n}};
    if (tc.large) {
      const std::string why =
          large_case_obstacle(ctx, std::size_t(n) * n * n, std::size_t(views) * n * n);
      if (!why.empty()) {
        for (const char* op : {"_project", "_backproject"}) {
          Record r{ctx.device_key, "tomo", base + op, "ivr", params};
          r.note = "skipped: " + why;
          ctx.results.add(std::move(r));
        }
        std::cerr << "ivr-bench: tomo/" << base << " skipped: " << why << "\n";
        continue;
      }
    }
    std::cerr << "ivr-bench: tomo/" << base << "...\n";
    const Scene scene = tomo_scene(n, views, cone, 1);
    const Projector P(ctx.device, scene);
    const std::vector<double> x = uniform(P.voxel_count(), 1), y = uniform(P.ray_count(), 2);
    const double lhs = dot(P.project(x), y), rhs = dot(x, P.backproject(y));
    const double mismatch = std::abs(lhs - rhs) / std::max(std::abs(lhs), std::abs(rhs));
    Check check{mismatch <= 1e-5, "⟨N x, y⟩ = ⟨x, Nᵀ y⟩", "relative", mismatch, 1e-5};
    if (!cone && check.passed) {  // the chords: parallel beam has them in closed form
      const Check chord =
          check_max(difference(P.project(std::vector<double>(P.voxel_count(), 1.0)), chords(scene)),
                    "chord lengths through the box (closed form)", 1e-6, 1e-5);
      if (!chord.passed) check = chord;
    }
    for (bool transpose : {false, true}) {
      const Measurement m = measure(
          ctx.budget,
          [&] {
            if (transpose)
              P.backproject(y);
            else
              P.project(x);
            return P.last_kernel_seconds();
          },
          [&] { return check.passed; });
      Record r{ctx.device_key, "tomo", base + (transpose ? "_backproject" : "_project"), "ivr",
               params};
      add_timing(r, m);
      r.metrics["rays_per_s"] = double(P.ray_count()) / m.wall.median;
      r.metrics["ray_cells_per_s"] = double(P.ray_count()) * n / m.wall.median;
      r.metrics["memory_bytes"] = operation_memory(ctx, m, 0);
      record_checked(ctx, std::move(r), check);
    }
    if (!cone && check.passed) astra_baseline(ctx, scene, P, base, params);
    // Resident: the volume and the lines already on the device, the result left there; held
    // to the same dot-product test on device arrays first.
    Scene geometry = scene;
    geometry.volume.data.clear();
    Session session(ctx.device, geometry);
    DeviceArray xd(ctx.device, session.volume_shape(), DType::f32);
    std::vector<std::int64_t> ray_shape = session.image_shape();
    ray_shape[3] = 1;
    DeviceArray yd(ctx.device, ray_shape, DType::f32);
    xd.upload(x.data(), x.size());
    yd.upload(y.data(), y.size());
    const double resident_lhs = dot(session.project(xd).to_doubles(), y),
                 resident_rhs = dot(x, session.backproject(yd).to_doubles());
    const double resident_mismatch = std::abs(resident_lhs - resident_rhs) /
                                     std::max(std::abs(resident_lhs), std::abs(resident_rhs));
    const Check resident_check{resident_mismatch <= 1e-5 && check.passed,
                               "⟨N x, y⟩ = ⟨x, Nᵀ y⟩ on device arrays", "relative",
                               resident_mismatch, 1e-5};
    for (bool transpose : {false, true}) {
      DeviceArray out;
      const Measurement m = measure_resident(
          ctx.budget, session,
          [&] {
            out = transpose ? session.backproject(yd) : session.project(xd);
            out.wait();
          },
          [&] { return resident_check.passed; });
      Record r{ctx.device_key, "tomo", base + (transpose ? "_backproject" : "_project"),
               "ivr-resident", params};
      add_timing(r, m);
      r.metrics["rays_per_s"] = double(P.ray_count()) / m.wall.median;
      r.metrics["ray_cells_per_s"] = double(P.ray_count()) * n / m.wall.median;
      r.metrics["memory_bytes"] = operation_memory(ctx, m, 0);
      record_checked(ctx, std::move(r), resident_check);
    }
  }
  // CGLS to a relative residual of 1 %, and each solver's convergence over a fixed count (the
  // Shepp–Logan phantom from parallel views).
  const int n = ctx.quick ? 32 : 64, solve_views = ctx.quick ? 30 : 90;
  for (int size : ctx.quick ? std::vector<int>{32} : std::vector<int>{64, 128})
    solver_case(ctx, "cgls_to_1_percent_v" + std::to_string(size), size, solve_views, Solver::cgls,
                500, 0.01);
  for (Solver solver : {Solver::cgls, Solver::lsqr, Solver::sirt})
    solver_case(ctx, std::string("convergence_v") + std::to_string(n) + "_" + solver_name(solver),
                n, solve_views, solver, ctx.quick ? 20 : 50, 0);
}

}  // namespace ivr::bench
