// measure.cpp — statistics of repeated runs and the process's host memory (Linux /proc).
#include "measure.hpp"

#include <fstream>
#include <sstream>
#include <string>

namespace ivr::bench {

Stats stats_of(std::vector<double> samples) {
  Stats s;
  s.samples = samples;
  if (samples.empty()) return s;
  std::sort(samples.begin(), samples.end());
  const std::size_t n = samples.size();
  s.median = n % 2 ? samples[n / 2] : 0.5 * (samples[n / 2 - 1] + samples[n / 2]);
  s.min = samples.front();
  s.max = samples.back();
  return s;
}

namespace {

std::uint64_t status_kib(const std::string& field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, field.size() + 1, field + ":") == 0) {
      std::istringstream value(line.substr(field.size() + 1));
      std::uint64_t kib = 0;
      value >> kib;
      return kib;
    }
  return 0;
}

}  // namespace

std::uint64_t resident_bytes() {
  return 1024 * status_kib("VmRSS");
}

std::uint64_t peak_resident_bytes() {
  return 1024 * status_kib("VmHWM");
}

bool reset_peak_resident() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return bool(out);
}

}  // namespace ivr::bench
