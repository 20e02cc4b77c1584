// device_params.hpp — per-device launch parameters from a small database (lib/runtime/device_params_db.inc:
// the most specific of device → vendor → default rows), overridable by $IVR_LOCAL_SIZE ("16x8").
#pragma once
#include <string>
#include <vector>

#include "ivr/device.hpp"

namespace ivr {

struct LaunchParams {
  int local_x = 0, local_y = 0;  // 0: let the driver choose the work-group size
  // Which entry supplied them: "env", "default" (the every-kernel, every-device row), the row as
  // "kernel/vendor/device" with "*" for an empty field (e.g. "adjoint/NVIDIA/*"), or "none".
  std::string source;
};

// One row of the database (see lib/runtime/device_params_db.inc for the fields).
struct DatabaseRow {
  const char* kernel;
  const char* vendor;
  const char* device;
  int local_x, local_y;
};

// $IVR_LOCAL_SIZE, else the compiled database's row for this device and tuning name.
LaunchParams launch_params(const DeviceInfo& device, const std::string& kernel);

// The lookup alone over any table (the compiled one, or a test's): the most specific matching row
// — device before vendor before neither, then a kernel's own row before an every-kernel row, then
// the longer device and vendor substrings; the first of equals.
LaunchParams lookup_launch_params(const std::vector<DatabaseRow>& table, const DeviceInfo& device,
                                  const std::string& kernel);

// The compiled database (lib/runtime/device_params_db.inc), in file order.
const std::vector<DatabaseRow>& launch_database();

}  // namespace ivr
