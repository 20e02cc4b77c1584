// device_params.cpp — the launch-parameter database. Add an entry only with a measurement behind
// it (build/bench/ivr-bench --device …), naming the device it was measured on.
#include "device_params.hpp"

#include <cstdio>
#include <cstdlib>

#include "ivr/error.hpp"

namespace ivr {

namespace {

struct Entry {
  const char* kernel;  // "" matches every kernel
  const char* vendor;  // substring of CL_DEVICE_VENDOR; "" matches every vendor
  const char* device;  // substring of CL_DEVICE_NAME; "" matches every device of the vendor
  int local_x, local_y;
};

// Most specific entries first. PoCL's CPU device: measured on a 2-core EPYC (skylake-avx512
// target), the driver's own work-group choice was as fast as any fixed 2-D size tried
// (1x1 … 64x1, 8x8, 16x16), so the default leaves the choice to the driver. Re-measured after the
// scalar render kernel (PoCL 3.1, 2 threads, 128³/256³ × 256²/512²): 8x8, 16x16, 32x4, 64x4, 64x1
// and 256x1 all within ~5% of the driver's choice (256x16 at 256²), the noise level there.
constexpr Entry kDatabase[] = {
    {"", "", "", 0, 0},  // default
};

bool contains(const std::string& text, const char* part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

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
  for (const Entry& e : kDatabase) {
    if ((*e.kernel && kernel != e.kernel) || !contains(device.vendor, e.vendor) ||
        !contains(device.name, e.device))
      continue;
    p.local_x = e.local_x;
    p.local_y = e.local_y;
    p.source = *e.vendor ? std::string(e.vendor) + ":" + e.device : "default";
    return p;
  }
  return p;
}

}  // namespace ivr
