// scatter_cache.cpp — the scatter cache's default per device, its switch and its fit check.
#include "adjoint/scatter_cache.hpp"

#include <cstdlib>

#include "runtime/device_params.hpp"
#include "ivr/error.hpp"

namespace ivr {

bool scatter_cache_for(const DeviceInfo& info, std::uint64_t local_memory, std::size_t real_size,
                       std::size_t other_local) {
  const char* env = std::getenv("IVR_SCATTER_CACHE");
  const std::string forced = env ? env : "";
  if (!forced.empty() && forced != "auto" && forced != "0" && forced != "1")
    throw Error(Status::invalid_argument,
                "IVR_SCATTER_CACHE must be auto, 0 or 1, got '" + forced + "'");
  if (forced == "0") return false;
  const std::size_t needed = scatter_cache_bytes(real_size) + other_local;
  const bool fits = needed <= local_memory;
  if (forced == "1") {
    if (!fits)
      throw Error(Status::invalid_argument,
                  "IVR_SCATTER_CACHE=1: the scatter cache and the kernel's other local memory (" +
                      std::to_string(needed) + " bytes) do not fit in " + info.name + "'s " +
                      std::to_string(local_memory) + " bytes of local memory");
    return true;
  }
  // Off by default everywhere until a GPU measures it: on PoCL it costs 15–51 % (docs/devices.md),
  // and on a GPU, where it is meant to pay (an 8×8 tile makes ~7 global adds per voxel it
  // touches; the evicting table ~1.5 in a model), neither its speed nor its build has been seen
  // yet.
  (void)info;
  return false;
}

bool scatter_cache_for(Device::Impl& dev, std::size_t real_size, std::size_t other_local) {
  const std::uint64_t local = cl_call("querying " + dev.info.name + "'s local memory", [&] {
    return std::uint64_t(dev.device.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>());
  });
  return scatter_cache_for(dev.info, local, real_size, other_local);
}

std::size_t expected_group_items(const DeviceInfo& info, const std::string& tuning) {
  const LaunchParams p = launch_params(info, tuning);
  return p.local_x > 0 && p.local_y > 0 ? std::size_t(p.local_x) * std::size_t(p.local_y) : 64;
}

KernelConfig& with_scatter_cache(KernelConfig& c, bool on) {
  return c.set(Switch::scatter_cache, on);
}

}  // namespace ivr
