// reconstruct_bench.cpp — density reconstruction (emission–absorption, known TF): iterations per
// second and peak memory at 64³ and 128³ with 8 random views of 128² per iteration (against a
// plain render of the same 8 views, measured in the same run), and the time to reach 30 dB on
// held-out views with the default settings (coarse to fine, Adam), whose whole run (PSNR and
// volume error against time) bench/plot_reconstruct.py plots.
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <glm/geometric.hpp>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench_scene.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"

using ivr::bench::median;
using ivr::bench::wall_seconds;
using nlohmann::json;

namespace {

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // Linux: KiB
}

json run_size(ivr::Device& device, int n, int views, int batch, int image, int repeats,
              double target_db, int max_iterations, int eval_every) {
  std::vector<ivr::Camera> train = ivr::bench::orbit(views / 2, {0, 0, 1}, 0, image);
  for (const ivr::Camera& c : ivr::bench::orbit(views - views / 2, {1, 0, 0}, 11.25, image))
    train.push_back(c);
  const ivr::Scene truth = ivr::bench::phantom_scene(n, train);
  const ivr::Image targets = ivr::render(device, truth);
  ivr::Scene held = ivr::bench::phantom_scene(n, ivr::bench::orbit(4, {0, 1, 0}, 10, image));
  const ivr::Image held_targets = ivr::render(device, held);
  json out = {{"n", n}, {"views", views}, {"batch", batch}, {"image", image}};

  // Throughput on the full grid (one level), after two warm-up iterations (kernel builds): the
  // default fixed-point (deterministic) gradient, and the float atomics' for comparison.
  auto throughput = [&](bool deterministic, std::uint64_t* device_bytes) {
    ivr::ReconstructOptions o;
    o.levels = 1;
    o.batch = batch;
    o.init = ivr::Init::constant;
    o.iterations = repeats + 2;
    o.deterministic = deterministic;
    ivr::Reconstruction r(device, truth, targets, o);
    r.step();
    r.step();
    std::vector<double> seconds;
    while (!r.done()) {
      const ivr::IterationRecord& rec = r.step();
      seconds.push_back(rec.seconds);
      *device_bytes = std::max(*device_bytes, rec.device_bytes);
    }
    return median(seconds);
  };
  std::uint64_t device_bytes = 0, float_bytes = 0;
  const double it = throughput(true, &device_bytes);
  const double it_float = throughput(false, &float_bytes);
  // Baseline: rendering the same number of views of the same volume.
  ivr::Scene eight = truth;
  eight.cameras.resize(std::size_t(batch));
  ivr::render(device, eight);
  std::vector<double> render_seconds;
  for (int i = 0; i < repeats; ++i)
    render_seconds.push_back(wall_seconds([&] { ivr::render(device, eight); }));
  const double rend = median(render_seconds);
  out["seconds_per_iteration"] = it;
  out["iterations_per_second"] = 1 / it;
  out["render_seconds_same_views"] = rend;
  out["iteration_over_render"] = it / rend;
  out["iterations_per_second_float_atomics"] = 1 / it_float;
  out["peak_device_mib_float_atomics"] = double(float_bytes) / (1 << 20);
  out["peak_device_mib"] = double(device_bytes) / (1 << 20);
  std::cerr << n << "³: " << 1 / it << " it/s (" << it / rend << "× a render of " << batch
            << " views), device " << double(device_bytes) / (1 << 20) << " MiB\n";

  // Time to target_db with the defaults (coarse to fine from 1/4 resolution).
  ivr::ReconstructOptions d;
  d.batch = batch;
  d.init = ivr::Init::constant;
  d.iterations = max_iterations;
  ivr::Reconstruction full(device, truth, targets, d);
  json curve = json::array();
  double clock = 0, reached = -1;
  int reached_at = -1;
  while (!full.done()) {
    clock += full.step().seconds;
    if (full.iteration() % eval_every && !full.done()) continue;
    const ivr::Scene now = full.result();  // evaluation time is not counted
    held.volume = now.volume;
    const double db = ivr::psnr(ivr::render(device, held), held_targets);
    const double error = ivr::relative_volume_error(now.volume, truth.volume);
    curve.push_back({full.iteration(), clock, db, error});
    std::cerr << "  it " << full.iteration() << " " << clock << " s  " << db << " dB  volume error "
              << error << "\n";
    if (db >= target_db && reached < 0) {
      reached = clock;
      reached_at = full.iteration();
    }
  }
  out["target_db"] = target_db;
  out["seconds_to_target"] = reached >= 0 ? json(reached) : json(nullptr);
  out["iterations_to_target"] = reached_at >= 0 ? json(reached_at) : json(nullptr);
  out["levels"] = full.levels();
  out["curve"] = curve;  // [iteration, seconds, held-out PSNR dB, relative volume error]
  out["peak_host_rss_mib"] = peak_rss_mib();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr density-reconstruction benchmark"};
  std::string device_sel, out_path, sizes = "64,128";
  int views = 32, batch = 8, image = 128, repeats = 7, max_iterations = 300, eval_every = 10;
  double target_db = 30;
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--sizes", sizes, "Phantom edges");
  app.add_option("--views", views, "Training views (two orbits)")->check(CLI::Range(2, 1000));
  app.add_option("--batch", batch, "Views per iteration")->check(CLI::Range(1, 1000));
  app.add_option("--image", image, "Image edge (pixels)")->check(CLI::Range(8, 4096));
  app.add_option("--repeats", repeats, "Timed iterations (median)")->check(CLI::Range(1, 100));
  app.add_option("--target-db", target_db, "Held-out PSNR to reach");
  app.add_option("--max-iterations", max_iterations, "Most iterations of the timed run");
  app.add_option("--eval-every", eval_every, "Iterations between held-out evaluations");
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  CLI11_PARSE(app, argc, argv);
  try {
    ivr::Device device(device_sel);
    json doc = {{"benchmark", "reconstruct"},
                {"ivr_version", IVR_VERSION_STRING},
                {"device", device.info().name},
                {"driver", device.info().driver},
                {"results", json::array()}};
    std::stringstream list(sizes);
    for (std::string item; std::getline(list, item, ',');)
      doc["results"].push_back(run_size(device, std::stoi(item), views, batch, image, repeats,
                                        target_db, max_iterations, eval_every));
    ivr::bench::emit_json(doc, out_path);
  } catch (const ivr::Error& e) {
    std::cerr << "ivr_reconstruct_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
