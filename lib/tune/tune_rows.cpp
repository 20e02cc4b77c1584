// tune_rows.cpp — the tuner's winners as rows of the launch database (lib/runtime/device_params_db.inc),
// with the measurements behind them in comments.
#include <cstdio>
#include <sstream>

#include "ivr/tune.hpp"

namespace ivr {

namespace {

// A C string literal of `text`.
std::string quoted(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    if (ch == '"' || ch == '\\') out += '\\';
    out += ch;
  }
  return out + '"';
}

std::string milliseconds(double seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4g", seconds * 1e3);
  return text;
}

// A comment is one line: nothing in it may end it early.
std::string one_line(std::string text) {
  for (char& ch : text)
    if (ch == '\n' || ch == '\r') ch = ' ';
  return text;
}

}  // namespace

std::string tune_database_rows(const TuneResult& result, const std::string& command) {
  const DeviceInfo& d = result.device;
  std::ostringstream out;
  out << "// " << one_line(d.name) << " (" << one_line(d.vendor) << "), " << one_line(d.platform)
      << ", driver " << one_line(d.driver) << ", " << result.date << ": " << one_line(command)
      << " (" << (result.options.statistic == TuneStatistic::minimum ? "minima" : "medians")
      << " of " << result.options.repeats << " runs, ms)\n";
  for (const KernelTuning& k : result.kernels) {
    if (k.winner < 0) {
      out << "// " << k.kernel << ": " << one_line(k.skipped) << "\n";
      continue;
    }
    const TuneCandidate& w = k.candidates[std::size_t(k.winner)];
    out << "{" << quoted(k.kernel) << ", " << quoted(d.vendor) << ", " << quoted(d.name) << ", "
        << w.local_x << ", " << w.local_y << "},  // ms:";
    const char* separator = " ";
    for (const TuneCandidate& c : k.candidates)
      if (c.skipped.empty()) {
        out << separator << c.local_x << "x" << c.local_y << " " << milliseconds(c.score_seconds);
        separator = ", ";
      }
    if (k.winner != k.fastest) {
      const TuneCandidate& f = k.candidates[std::size_t(k.fastest)];
      out << "; kept " << w.local_x << "x" << w.local_y << " (in use, from " << k.current_source
          << "): the fastest, " << f.local_x << "x" << f.local_y << ", is within "
          << result.options.tie * 100 << "%";
    }
    out << "\n";
  }
  return out.str();
}

}  // namespace ivr
