// private_sums.cpp — the private-sums choice per operation and device, and its switch.
#include "adjoint/private_sums.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "ivr/error.hpp"

namespace ivr {

namespace {
// Values of the copies' sum worth one atomic add it saves (see private_sums_for). Measured on 2
// cores (PoCL 3.1, the density gradient, private sums against the atomics, same process): 128³ →
// 256² (ratio copies·voxels / pixels·edge 0.5) 140 against 194 ms, 256³ → 64² (32) 56 against
// 63 ms, 256³ → 16² (512) 18.4 against 19.9 ms, 512³ → 16² (2,048) 112 against 82 ms: the
// crossover near 1,000; a quarter of it, since more cores make the sum's memory traffic dearer.
constexpr double kCopyValuesPerAdd = 256;
}  // namespace

PrivateSums private_sums_for(const DeviceInfo& info, const PrivateSumsQuery& q) {
  const char* env = std::getenv("IVR_PRIVATE_SUMS");
  const std::string forced = env ? env : "";
  if (!forced.empty() && forced != "auto" && forced != "0" && forced != "1")
    throw Error(Status::invalid_argument,
                "IVR_PRIVATE_SUMS must be auto, 0 or 1, got '" + forced + "'");
  PrivateSums p;
  if (forced == "0") return p;
  if (!q.packet || !q.eligible) {
    if (forced == "1")
      throw Error(Status::invalid_argument,
                  "IVR_PRIVATE_SUMS=1: private sums serve the packet adjoint's float sums on CPU "
                  "devices, without the camera gradient, fixed point or the scatter cache");
    return p;
  }
  p.groups = std::max(info.compute_units, 1);
  p.copy_values = q.density ? private_copy_values(q.voxels) : 0;
  const std::uint64_t bytes = p.bytes(q.real_size);
  const bool fits = bytes <= info.global_memory / 4 && (bytes <= info.max_allocation || !bytes) &&
                    bytes <= q.room;
  if (forced == "1") {
    if (!fits)
      throw Error(Status::invalid_argument,
                  "IVR_PRIVATE_SUMS=1: " + std::to_string(p.groups) + " copies of the density "
                  "gradient (" + std::to_string(bytes) + " bytes) do not fit in " + info.name +
                  "'s memory (a quarter of it, one allocation)" +
                  (q.room == UINT64_MAX ? std::string()
                                        : " and the device-memory budget's " +
                                              std::to_string(q.room) + " bytes left"));
    p.on = true;
    return p;
  }
  const double adds = double(q.pixels) * double(std::max(q.longest_edge, 1));
  p.on = fits && double(p.groups) * double(p.copy_values) <= kCopyValuesPerAdd * adds;
  return p;
}

}  // namespace ivr
