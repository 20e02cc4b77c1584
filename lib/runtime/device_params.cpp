// device_params.cpp — the launch-parameter database (rows in lib/runtime/device_params_db.inc, written by
// `ivr tune --emit-entries`) and its lookup.
#include "runtime/device_params.hpp"

#include <cstdio>
#include <cstdlib>
#include <tuple>

#include "ivr/error.hpp"

namespace ivr {

namespace {

bool contains(const std::string& text, const char* part) {
  return text.find(part) != std::string::npos;
}

std::string field(const char* s) {
  return *s ? s : "*";
}

}  // namespace

const std::vector<DatabaseRow>& launch_database() {
  static const std::vector<DatabaseRow> rows = {
#include "runtime/device_params_db.inc"
  };
  return rows;
}

LaunchParams lookup_launch_params(const std::vector<DatabaseRow>& table, const DeviceInfo& device,
                                  const std::string& kernel) {
  // Specificity as a tuple compared lexicographically, so the order of the rows in the file does
  // not matter: a row appended by the tuner wins over the vendor or default rows above it.
  using Rank = std::tuple<bool, bool, bool, std::size_t, std::size_t>;
  const DatabaseRow* best = nullptr;
  Rank best_rank{};
  for (const DatabaseRow& row : table) {
    if ((*row.kernel && kernel != row.kernel) || !contains(device.vendor, row.vendor) ||
        !contains(device.name, row.device))
      continue;
    const Rank rank{*row.device != 0, *row.vendor != 0, *row.kernel != 0,
                    std::string(row.device).size(), std::string(row.vendor).size()};
    if (!best || rank > best_rank) {
      best = &row;
      best_rank = rank;
    }
  }
  LaunchParams p;
  if (!best) {
    p.source = "none";
    return p;
  }
  p.local_x = best->local_x;
  p.local_y = best->local_y;
  p.source = !*best->kernel && !*best->vendor && !*best->device
                 ? "default"
                 : field(best->kernel) + "/" + field(best->vendor) + "/" + field(best->device);
  return p;
}

LaunchParams launch_params(const DeviceInfo& device, const std::string& kernel) {
  LaunchParams p;
  if (const char* env = std::getenv("IVR_LOCAL_SIZE"); env && *env) {
    if (std::sscanf(env, "%dx%d", &p.local_x, &p.local_y) != 2 || p.local_x < 1 || p.local_y < 1 ||
        p.local_x * p.local_y > 4096)
      throw Error(
          Status::invalid_argument,
          std::string("IVR_LOCAL_SIZE must look like 16x8 (at most 4096 work-items), got '") + env +
              "'");
    p.source = "env";
    return p;
  }
  return lookup_launch_params(launch_database(), device, kernel);
}

}  // namespace ivr
