// program_cache.hpp — compiled OpenCL programs, cached in process and as binaries on disk.
#pragma once
#include <CL/opencl.hpp>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

#include "ivr/device.hpp"

namespace ivr {

// 64-bit FNV-1a, for cache keys (not for security).
std::uint64_t fnv1a64(const std::string& text, std::uint64_t seed = 1469598103934665603ull);

// The on-disk cache folder: $IVR_CACHE_DIR, else $XDG_CACHE_HOME/ivr/kernels, else
// ~/.cache/ivr/kernels; "" when $IVR_KERNEL_CACHE is 0/off or no folder can be found.
std::string kernel_cache_dir();

class ProgramCache {
 public:
  // A built program for `source` + `options` on `device`. Looks in process, then on disk (keyed
  // by source, options, platform, device, driver and ivr version; not on PoCL, which caches its
  // builds itself: program_cache.cpp), then compiles; every disk cache failure falls back to
  // compiling. Throws ivr::Error(build) with the build log.
  // `label` names the program in errors; `*seconds` receives the time spent here.
  cl::Program get(const cl::Context& context, const cl::Device& device, const DeviceInfo& info,
                  const std::string& source, const std::string& options, const std::string& label,
                  double* seconds = nullptr);

  // Where the last get() found its program: "memory", "disk" or "compiled".
  const std::string& last_origin() const { return last_origin_; }

  // Programs by a caller's short key (lib/runtime/launch.cpp: file, preamble and options), so that a
  // program built once is found again without assembling and hashing its source. recall gives
  // an empty program for a key never remembered.
  cl::Program recall(const std::string& key);
  void remember(const std::string& key, const cl::Program& program);

 private:
  std::mutex mutex_;
  std::map<std::string, cl::Program> programs_;
  std::map<std::string, cl::Program> by_key_;
  std::string last_origin_;
};

}  // namespace ivr
