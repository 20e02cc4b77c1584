// tomo_bench.cpp — absorption tomography: projector and back-projector throughput (parallel and
// cone beam, 128³ and 256³), CGLS time to a relative residual of 1 % (64³ and 128³ Shepp–Logan
// from 90 parallel views), and the convergence histories of CGLS, SIRT and LSQR for the plot
// (bench/plot_tomo.py). Each timed operation is checked first: the dot-product test of the pair.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "bench_scene.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"

using ivr::bench::dot;
using ivr::bench::median;
using ivr::bench::uniform;
using ivr::bench::wall_seconds;
using nlohmann::json;

namespace {

json throughput(ivr::Device& device, int n, int views, bool cone, int repeats) {
  const ivr::Scene scene = ivr::bench::tomo_scene(n, views, cone, 1);
  const ivr::Projector P(device, scene);
  const std::vector<double> x = uniform(P.voxel_count(), 1), y = uniform(P.ray_count(), 2);
  const std::vector<double> Nx = P.project(x), Nty = P.backproject(y);  // warm-up and check
  const double lhs = dot(Nx, y), rhs = dot(x, Nty);
  const double mismatch = std::abs(lhs - rhs) / std::max(std::abs(lhs), std::abs(rhs));
  if (!(mismatch <= 1e-5))
    throw ivr::Error(ivr::Status::invalid_argument,
                     "dot-product test failed: " + std::to_string(mismatch));
  std::vector<double> tp, tb;
  for (int r = 0; r < repeats; ++r) {
    P.project(x);
    tp.push_back(P.last_kernel_seconds());
    P.backproject(y);
    tb.push_back(P.last_kernel_seconds());
  }
  const double rays = double(P.ray_count()), mp = median(tp), mb = median(tb);
  json j = {{"volume", n},
            {"views", views},
            {"beam", cone ? "cone" : "parallel"},
            {"rays", P.ray_count()},
            {"dot_mismatch", mismatch},
            {"project_seconds", mp},
            {"backproject_seconds", mb},
            {"project_rays_per_second", rays / mp},
            {"backproject_rays_per_second", rays / mb},
            {"project_ray_cells_per_second", rays * n / mp},
            {"backproject_ray_cells_per_second", rays * n / mb}};
  std::cerr << n << "³ " << (cone ? "cone" : "parallel") << ": project " << mp << " s, backproject "
            << mb << " s (" << P.ray_count() << " rays)\n";
  return j;
}

double volume_error(const std::vector<float>& x, const ivr::Volume& truth) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    num += (double(x[i]) - truth.data[i]) * (double(x[i]) - truth.data[i]);
    den += double(truth.data[i]) * truth.data[i];
  }
  return std::sqrt(num / den);
}

json solve(ivr::Device& device, int n, int views, ivr::Solver solver, int iterations,
           double tolerance) {
  const ivr::Scene scene = ivr::bench::tomo_scene(n, views, false);
  const ivr::Projector P(device, scene);
  const std::vector<double> lines = P.project({scene.volume.data.begin(), scene.volume.data.end()});
  ivr::TomoOptions o;
  o.solver = solver;
  o.iterations = iterations;
  o.tolerance = tolerance;
  ivr::TomoResult r;
  const double wall = wall_seconds([&] { r = ivr::tomo(device, scene, lines, o); });
  json history = json::array();
  for (const ivr::TomoIteration& it : r.history)
    history.push_back(
        {{"iteration", it.iteration}, {"residual", it.residual}, {"seconds", it.seconds}});
  const double err = volume_error(r.volume, scene.volume);
  std::cerr << n << "³ " << ivr::solver_name(solver) << ": " << r.history.size()
            << " iterations, residual " << r.history.back().residual << ", volume error " << err
            << ", " << wall << " s (" << r.stop_reason << ")\n";
  return {{"volume", n},
          {"views", views},
          {"solver", ivr::solver_name(solver)},
          {"iterations", r.history.size()},
          {"stop_reason", r.stop_reason},
          {"residual", r.history.back().residual},
          {"volume_error", err},
          {"seconds", wall},
          {"setup_seconds", r.setup_seconds},
          {"history", history}};
}

std::vector<int> parse_ints(const std::string& text) {
  std::vector<int> out;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t comma = text.find(',', pos);
    out.push_back(std::stoi(text.substr(pos, comma - pos)));
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr tomography benchmark"};
  std::string device_sel, out_path, sizes = "128,256", solve_sizes = "64,128";
  int repeats = 5, views = 32, solve_views = 90, history_iterations = 50;
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--repeats", repeats, "Timed runs per projector case (median)")
      ->check(CLI::Range(1, 100));
  app.add_option("--sizes", sizes, "Volume edges for the projector throughput");
  app.add_option("--views", views, "Views of the throughput scenes (detector n×n)");
  app.add_option("--solve-sizes", solve_sizes, "Phantom edges for CGLS to 1 % residual");
  app.add_option("--solve-views", solve_views, "Parallel views of the reconstructions");
  app.add_option("--history-iterations", history_iterations,
                 "Iterations of each solver for the convergence plot (64³; 0: skip)");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  CLI11_PARSE(app, argc, argv);
  try {
    ivr::Device device(device_sel);
    json doc = {{"benchmark", "tomo"},          {"ivr_version", IVR_VERSION_STRING},
                {"device", device.info().name}, {"driver", device.info().driver},
                {"throughput", json::array()},  {"cgls_to_1_percent", json::array()},
                {"convergence", json::array()}};
    for (int n : parse_ints(sizes))
      for (bool cone : {false, true})
        doc["throughput"].push_back(throughput(device, n, views, cone, repeats));
    for (int n : parse_ints(solve_sizes))
      doc["cgls_to_1_percent"].push_back(
          solve(device, n, solve_views, ivr::Solver::cgls, 500, 0.01));
    if (history_iterations > 0)
      for (ivr::Solver s : {ivr::Solver::cgls, ivr::Solver::lsqr, ivr::Solver::sirt})
        doc["convergence"].push_back(solve(device, 64, solve_views, s, history_iterations, 0));
    ivr::bench::emit_json(doc, out_path);
  } catch (const ivr::Error& e) {
    std::cerr << "ivr_tomo_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
