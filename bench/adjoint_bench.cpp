// adjoint_bench.cpp — gradient benchmark: for 128³ and 256³ volumes into 256² images at steps 0.5
// and 0.1, the forward render's kernel time next to the gradient's (primal march + loss + adjoint
// march, d mse / d density against a target rendered from a perturbed volume), their ratio, and
// the peak memory of one gradient evaluation: AdjointGradient::device_bytes and the peak resident set of
// a fresh process (on a CPU device the device buffers live in host memory). Checks the two
// targets of issue 3: gradient <= 3x render, peak memory at step 0.1 within 5% of step 0.5.
// Prints one JSON document.
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bench_scene.hpp"
#include "bench_support.hpp"
#include "ivr/core.hpp"

extern char** environ;

using nlohmann::json;

namespace {

using ivr::bench::median;
using ivr::bench::wall_seconds;

constexpr double kRatioTarget = 3.0;    // gradient kernel time <= 3x render kernel time
constexpr double kMemoryTarget = 0.05;  // peak RSS at step 0.1 within 5% of step 0.5
constexpr double kSteps[] = {0.5, 0.1};
constexpr int kImage = 256;

ivr::AdjointOptions gradient_options(double step) {
  return ivr::AdjointOptions{ivr::Precision::f32, step,
                              ivr::Loss::mse,      /*density=*/true,
                              /*tf=*/false,        /*background=*/false};
}

// CPU time of every thread of this process but the calling one: on a CPU device, the driver's
// worker threads, which run the kernels (and the call's buffer transfers). Unlike the kernel's
// wall time it hardly grows when other processes compete for the cores.
double worker_cpu_seconds() {
  const auto seconds = [](clockid_t clock) {
    timespec t{};
    clock_gettime(clock, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
  };
  return seconds(CLOCK_PROCESS_CPUTIME_ID) - seconds(CLOCK_THREAD_CPUTIME_ID);
}

long max_rss_kib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;  // Linux: KiB
}

// The high-water mark of this process image's resident set (/proc/self/status VmHWM, KiB; -1
// where there is no procfs): a cross-check of ru_maxrss that exec resets.
long vm_hwm_kib() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

// The hidden child mode: one gradient in this (fresh) process, then its peak resident set.
int measure_memory(const std::string& device_sel, int n, double step) {
  ivr::Device device(device_sel);
  const ivr::Scene scene = ivr::bench::bench_scene(n, kImage);
  const ivr::Image target = ivr::bench::perturbed_target(device, scene, step);
  const long before = max_rss_kib();
  const ivr::AdjointGradient g = ivr::adjoint(device, scene, target, gradient_options(step));
  const long after = max_rss_kib();
  std::cout << json{{"max_rss_kib", after},       {"max_rss_kib_before_gradient", before},
                    {"vm_hwm_kib", vm_hwm_kib()}, {"device_bytes", g.device_bytes},
                    {"samples", g.samples},       {"loss", g.loss}}
                   .dump()
            << std::endl;
  return 0;
}

// Re-executes this program with --measure-memory and parses the child's one line of JSON.
json child_memory(const std::string& device_sel, int n, double step) {
  std::vector<std::string> args = {"/proc/self/exe", "--measure-memory", std::to_string(n),
                                   std::to_string(step)};
  if (!device_sel.empty()) args.insert(args.end(), {"--device", device_sel});
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error("pipe() failed");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  posix_spawn_file_actions_addclose(&actions, fds[1]);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(fds[1]);
  if (rc != 0) {
    close(fds[0]);
    throw std::runtime_error("could not re-execute the benchmark for the memory measurement");
  }
  std::string out;
  char buf[4096];
  for (ssize_t r; (r = read(fds[0], buf, sizeof buf)) > 0;) out.append(buf, std::size_t(r));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("memory measurement child failed (volume " + std::to_string(n) +
                             ", step " + std::to_string(step) + ")");
  std::istringstream lines(out);
  std::string line, last;
  while (std::getline(lines, line))
    if (!line.empty() && line.front() == '{') last = line;
  return json::parse(last);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr gradient benchmark: adjoint gradient vs forward render, time and peak memory"};
  std::string device_sel, out_path;
  int repeats = 5, memory_repeats = 3;
  bool quick = false;
  std::vector<double> measure;  // hidden child mode: N STEP
  app.add_option("--device", device_sel, "Device selector (default: $IVR_DEVICE)");
  app.add_option("--repeats", repeats, "Timed runs per configuration (median reported)")
      ->check(CLI::Range(1, 100));
  app.add_option("--memory-repeats", memory_repeats,
                 "Fresh processes per memory measurement (median reported)")
      ->check(CLI::Range(1, 20));
  app.add_option("-o,--output", out_path, "Also write the JSON here");
  app.add_flag("--quick", quick, "Only the 128³ volume");
  app.add_option("--measure-memory", measure)->expected(2)->group("");
  CLI11_PARSE(app, argc, argv);

  try {
    if (!measure.empty()) return measure_memory(device_sel, int(measure[0]), measure[1]);
    const std::vector<int> volumes = quick ? std::vector<int>{128} : std::vector<int>{128, 256};

    // Memory first, while this process is still small: a child's ru_maxrss starts at the
    // resident set of the process that spawned it (at exec Linux folds the high-water mark of the
    // memory it replaces into ru_maxrss, and a spawned child's memory before exec is, or copies,
    // its parent's), so the children must come from a process that has not yet loaded the OpenCL
    // platform or any volume. One fresh child per measurement (ru_maxrss only grows within a
    // process), the configurations interleaved; a first, discarded child fills the program caches
    // so that no measured child compiles.
    child_memory(device_sel, volumes.front(), kSteps[0]);
    std::vector<std::vector<json>> memory_runs(volumes.size() * std::size(kSteps));
    for (int r = 0; r < memory_repeats; ++r)
      for (std::size_t v = 0; v < volumes.size(); ++v)
        for (std::size_t k = 0; k < std::size(kSteps); ++k)
          memory_runs[v * std::size(kSteps) + k].push_back(
              child_memory(device_sel, volumes[v], kSteps[k]));

    ivr::Device device(device_sel);
    json configs = json::array();
    json ratio_checks = json::array(), memory_checks = json::array();
    bool ratio_pass = true, memory_pass = true;
    double worst_ratio = 0, worst_memory = 0;
    for (int n : volumes) {
      const ivr::Scene scene = ivr::bench::bench_scene(n, kImage);
      for (double step : kSteps) {
        const ivr::Image target = ivr::bench::perturbed_target(device, scene, step);
        const ivr::RenderOptions ro{ivr::Precision::f32, step};
        const ivr::AdjointOptions go = gradient_options(step);
        ivr::RenderStats stats;
        ivr::render(device, scene, ro, &stats);                      // warm-up, compiles
        ivr::AdjointGradient g = ivr::adjoint(device, scene, target, go);  // warm-up, compiles
        // Interleaved (render, gradient, render, ...), so that a burst of load from elsewhere on
        // this shared machine hits both.
        std::vector<double> render_s, grad_s, render_wall, grad_wall, render_cpu, grad_cpu,
            pair_ratio;
        for (int r = 0; r < repeats; ++r) {
          double cpu = worker_cpu_seconds();
          render_wall.push_back(wall_seconds([&] { ivr::render(device, scene, ro, &stats); }));
          render_cpu.push_back(worker_cpu_seconds() - cpu);
          render_s.push_back(stats.kernel_seconds);
          cpu = worker_cpu_seconds();
          grad_wall.push_back(wall_seconds([&] { g = ivr::adjoint(device, scene, target, go); }));
          grad_cpu.push_back(worker_cpu_seconds() - cpu);
          grad_s.push_back(g.kernel_seconds);
          pair_ratio.push_back(grad_s.back() / render_s.back());
        }
        const double rk = median(render_s), gk = median(grad_s), ratio = gk / rk;
        const std::vector<json>& mem = memory_runs[configs.size()];
        std::vector<double> rss, hwm, before;
        for (const json& m : mem) {
          rss.push_back(m["max_rss_kib"].get<double>());
          hwm.push_back(m["vm_hwm_kib"].get<double>());
          before.push_back(m["max_rss_kib_before_gradient"].get<double>());
        }
        json c = {{"volume", n},
                  {"image", kImage},
                  {"step", step},
                  {"render",
                   {{"kernel_ms", 1e3 * rk},
                    {"total_ms", 1e3 * median(render_wall)},
                    {"worker_cpu_ms", 1e3 * median(render_cpu)},
                    {"samples", stats.samples},
                    {"samples_per_s", double(stats.samples) / rk}}},
                  {"gradient",
                   {{"kernel_ms", 1e3 * gk},
                    {"total_ms", 1e3 * median(grad_wall)},
                    {"worker_cpu_ms", 1e3 * median(grad_cpu)},
                    {"adjoint_samples", g.samples},
                    {"loss", g.loss},
                    {"device_bytes", g.device_bytes}}},
                  {"ratio", ratio},
                  {"ratio_median_of_pairs", median(pair_ratio)},
                  {"ratio_worker_cpu", median(grad_cpu) / median(render_cpu)},
                  {"memory",
                   {{"peak_rss_kib", median(rss)},
                    {"peak_rss_kib_runs", rss},
                    {"vm_hwm_kib", median(hwm)},
                    {"peak_rss_kib_before_gradient", median(before)},
                    {"gradient_rss_increase_kib", median(rss) - median(before)}}}};
        for (double s : render_s) c["render"]["kernel_ms_runs"].push_back(1e3 * s);
        for (double s : grad_s) c["gradient"]["kernel_ms_runs"].push_back(1e3 * s);
        const bool ok = ratio <= kRatioTarget;
        ratio_pass = ratio_pass && ok;
        worst_ratio = std::max(worst_ratio, ratio);
        ratio_checks.push_back({{"volume", n}, {"step", step}, {"ratio", ratio}, {"pass", ok}});
        std::cerr << "volume " << n << "³ image " << kImage << "² step " << step << ": render "
                  << 1e3 * rk << " ms, gradient " << 1e3 * gk << " ms (kernel), ratio " << ratio
                  << ", device_bytes " << g.device_bytes << ", peak RSS " << median(rss) / 1024
                  << " MiB\n";
        configs.push_back(c);
      }
    }

    for (std::size_t i = 0; i + 1 < configs.size(); i += 2) {
      const json &coarse = configs[i], &fine = configs[i + 1];  // steps 0.5, 0.1 of one volume
      const double a = coarse["memory"]["peak_rss_kib"].get<double>(),
                   b = fine["memory"]["peak_rss_kib"].get<double>();
      const double rel = b / a - 1;
      const bool ok = std::abs(rel) <= kMemoryTarget;
      memory_pass = memory_pass && ok;
      worst_memory = std::max(worst_memory, std::abs(rel));
      memory_checks.push_back({{"volume", coarse["volume"]},
                               {"peak_rss_kib_step_0.5", a},
                               {"peak_rss_kib_step_0.1", b},
                               {"relative_change", rel},
                               {"device_bytes_step_0.5", coarse["gradient"]["device_bytes"]},
                               {"device_bytes_step_0.1", fine["gradient"]["device_bytes"]},
                               {"pass", ok}});
      std::cerr << "volume " << coarse["volume"] << "³: peak RSS " << a / 1024
                << " MiB (step 0.5), " << b / 1024 << " MiB (step 0.1), change " << 100 * rel
                << "%\n";
    }

    const json result = {
        {"benchmark", "adjoint"},
        {"ivr_version", IVR_VERSION_STRING},
        {"device", device.info().name},
        {"platform", device.info().platform},
        {"repeats", repeats},
        {"memory_repeats", memory_repeats},
        {"statistic", "median"},
        {"gradient", "d mse / d density, float32, target rendered from a perturbed volume"},
        {"method",
         {{"time", "kernel ms (profiling events), medians of interleaved render/gradient runs"},
          {"ratio", "median gradient kernel ms / median render kernel ms"},
          {"memory",
           "ru_maxrss of a fresh child process after one gradient (median of "
           "memory_repeats children); vm_hwm_kib is /proc VmHWM, a cross-check"}}},
        {"configs", configs},
        {"targets",
         {{"gradient_over_render",
           {{"limit", kRatioTarget},
            {"worst", worst_ratio},
            {"pass", ratio_pass},
            {"checks", ratio_checks}}},
          {"peak_memory_step_0.1_vs_0.5",
           {{"limit", kMemoryTarget},
            {"worst", worst_memory},
            {"pass", memory_pass},
            {"checks", memory_checks}}}}}};
    ivr::bench::emit_json(result, out_path);
  } catch (const ivr::Error& e) {
    std::cerr << "ivr_adjoint_bench: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ivr_adjoint_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
