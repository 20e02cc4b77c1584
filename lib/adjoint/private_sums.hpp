// private_sums.hpp — whether the CPU packet adjoint sums into private copies without atomics.
#pragma once
#include <cstddef>
#include <cstdint>

#include "ivr_constants.h"
#include "runtime/runtime.hpp"

namespace ivr {

// What the adjoint launch needs of kernels/private_sums.cl: `groups` work-groups of one
// work-item (one a compute unit), each with its own copy of the density gradient where there
// is one (`copy_values` values a copy, padded to IVR_PRIVATE_ALIGN; 0 without a density gradient).
struct PrivateSums {
  bool on = false;
  int groups = 0;
  std::size_t copy_values = 0;
  std::size_t bytes(std::size_t real_size) const {
    return std::size_t(groups) * copy_values * real_size;
  }
};

// The values one padded copy of `voxels` holds (kernels/private_sums.cl, private_copy_offset).
inline std::size_t private_copy_values(std::size_t voxels) {
  return (voxels + IVR_PRIVATE_ALIGN - 1) / IVR_PRIVATE_ALIGN * IVR_PRIVATE_ALIGN;
}

// What the choice depends on: the operation and the device.
struct PrivateSumsQuery {
  bool packet = false;        // the adjoint marches packets (CPU devices)
  bool density = false;       // a density gradient is asked for
  bool eligible = false;      // float sums: no camera gradient, no fixed point, no scatter cache
  std::size_t voxels = 0;     // the volume's
  std::size_t real_size = 4;  // bytes of a real
  std::uint64_t pixels = 0;   // rays of the operation
  int longest_edge = 0;       // the volume's longest edge in voxels
  // Device memory the copies may take beside what the operation has planned (out of core: what
  // the plan's budget leaves); the device's own limits apply either way.
  std::uint64_t room = UINT64_MAX;
};

// On for the packet adjoint's float sums on CPU devices, one group a compute unit, where the
// copies fit (a quarter of the device's global memory, one allocation, `room`) and cost less than the
// atomics they replace: the copies' sum touches groups × voxels values, the atomics are about one
// per cell a ray crosses (pixels × longest edge), and a streamed value costs a small fraction of
// a compare-and-swap (kCopyValuesPerAdd in private_sums.cpp, with its measurements).
// $IVR_PRIVATE_SUMS=0|1|auto: 0 off, 1 on wherever eligible (an error where not, or where the
// copies do not fit), auto (or unset) the default.
PrivateSums private_sums_for(const DeviceInfo& info, const PrivateSumsQuery& q);

}  // namespace ivr
