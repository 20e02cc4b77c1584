// results.cpp — ivr-bench's records as JSON and CSV, the ratios against the baselines, the machine
// metadata, and the comparison against an earlier results file.
#include "results.hpp"

#include <sys/utsname.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <thread>

#include "ivr/core.hpp"

namespace ivr::bench {

using nlohmann::json;

namespace {

json stats_json(const Stats& s) {
  return {{"median", s.median}, {"min", s.min}, {"max", s.max}};
}

void write_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    if (!out) throw Error(Status::io, "cannot write " + tmp);
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error(Status::io, "cannot rename " + tmp + " to " + path + ": " + ec.message());
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string key_of(const json& r) {
  return r.value("device", "") + "|" + r.value("suite", "") + "|" + r.value("case", "") + "|" +
         r.value("implementation", "");
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      return colon == std::string::npos ? line : line.substr(colon + 2);
    }
  return "unknown";
}

std::uint64_t memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string name;
  std::uint64_t kib = 0;
  while (in >> name >> kib) {
    if (name == "MemTotal:") return kib * 1024;
    in.ignore(1 << 10, '\n');
  }
  return 0;
}

}  // namespace

void add_timing(Record& r, const Measurement& m) {
  r.metrics["median_s"] = m.wall.median;
  r.metrics["min_s"] = m.wall.min;
  r.metrics["max_s"] = m.wall.max;
  r.metrics["runs"] = m.wall.samples.size();
  r.metrics["samples_s"] = m.wall.samples;
  if (m.device) {
    r.metrics["device_median_s"] = m.device->median;
    r.metrics["device_min_s"] = m.device->min;
    r.metrics["device_max_s"] = m.device->max;
    // What the call costs beyond its kernels: 1 is kernel speed.
    if (m.device->median > 0) r.metrics["end_to_end_over_kernel"] = m.wall.median / m.device->median;
  }
  r.metrics["peak_host_bytes"] = m.host_peak;
  r.metrics["peak_host_increase_bytes"] = m.peak_increase();
  r.params["peak_reset"] = m.peak_reset;
}

Record& Results::add(Record r) {
  records.push_back(std::move(r));
  return records.back();
}

json Results::ratios() const {
  json out = json::array();
  for (const Record& ivr : records) {
    // Every baseline against ivr one-shot and ivr resident (its data already on the device).
    if ((ivr.implementation != "ivr" && ivr.implementation != "ivr-resident") ||
        !ivr.metrics.contains("median_s"))
      continue;
    for (const Record& b : records) {
      if ((b.device != kHostDevice && b.device != kGpuBaselineDevice) || b.suite != ivr.suite ||
          b.case_name != ivr.case_name || !b.metrics.contains("median_s"))
        continue;
      json r = {
          {"device", ivr.device},
          {"suite", ivr.suite},
          {"case", ivr.case_name},
          {"ivr", ivr.implementation},
          {"baseline", b.implementation},
          {"baseline_device", b.device},
          {"speedup", b.metrics["median_s"].get<double>() / ivr.metrics["median_s"].get<double>()}};
      // A memory of 0 (buffers reused from call to call) has no ratio.
      if (b.metrics.contains("memory_bytes") && ivr.metrics.contains("memory_bytes") &&
          ivr.metrics["memory_bytes"].get<double>() > 0 &&
          b.metrics["memory_bytes"].get<double>() > 0)
        r["memory_ratio"] =
            b.metrics["memory_bytes"].get<double>() / ivr.metrics["memory_bytes"].get<double>();
      out.push_back(r);
    }
  }
  return out;
}

