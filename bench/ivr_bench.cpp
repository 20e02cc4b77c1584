// ivr_bench.cpp — `ivr-bench`: every benchmark suite on every OpenCL device it finds (or those the
// filters pick), next to the native and Python baselines, each result checked before it is
// timed; writes versioned JSON and CSV and compares against an earlier run.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <thread>

#include "ivr/core.hpp"
#include "runner/suite.hpp"

namespace {

using nlohmann::json;
namespace fs = std::filesystem;
namespace bench = ivr::bench;

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

// A device matches "N" (its index), "cpu"/"gpu"/"accelerator" (its type) or a case-insensitive
// substring of "platform device-name".
bool matches(const ivr::DeviceInfo& d, const std::string& selector) {
  if (selector.empty()) return true;
  if (std::all_of(selector.begin(), selector.end(), ::isdigit))
    return std::stoi(selector) == d.index;
  const std::string s = lower(selector);
  if (s == "cpu" || s == "gpu" || s == "accelerator") return lower(d.type) == s;
  return lower(d.platform + " " + d.name).find(s) != std::string::npos;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return text;
}

// A fresh folder under $TMPDIR (else /tmp), removed with everything in it when the run ends
// in any way, unless `keep`.
struct ScratchDir {
  std::string path;
  bool keep = false;
  ScratchDir() {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern = std::string(tmp && *tmp ? tmp : "/tmp") + "/ivr-bench-XXXXXX";
    if (!mkdtemp(pattern.data()))
      throw ivr::Error(ivr::Status::io, "cannot make a scratch folder '" + pattern + "'");
    path = pattern;
  }
  ~ScratchDir() {
    std::error_code ec;
    if (!keep) fs::remove_all(path, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ivr-bench: every ivr operation on every OpenCL device, against the baselines"};
  std::string device_filter, platform_filter, suites_text, output = "ivr-bench", compare_path,
                                                           input_path, python, data_dir,
                                                           frameworks_text = "jax,drjit,torch";
  bench::Budget budget;
  double threshold = 0.1, baseline_timeout = 900;
  bool quick = false, list = false, no_baselines = false, keep_cases = false;
  app.add_option("--device", device_filter,
                 "Only devices matching: index, cpu/gpu/accelerator, or a substring of "
                 "'platform name' (default: $IVR_DEVICE, else every device)");
  app.add_option("--platform", platform_filter, "Only devices of platforms containing this");
  app.add_option("--suite", suites_text,
                 "Comma-separated suites (default: all; --list names them)");
  app.add_option("--budget", budget.seconds, "Seconds of timed runs per measurement")
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--min-runs", budget.min_runs, "Timed runs at least")->check(CLI::Range(1, 1000));
  app.add_option("--max-runs", budget.max_runs, "Timed runs at most")->check(CLI::Range(1, 100000));
  app.add_flag("--quick", quick, "Small cases only (minutes, not an hour)");
  std::vector<std::string> case_filter;
  app.add_option("--cases", case_filter,
                 "Comma-separated: only the render and tomo cases whose name contains one of "
                 "these (e.g. v128_i256_s0.500)")
      ->delimiter(',');
  app.add_option("-o,--output", output, "Write PREFIX.json and PREFIX.csv");
  app.add_option("--compare", compare_path, "Print ratios against this earlier results file");
  app.add_option("--input", input_path,
                 "With --compare: compare this results file instead of running");
  app.add_option("--threshold", threshold, "Regression threshold for --compare (0.1 = 10 %)")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--baselines", frameworks_text,
                 "Comma-separated Python baselines: jax, drjit, torch, astra (the tomo suite's "
                 "projectors, GPU only; not in the default set) (empty: none)");
  app.add_flag("--no-baselines", no_baselines, "Neither the native nor the Python baselines");
  app.add_option("--python", python,
                 "Interpreter of the baselines (default: $IVR_BENCH_PYTHON, else .venv-bench)");
  app.add_option("--baseline-timeout", baseline_timeout, "Seconds per baseline run")
      ->check(CLI::Range(1.0, 86400.0));
  app.add_option("--data", data_dir, "Folder of the shared real volumes (default ../shared/data)");
  app.add_flag("--keep-cases", keep_cases, "Keep the baselines' case directories");
  app.add_flag("--list", list, "List the suites and the devices, then exit");
  CLI11_PARSE(app, argc, argv);

  try {
    if (!input_path.empty() && compare_path.empty())
      throw ivr::Error(ivr::Status::invalid_argument, "--input needs --compare");
    if (!input_path.empty()) {
      const json base = bench::read_results(compare_path), now = bench::read_results(input_path);
      return bench::compare_results(base, now, threshold, std::cout) > 0 ? 3 : 0;
    }
    std::vector<bench::Suite> suites;
    for (const std::string& name : split(suites_text)) {
      const auto& all = bench::all_suites();
      const auto it = std::find_if(all.begin(), all.end(),
                                   [&](const bench::Suite& s) { return s.name == name; });
      if (it == all.end()) {
        std::string known;
        for (const bench::Suite& s : all) known += (known.empty() ? "" : ", ") + s.name;
        throw ivr::Error(ivr::Status::invalid_argument,
                         "--suite: unknown suite '" + name + "' (known: " + known + ")");
      }
      suites.push_back(*it);
    }
    if (suites.empty()) suites = bench::all_suites();
    std::vector<std::string> frameworks = split(frameworks_text);
    for (const std::string& f : frameworks)
      if (f != "jax" && f != "drjit" && f != "torch" && f != "astra")
        throw ivr::Error(ivr::Status::invalid_argument, "--baselines: unknown baseline '" + f +
                                                            "' (known: jax, drjit, torch, astra)");
    json compare_base;
    if (!compare_path.empty()) compare_base = bench::read_results(compare_path);  // fail early
    if (budget.max_runs < budget.min_runs)
      throw ivr::Error(ivr::Status::invalid_argument, "--max-runs is below --min-runs");

    // The run's scratch folder (the baselines' cases, the compile suite's caches), removed at
    // exit unless --keep-cases. Made before any OpenCL call: PoCL's kernel cache goes into it.
    ScratchDir scratch;
    scratch.keep = keep_cases;
    const std::string work_dir = scratch.path;
    // PoCL's kernel cache: a fresh one of this run's own (unless the user chose one), so that
    // no other process shares or removes its files, and so that what is cold is cold.
    // POCL_KERNEL_CACHE=0 is not used: with it PoCL deletes a program's folder when the program
    // is released, and programs made from the same binary (ivr's disk cache) share that folder —
    // in one process or several — so a release removed the files of another program's pending
    // kernel compile ("Can't get stat() on …/uncached/…/brick_ranges/0-0-0").
    setenv("POCL_CACHE_DIR", (work_dir + "/pocl-cache").c_str(), 0);
    if (device_filter.empty())
      if (const char* env = std::getenv("IVR_DEVICE")) device_filter = env;
    std::vector<ivr::DeviceInfo> devices;
    for (const ivr::DeviceInfo& d : ivr::list_devices())
      if (matches(d, device_filter) &&
          lower(d.platform).find(lower(platform_filter)) != std::string::npos)
        devices.push_back(d);
    if (list) {
      std::cout << "suites:\n";
      for (const bench::Suite& s : bench::all_suites())
        std::cout << "  " << s.name << " — " << s.what << "\n";
      std::cout << "devices:\n";
      for (const ivr::DeviceInfo& d : devices)
        std::cout << "  " << d.index << ": " << d.platform << " / " << d.name << " (" << d.type
                  << ", " << d.driver << ")\n";
      return 0;
    }
    if (devices.empty())
      throw ivr::Error(ivr::Status::no_device, "no OpenCL device matches --device '" +
                                                   device_filter + "' and --platform '" +
                                                   platform_filter +
                                                   "' (ivr-bench --list shows them)");
    if (quick && !app.count("--budget")) budget.seconds = 0.5;

    bench::BaselineEnv baselines =
        bench::find_baselines(python, no_baselines ? std::vector<std::string>{} : frameworks);
    baselines.timeout = baseline_timeout;
    baselines.threads = int(std::thread::hardware_concurrency());
    if (!baselines.usable && !frameworks.empty() && !no_baselines)
      std::cerr << "ivr-bench: Python baselines skipped: " << baselines.note << "\n";
    if (data_dir.empty()) data_dir = std::string(IVR_SOURCE_DIR) + "/../shared/data";

    bench::Results results;
    results.meta = {{"ivr_version", IVR_VERSION_STRING},
                    {"created", utc_now()},
                    {"machine", bench::machine_json()},
                    {"options",
                     {{"budget_s", budget.seconds},
                      {"min_runs", budget.min_runs},
                      {"max_runs", budget.max_runs},
                      {"warmup_runs", budget.warmup},
                      {"quick", quick},
                      {"statistic", "median of the timed runs (wall clock around the call)"}}},
                    {"baselines",
                     {{"python", baselines.python},
                      {"usable", baselines.usable},
                      {"note", baselines.note},
                      {"frameworks", baselines.frameworks},
                      {"native", !no_baselines}}}};
    json devs = json::array(), suite_names = json::array();
    const json every = json::parse(ivr::devices_json())["devices"];  // as `ivr devices --json`
    for (const ivr::DeviceInfo& d : devices) {
      json entry = every.at(std::size_t(d.index));
      entry["key"] = d.platform + " / " + d.name;  // the results' device field
      devs.push_back(entry);
    }
    for (const bench::Suite& s : suites) suite_names.push_back(s.name);
    results.meta["devices"] = devs;
    results.meta["suites"] = suite_names;

    std::vector<std::string> failures;
    bool cpu_baselines_done = false, gpu_baselines_done = false;
    for (std::size_t k = 0; k < devices.size(); ++k) {
      const ivr::DeviceInfo& info = devices[k];
      ivr::Device device(std::to_string(info.index));
      std::cerr << "ivr-bench: device " << info.index << ": " << info.platform << " / " << info.name
                << "\n";
      bench::Context ctx{device,
                         info.platform + " / " + info.name,
                         budget,
                         quick,
                         k == 0 && !no_baselines,
                         results,
                         baselines,
                         work_dir,
                         data_dir,
                         {}};
      ctx.cases = case_filter;
      // The Python baselines once per kind of device: on the CPU beside the first CPU device
      // (or the first device of any kind but GPU), on the GPU beside the first GPU device.
      const bool gpu = info.type == "gpu";
      ctx.baseline_device = gpu ? "gpu" : "cpu";
      ctx.python_baselines = !no_baselines && !(gpu ? gpu_baselines_done : cpu_baselines_done);
      (gpu ? gpu_baselines_done : cpu_baselines_done) = true;
      for (const bench::Suite& s : suites) {
        const auto start = std::chrono::steady_clock::now();
        try {
          s.run(ctx);
        } catch (const ivr::Error& e) {  // one suite failing does not lose the others' results
          std::cerr << "ivr-bench: " << s.name << " on " << ctx.device_key
                    << ": error: " << e.what() << "\n";
          ctx.failures.push_back(s.name + ": " + e.what());
        }
        std::cerr << "ivr-bench: " << s.name << " done in "
                  << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
                  << " s\n";
        // What is measured so far, should the run be stopped before the end (the final write
        // below replaces it; "partial" says which one a file is).
        results.meta["partial"] = true;
        results.write(output);
      }
      failures.insert(failures.end(), ctx.failures.begin(), ctx.failures.end());
    }
    results.meta["failures"] = failures;
    results.meta["partial"] = false;
    results.write(output);
    std::cerr << "ivr-bench: wrote " << output << ".json and " << output << ".csv\n";
    if (keep_cases) std::cerr << "ivr-bench: the baselines' cases are in " << work_dir << "\n";

    int status = failures.empty() ? 0 : 1;
    for (const std::string& f : failures) std::cerr << "ivr-bench: FAILED " << f << "\n";
    if (!compare_base.is_null() &&
        bench::compare_results(compare_base, results.to_json(), threshold, std::cout) > 0 &&
        status == 0)
      status = 3;
    return status;
  } catch (const ivr::Error& e) {
    std::cerr << "ivr-bench: error: " << e.what() << "\n";
    return 1;
  }
}
