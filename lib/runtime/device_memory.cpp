// device_memory.cpp — the device-memory cap from $IVR_DEVICE_MEMORY_LIMIT, and byte counts as text.
#include "runtime/device_memory.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "ivr/error.hpp"

namespace ivr {

std::uint64_t device_memory_limit_from_env() {
  const char* env = std::getenv("IVR_DEVICE_MEMORY_LIMIT");
  if (!env || !*env) return 0;
  const std::string text = env;
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(env, &end);
  std::string suffix(end);
  while (!suffix.empty() && std::isspace(static_cast<unsigned char>(suffix.back()))) suffix.pop_back();
  double scale = 1;
  if (suffix == "K" || suffix == "KiB" || suffix == "k") scale = 1024.0;
  else if (suffix == "M" || suffix == "MiB") scale = 1024.0 * 1024;
  else if (suffix == "G" || suffix == "GiB") scale = 1024.0 * 1024 * 1024;
  else if (!suffix.empty()) scale = -1;
  if (end == env || errno || scale < 0 || !(value >= 1) || !std::isfinite(value * scale))
    throw Error(Status::invalid_argument,
                "IVR_DEVICE_MEMORY_LIMIT: '" + text +
                    "' is not a byte count (an integer ≥ 1, optionally with K, M or G)");
  return std::uint64_t(value * scale);
}

std::uint64_t device_memory_budget(const DeviceInfo& info) {
  const std::uint64_t limit = device_memory_limit_from_env();
  const std::uint64_t memory = info.global_memory ? info.global_memory : limit;
  return limit ? std::min(limit, memory ? memory : limit) : memory;
}

std::string memory_text(std::uint64_t bytes) {
  std::ostringstream s;
  s.precision(3);
  if (bytes >= (1ull << 30)) s << double(bytes) / double(1ull << 30) << " GiB";
  else if (bytes >= (1ull << 20)) s << double(bytes) / double(1ull << 20) << " MiB";
  else if (bytes >= 1024) s << double(bytes) / 1024.0 << " KiB";
  else s << bytes << " bytes";
  return s.str();
}

}  // namespace ivr
