// results.hpp — what ivr-bench records: one Record per device × suite × case × implementation,
// with the check made before timing and the metrics; written as versioned JSON and flat CSV
// (device, suite, case, implementation, metric, value), read back for --compare.
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "measure.hpp"

namespace ivr::bench {

constexpr const char* kResultsSchema = "ivr-bench/1";
constexpr const char* kHostDevice = "host";  // the device key of the CPU baselines
constexpr const char* kGpuBaselineDevice = "cuda";  // the Python baselines' GPU runs

// The comparison made before an implementation's times count.
struct Check {
  bool passed = false;
  std::string against;  // what was compared with: "reference f64 (same step)", "ivr", ...
  std::string measure;  // "max_abs", "relative_l2", ...
  double error = 0, tolerance = 0;
};

struct Record {
  std::string device, suite, case_name, implementation;
  nlohmann::json params = nlohmann::json::object();   // volume, image, step, lanes, ...
  nlohmann::json metrics = nlohmann::json::object();  // name → number (units in the name)
  bool has_check = false;
  Check check;
  std::string note;  // why it was skipped or failed; empty when it ran
  // Curves for plots (e.g. a solver's residual per iteration): JSON only, not in the CSV.
  nlohmann::json series;
};

// Fills a record's metrics from a measurement: median_s, min_s, max_s, runs, device_*_s,
// peak_host_bytes, peak_host_increase_bytes.
void add_timing(Record& record, const Measurement& m);

class Results {
 public:
  nlohmann::json meta = nlohmann::json::object();  // schema, ivr version, machine, devices, options
  std::vector<Record> records;

  Record& add(Record r);
  // Speed and memory ratios of every baseline against ivr on the same case, per device.
  nlohmann::json ratios() const;
  nlohmann::json to_json() const;
  // PREFIX.json and PREFIX.csv, each through a temporary file and a rename.
  void write(const std::string& prefix) const;
};

// What this machine is: hostname, CPU model, logical cores, memory, OS.
nlohmann::json machine_json();

// Reads a results file (any ivr-bench/1 document); throws ivr::Error naming the file.
nlohmann::json read_results(const std::string& path);

// Prints per-case ratios of `current` against `baseline` (median time and peak memory) and returns
// the number of cases slower (or bigger) than the baseline by more than `threshold` (0.1 = 10 %).
int compare_results(const nlohmann::json& baseline, const nlohmann::json& current, double threshold,
                    std::ostream& out);

}  // namespace ivr::bench
