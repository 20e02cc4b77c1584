// suite.cpp — the suites' registry and the checks and records they share.
#include "suite.hpp"

#include <cmath>
#include <iostream>

namespace ivr::bench {

const std::vector<Suite>& all_suites() {
  static const std::vector<Suite> suites = {
      {"compile", "kernel compile time, cold and from the program cache", compile_suite},
      {"render", "forward render vs the native C++ marcher and the Python baselines", render_suite},
      {"gradient", "density gradient (adjoint) vs native, JAX, Dr.Jit, PyTorch", gradient_suite},
      {"planner", "forward mode vs adjoint by parameter count (TF lanes): the crossover",
       planner_suite},
      {"integrators", "every integrator's speed against its error", integrators_suite},
      {"tomo", "absorption projector and back-projector throughput", tomo_suite},
      {"rays", "ray lists against the same rays as cameras' pixels; sightlines", rays_suite},
      {"out_of_core", "bricked render and gradient against in core; 1024³ under a 1 GiB cap (--cases v1024)", out_of_core_suite},
      {"reconstruct", "reconstruction iterations per second", reconstruct_suite},
      {"scaling", "time and memory as volume, image and step grow", scaling_suite},
      {"empty_space", "empty-space skipping on against off: render and gradient",
       empty_space_suite},
      {"stability", "the hard cases: errors against float64, f32 gradients, no NaN/Inf",
       stability_suite},
  };
  return suites;
}

namespace {

template <class T>
Difference difference_of(const std::vector<T>& got, const std::vector<double>& ref) {
  Difference d;
  if (got.size() != ref.size() || got.empty()) {
    d.max_abs = d.relative_l2 = INFINITY;
    return d;
  }
  double num = 0, den = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const double g = double(got[i]), r = ref[i];
    if (!std::isfinite(g) || !std::isfinite(r)) {
      d.max_abs = d.relative_l2 = INFINITY;
      return d;
    }
    const double e = std::abs(g - r);
    d.max_abs = std::max(d.max_abs, e);
    d.ref_max = std::max(d.ref_max, std::abs(r));
    num += e * e;
    den += r * r;
  }
  d.relative_l2 = den > 0 ? std::sqrt(num / den) : (num > 0 ? INFINITY : 0);
  return d;
}

}  // namespace

Difference difference(const std::vector<float>& got, const std::vector<double>& ref) {
  return difference_of(got, ref);
}
Difference difference(const std::vector<double>& got, const std::vector<double>& ref) {
  return difference_of(got, ref);
}

Check check_max(const Difference& d, const std::string& against, double atol, double rtol) {
  Check c;
  c.against = against;
  c.measure = "max_abs";
  c.error = d.max_abs;
  c.tolerance = atol + rtol * d.ref_max;
  c.passed = d.max_abs <= c.tolerance;
  return c;
}

Check check_l2(const Difference& d, const std::string& against, double tolerance) {
  Check c;
  c.against = against;
  c.measure = "relative_l2";
  c.error = d.relative_l2;
  c.tolerance = tolerance;
  c.passed = d.relative_l2 <= tolerance;
  return c;
}

std::string scene_case(int volume, int image, double step) {
  return "v" + std::to_string(volume) + "_i" + std::to_string(image) + "_s" +
         std::to_string(step).substr(0, 5);
}

std::vector<double> widen(const std::vector<float>& v) {
  return std::vector<double>(v.begin(), v.end());
}

void record_checked(Context& ctx, Record r, const Check& check) {
  r.has_check = true;
  r.check = check;
  if (!check.passed) {  // keep the errors (to see why), drop every time and memory figure
    nlohmann::json kept = nlohmann::json::object();
    for (auto it = r.metrics.begin(); it != r.metrics.end(); ++it)
      if (it.key().rfind("error", 0) == 0 || it.key().rfind("relative", 0) == 0 ||
          it.key() == "loss")
        kept[it.key()] = it.value();
    r.metrics = kept;
    r.note = "check failed: " + check.measure + " " + std::to_string(check.error) + " > " +
             std::to_string(check.tolerance) + " against " + check.against + " (times not counted)";
    std::cerr << "ivr-bench: " << r.suite << "/" << r.case_name << " " << r.implementation << ": "
              << r.note << "\n";
    if (r.implementation.rfind("ivr", 0) == 0 || r.implementation == "native")
      ctx.failures.push_back(r.suite + "/" + r.case_name + " " + r.implementation);
  }
  ctx.results.add(std::move(r));
}

std::uint64_t operation_memory(const Context& ctx, const Measurement& m,
                               std::uint64_t device_bytes) {
  const bool host_device = ctx.device.info().type == "cpu";
  return host_device ? std::max<std::uint64_t>(m.peak_increase(), device_bytes)
                     : m.peak_increase() + device_bytes;
}

void run_python_baselines(Context& ctx, const std::string& suite, const std::string& case_name,
                          const nlohmann::json& params, const std::string& case_dir,
                          const std::string& task, const std::string& output,
                          const std::function<Check(const BaselineRun&, Record&)>& compare) {
  if (!ctx.python_baselines) return;
  for (const std::string& fw : ctx.baselines.frameworks) {
    if (!baseline_does(fw, task)) continue;  // e.g. astra in the march suites
    Record r{ctx.baseline_device == "gpu" ? kGpuBaselineDevice : kHostDevice, suite, case_name, fw,
             params};
    if (!ctx.baselines.usable) {
      r.note = "skipped: " + ctx.baselines.note;
      ctx.results.add(std::move(r));
      continue;
    }
    std::cerr << "ivr-bench: " << suite << "/" << case_name << " " << fw << " " << task << "...\n";
    const BaselineRun run = run_baseline(ctx.baselines, fw, task, case_dir, ctx.budget.seconds,
                                         output, ctx.baseline_device);
    if (run.result.contains("version")) r.params["version"] = run.result["version"];
    if (!run.ok) {
      r.note = (run.available ? "failed: " : "skipped: ") + run.note;
      std::cerr << "ivr-bench: " << fw << ": " << r.note << "\n";
      ctx.results.add(std::move(r));
      continue;
    }
    const nlohmann::json& j = run.result;
    for (const char* k : {"median_s", "min_s", "max_s", "first_call_s"})
      if (j.contains(k)) r.metrics[k] = j[k];
    r.metrics["runs"] = j.value("times_s", nlohmann::json::array()).size();
    r.metrics["samples_s"] = j.value("times_s", nlohmann::json::array());
    r.metrics["peak_host_bytes"] = j.value("peak_rss_bytes", 0.0);
    r.metrics["peak_host_increase_bytes"] = j.value("peak_increase_bytes", 0.0);
    r.metrics["memory_bytes"] = j.value("peak_increase_bytes", 0.0);
    if (ctx.baseline_device == "gpu") {  // the GPU's memory, as the framework reports it
      r.params["device_name"] = j.value("device_name", "");
      for (const char* k : {"device_peak_increase_bytes", "device_peak_bytes"})
        if (j.contains(k) && j[k].is_number()) {
          r.metrics[k] = j[k];
          r.metrics["memory_bytes"] = j[k];
          r.params["memory"] = k;
          break;
        }
    }
    r.params["peak_reset"] = j.value("peak_reset", false);
    if (std::isfinite(run.loss)) r.metrics["loss"] = run.loss;
    const Check check = compare(run, r);
    record_checked(ctx, std::move(r), check);
  }
}

}  // namespace ivr::bench
