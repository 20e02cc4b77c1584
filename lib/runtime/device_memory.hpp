// device_memory.hpp — internal: how much device memory operations may use ($IVR_DEVICE_MEMORY_LIMIT,
// the cap that Device::Impl::buffer() enforces and the out-of-core plans keep within).
#pragma once
#include <cstdint>
#include <string>

#include "ivr/device.hpp"

namespace ivr {

// The device memory an operation may use: $IVR_DEVICE_MEMORY_LIMIT (bytes; a plain integer, or
// with a K/M/G suffix of powers of 1024) where set, else the device's global memory, whichever is
// smaller. Throws Error(invalid_argument) naming the variable on a malformed value.
std::uint64_t device_memory_budget(const DeviceInfo& info);
// $IVR_DEVICE_MEMORY_LIMIT alone (0: not set).
std::uint64_t device_memory_limit_from_env();
// "1.5 GiB"-style text of a byte count.
std::string memory_text(std::uint64_t bytes);

}  // namespace ivr
