// scatter_cache.hpp — whether the scatter kernels sum a work-group's adds in local memory first.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

#include "runtime/launch.hpp"

namespace ivr {

// The table of kernels/scatter_cache.cl (IVR_SCATTER_SLOTS's default there): slots of an int key
// and a real value.
constexpr std::size_t kScatterSlots = 1024;
inline std::size_t scatter_cache_bytes(std::size_t real_size) {
  return kScatterSlots * (sizeof(std::int32_t) + real_size);
}

// Whether a scatter kernel (the adjoint's density gradient, the back-projector) sums its
// work-group's adds per voxel in a local table before the global atomic adds: by default on GPUs,
// whose global atomics on shared addresses contend where local ones do not, and off on CPU
// devices, where local memory is ordinary memory and a work-group's items run one after another
// in one thread, so the table only adds work (measured on PoCL: docs/devices.md).
// $IVR_SCATTER_CACHE=0|1 forces it (auto: the default). On, the table and the kernel's
// other local memory (`other_local` bytes) must fit in `local_memory` (CL_DEVICE_LOCAL_MEM_SIZE):
// the default is off where they do not, forcing it is then an error.
bool scatter_cache_for(const DeviceInfo& info, std::uint64_t local_memory, std::size_t real_size,
                       std::size_t other_local);
bool scatter_cache_for(Device::Impl& dev, std::size_t real_size, std::size_t other_local);

// The work-items of a group of the pixel kernel `tuning` as the launch database shapes it (8x8
// where it leaves the choice to the driver): for the local memory a kernel sizes per work-item.
std::size_t expected_group_items(const DeviceInfo& info, const std::string& tuning);

// The choice in a kernel configuration: IVR_SCATTER_CACHE 1 in its preamble and " scatter_cache"
// in its label where on; off leaves both as they were (the kernels' default is off).
KernelConfig& with_scatter_cache(KernelConfig& c, bool on);

}  // namespace ivr
