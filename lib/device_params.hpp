// device_params.hpp — per-device launch parameters from a small database (vendor → device →
// default fallback), overridable by $IVR_LOCAL_SIZE ("16x8") for tuning.
#pragma once
#include <string>

#include "ivr/device.hpp"

namespace ivr {

struct LaunchParams {
  int local_x = 0, local_y = 0;  // 0: let the driver choose the work-group size
  std::string source;            // which entry supplied them: "env", "vendor:device", "default"
};

LaunchParams launch_params(const DeviceInfo& device, const std::string& kernel);

}  // namespace ivr
