// suite.hpp — what every ivr-bench suite gets (the device, the budget, the results, the baseline
// environment) and the checks they share: an implementation's output against a reference with
// absolute and relative tolerances, made before its times count.
#pragma once
#include <cstdlib>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "baselines.hpp"
#include "ivr/core.hpp"
#include "measure.hpp"
#include "results.hpp"

namespace ivr::bench {

struct Context {
  Device& device;
  std::string device_key;  // "platform / device name"
  Budget budget;
  bool quick = false;
  bool host_baselines = true;  // run the native CPU baselines (once per run: the first device)
  Results& results;
  const BaselineEnv& baselines;
  std::string work_dir;               // scratch for the baselines' case directories
  std::string data_dir;               // ../shared/data (real volumes)
  std::vector<std::string> failures;  // checks that failed: the run's exit status says so
  // Run the Python baselines, on the CPU ("cpu": once per run, beside the first device that is
  // not a GPU) or on a GPU ("gpu": JAX, PyTorch, Dr.Jit and ASTRA on CUDA, beside the first GPU).
  bool python_baselines = true;
  std::string baseline_device = "cpu";
  // --cases: only the cases whose name contains one of these (empty: every case). The render and
  // tomo suites, whose cases each cost their own float64 references, honour it.
  std::vector<std::string> cases = {};
  bool wants(const std::string& case_name) const {
    if (cases.empty()) return true;
    for (const std::string& c : cases)
      if (case_name.find(c) != std::string::npos) return true;
    return false;
  }
};

struct Suite {
  std::string name, what;
  std::function<void(Context&)> run;
};
// Every suite, in the order they run.
const std::vector<Suite>& all_suites();

// |got − ref| over every element: the largest, the reference's largest magnitude, and
// ‖got − ref‖₂ / ‖ref‖₂. NaN or Inf anywhere, or a size mismatch, gives an infinite error.
struct Difference {
  double max_abs = 0, ref_max = 0, relative_l2 = 0;
};
Difference difference(const std::vector<float>& got, const std::vector<double>& ref);
Difference difference(const std::vector<double>& got, const std::vector<double>& ref);

// Passes when max_abs ≤ atol + rtol · ref_max (the error recorded is max_abs).
Check check_max(const Difference& d, const std::string& against, double atol, double rtol);
// Passes when relative_l2 ≤ tolerance.
Check check_l2(const Difference& d, const std::string& against, double tolerance);

std::vector<double> widen(const std::vector<float>& v);

// Sets an environment variable for the lifetime of the object, then restores it (the suites
// time ivr under $IVR_CACHE_DIR, $IVR_BUILD_OPTIONS, $IVR_PACKET settings).
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old, had_ = true;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() { had_ ? (void)::setenv(name_, old_.c_str(), 1) : (void)::unsetenv(name_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::string old_;
  bool had_ = false;
};

// The case name of a benchmark-scene case, e.g. "v128_i256_s0.500" (volume, image, step).
std::string scene_case(int volume, int image, double step);

// Records `r` with its check; a failed check drops the times (they do not count) and is listed in
// ctx.failures for ivr's own implementations.
void record_checked(Context& ctx, Record r, const Check& check);

// The memory an operation needs: on a CPU device buffers are host memory (the larger of the two
// figures), on others the device's buffers come on top of the host's.
std::uint64_t operation_memory(const Context& ctx, const Measurement& m,
                               std::uint64_t device_bytes);

// Runs every Python baseline of ctx.baselines that does `task` (baseline_does) on `case_dir` and
// records each (device "host", or "cuda" beside a GPU) with the check `compare` makes of its output
// (which may add metrics to the record, such as an error); skipped frameworks are recorded with
// their note and no metrics.
void run_python_baselines(Context& ctx, const std::string& suite, const std::string& case_name,
                          const nlohmann::json& params, const std::string& case_dir,
                          const std::string& task, const std::string& output,
                          const std::function<Check(const BaselineRun&, Record&)>& compare);

// The suites (bench/suites/*.cpp).
void render_suite(Context& ctx);
void gradient_suite(Context& ctx);
void planner_suite(Context& ctx);
void integrators_suite(Context& ctx);
void tomo_suite(Context& ctx);
void rays_suite(Context& ctx);
void out_of_core_suite(Context& ctx);
void reconstruct_suite(Context& ctx);
void scaling_suite(Context& ctx);
void compile_suite(Context& ctx);
void empty_space_suite(Context& ctx);
void stability_suite(Context& ctx);

}  // namespace ivr::bench
