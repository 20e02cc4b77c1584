// measure.hpp — how ivr-bench times one operation: warm-up, then repeated runs until a time budget,
// with the median, min and max of the wall times (and of the device times where the operation
// reports them), and the peak host memory the timed runs needed.
#pragma once
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

namespace ivr::bench {

struct Budget {
  double seconds = 2.0;  // timed runs continue until this much wall time is spent...
  int min_runs = 3;      // ...and at least this many ran
  int max_runs = 100;
  int warmup = 1;  // untimed runs first (compiling, first touches)
};

struct Stats {
  std::vector<double> samples;
  double median = 0, min = 0, max = 0;
};
Stats stats_of(std::vector<double> samples);

// Host memory of this process from /proc/self/status (bytes; 0 where unavailable).
std::uint64_t resident_bytes();
std::uint64_t peak_resident_bytes();
// Resets the peak (VmHWM) to the current resident set (/proc/self/clear_refs, Linux ≥ 4.0);
// false where that is not possible (the peak then includes what came before).
bool reset_peak_resident();

struct Measurement {
  Stats wall;                     // seconds per run, host wall clock around the call
  std::optional<Stats> device;    // seconds per run the operation reported as device time
  std::uint64_t host_before = 0;  // resident set when the timed runs started
  std::uint64_t host_peak = 0;    // high-water mark during the timed runs
  bool peak_reset = false;        // host_peak covers the timed runs only
  bool timed = false;             // the result passed its check, and was timed
  std::uint64_t peak_increase() const {
    return host_peak > host_before ? host_peak - host_before : 0;
  }
};

// `run()` performs the operation once and returns its device seconds, or a negative number when it
// has none. Warm-up runs first; then `valid()` judges the warm-up's result (against a reference):
// when it fails nothing is timed (`timed` is false); otherwise timed runs follow until the budget.
template <class Run, class Valid>
Measurement measure(const Budget& budget, Run&& run, Valid&& valid) {
  for (int i = 0; i < std::max(budget.warmup, 1); ++i) run();
  Measurement m;
  if (!valid()) return m;
  m.timed = true;
  m.peak_reset = reset_peak_resident();
  m.host_before = resident_bytes();
  std::vector<double> wall, device;
  const auto start = std::chrono::steady_clock::now();
  auto spent = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  while (int(wall.size()) < budget.max_runs &&
         (int(wall.size()) < budget.min_runs || spent() < budget.seconds)) {
    const auto t0 = std::chrono::steady_clock::now();
    const double d = run();
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    if (d >= 0) device.push_back(d);
  }
  m.host_peak = std::max(peak_resident_bytes(), m.host_before);
  m.wall = stats_of(std::move(wall));
  if (!device.empty()) m.device = stats_of(std::move(device));
  return m;
}

// For operations checked elsewhere (or not checkable): always timed.
template <class Run>
Measurement measure(const Budget& budget, Run&& run) {
  return measure(budget, std::forward<Run>(run), [] { return true; });
}

}  // namespace ivr::bench