json Results::to_json() const {
  json doc = meta;
  doc["schema"] = kResultsSchema;
  json rs = json::array();
  for (const Record& r : records) {
    json j = {{"device", r.device},  {"suite", r.suite},
              {"case", r.case_name}, {"implementation", r.implementation},
              {"params", r.params},  {"metrics", r.metrics}};
    if (r.has_check)
      j["check"] = {{"passed", r.check.passed},
                    {"against", r.check.against},
                    {"measure", r.check.measure},
                    {"error", r.check.error},
                    {"tolerance", r.check.tolerance}};
    if (!r.note.empty()) j["note"] = r.note;
    if (!r.series.is_null()) j["series"] = r.series;
    rs.push_back(j);
  }
  doc["results"] = rs;
  doc["ratios"] = ratios();
  return doc;
}

void Results::write(const std::string& prefix) const {
  const json doc = to_json();
  std::ostringstream csv;
  csv << std::setprecision(9) << "device,suite,case,implementation,metric,value\n";
  for (const Record& r : records) {
    const std::string head = csv_field(r.device) + "," + csv_field(r.suite) + "," +
                             csv_field(r.case_name) + "," + csv_field(r.implementation) + ",";
    for (auto it = r.metrics.begin(); it != r.metrics.end(); ++it)
      if (it.value().is_number())
        csv << head << csv_field(it.key()) << "," << it.value().get<double>() << "\n";
    if (r.has_check) csv << head << "check_error," << r.check.error << "\n";
  }
  write_atomically(prefix + ".json", doc.dump(2) + "\n");
  write_atomically(prefix + ".csv", csv.str());
}

json machine_json() {
  char host[256] = {0};
  gethostname(host, sizeof host - 1);
  utsname u{};
  uname(&u);
  return {{"hostname", host},
          {"cpu", cpu_model()},
          {"logical_cores", std::thread::hardware_concurrency()},
          {"memory_bytes", memory_bytes()},
          {"os", std::string(u.sysname) + " " + u.release + " " + u.machine}};
}

json read_results(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(Status::io, "cannot read the results file " + path);
  json doc;
  try {
    in >> doc;
  } catch (const json::exception& e) {
    throw Error(Status::io, path + ": not JSON (" + std::string(e.what()) + ")");
  }
  if (!doc.is_object() || doc.value("schema", "") != kResultsSchema || !doc.contains("results"))
    throw Error(Status::invalid_argument,
                path + ": not an ivr-bench results file (schema " + kResultsSchema + ")");
  return doc;
}

int compare_results(const json& baseline, const json& current, double threshold,
                    std::ostream& out) {
  std::map<std::string, const json*> old;
  for (const json& r : baseline["results"]) old[key_of(r)] = &r;
  int regressions = 0, matched = 0;
  out << std::left << std::setw(44) << "case" << std::setw(14) << "implementation" << std::right
      << std::setw(11) << "time ×" << std::setw(11) << "memory ×"
      << "\n";
  for (const json& r : current["results"]) {
    const auto it = old.find(key_of(r));
    if (it == old.end()) continue;
    const json &a = it->second->at("metrics"), &b = r.at("metrics");
    if (!a.contains("median_s") || !b.contains("median_s")) continue;
    ++matched;
    const double time = b["median_s"].get<double>() / a["median_s"].get<double>();
    double memory = NAN;
    if (a.contains("memory_bytes") && b.contains("memory_bytes") &&
        a["memory_bytes"].get<double>() > 0)
      memory = b["memory_bytes"].get<double>() / a["memory_bytes"].get<double>();
    const bool slower = time > 1 + threshold, bigger = memory > 1 + threshold;
    regressions += slower || bigger;
    std::ostringstream name;
    name << r.value("suite", "") << "/" << r.value("case", "");
    out << std::left << std::setw(44) << name.str() << std::setw(14)
        << r.value("implementation", "") << std::right << std::fixed << std::setprecision(3)
        << std::setw(11) << time << std::setw(11);
    if (std::isnan(memory))
      out << "-";
    else
      out << memory;
    out << (slower || bigger ? "  REGRESSION" : "") << "\n";
    out.unsetf(std::ios::fixed);
  }
  out << matched << " cases compared, " << regressions << " beyond " << 100 * threshold
      << " % (ratios: current / baseline)\n";
  return regressions;
}

}  // namespace ivr::bench
