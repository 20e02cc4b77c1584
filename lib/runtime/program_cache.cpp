// program_cache.cpp — in-process and on-disk program caches with a fallback to compiling, and
// build errors that carry the build log.
#include "runtime/program_cache.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "io/files.hpp"
#include "ivr/error.hpp"
#include "ivr/version.h"
#include "runtime/runtime.hpp"

namespace fs = std::filesystem;

namespace ivr {

std::uint64_t fnv1a64(const std::string& text, std::uint64_t seed) {
  std::uint64_t h = seed;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::string kernel_cache_dir() {
  if (const char* off = std::getenv("IVR_KERNEL_CACHE")) {
    const std::string v = off;
    if (v == "0" || v == "off" || v == "OFF" || v == "false") return "";
  }
  if (const char* dir = std::getenv("IVR_CACHE_DIR"); dir && *dir) return dir;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
    return std::string(xdg) + "/ivr/kernels";
  if (const char* home = std::getenv("HOME"); home && *home)
    return std::string(home) + "/.cache/ivr/kernels";
  return "";
}

namespace {

std::string build_log(const cl::Program& program, const cl::Device& device) {
  try {
    std::string log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device);
    while (!log.empty() && (log.back() == '\n' || log.back() == '\0' || log.back() == ' '))
      log.pop_back();
    return log;
  } catch (const cl::Error&) {
    return "(no build log)";
  }
}

// Loads and builds a cached binary; any problem means "not cached" (empty program).
cl::Program load_binary(const cl::Context& context, const cl::Device& device,
                        const std::string& file, const std::string& options) {
  std::error_code ec;
  if (file.empty() || !fs::is_regular_file(file, ec)) return cl::Program();
  try {
    std::ifstream in(file, std::ios::binary);
    std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) return cl::Program();
    if (bytes.empty()) return cl::Program();
    cl::Program::Binaries binaries{bytes};
    std::vector<cl_int> status;
    cl::Program program(context, {device}, binaries, &status);
    program.build({device}, options.c_str());
    return program;
  } catch (const cl::Error&) {
    return cl::Program();
  }
}

void store_binary(const cl::Program& program, const std::string& file) {
  if (file.empty()) return;
  try {
    const auto binaries = program.getInfo<CL_PROGRAM_BINARIES>();
    if (binaries.empty() || binaries[0].empty()) return;
    std::error_code ec;
    fs::create_directories(fs::path(file).parent_path(), ec);
    write_atomically(file, [&](const std::string& tmp) {
      std::ofstream out(tmp, std::ios::binary);
      out.write(reinterpret_cast<const char*>(binaries[0].data()),
                std::streamsize(binaries[0].size()));
      if (!out) throw Error(Status::io, "cannot write kernel cache file");
    });
  } catch (...) {
    // The disk cache is an optimisation: failing to store is not an error.
  }
}

// PoCL keeps no binaries in ivr's disk cache, for two reasons.
// - PoCL caches every build itself ($POCL_CACHE_DIR, keyed by source, options and device, across
//   processes): a program built from source a second time costs no compile. Asking it for the
//   program's binary (CL_PROGRAM_BINARIES) makes it compile every kernel of the program once more
//   for any work-group size ("0-0-0"), beside the variant for the size each launch uses: a cold
//   first run took twice as long (16.1 s against 7.8 s for one adjoint test; 0.46 s against
//   0.65 s warm), and the cache held each kernel twice.
// - With POCL_KERNEL_CACHE=0 PoCL deletes a program's folder when the program is released, and
//   programs made from the same binary share that folder (named by the build hash the binary
//   carries), in one process or several: releasing one removed the files another's pending
//   kernel compile needed (tests/runtime/runtime_test.cpp, ProgramCache.NoBinariesForPocl).
bool is_pocl(const DeviceInfo& info) {
  return info.platform.find("Portable Computing Language") != std::string::npos;
}

}  // namespace

cl::Program ProgramCache::get(const cl::Context& context, const cl::Device& device,
                              const DeviceInfo& info, const std::string& source,
                              const std::string& options, const std::string& label,
                              double* seconds) {
  const auto start = std::chrono::steady_clock::now();
  std::uint64_t h = fnv1a64(source);
  for (const std::string& part : {options, info.platform, info.name, info.version, info.driver,
                                  std::string(IVR_VERSION_STRING)})
    h = fnv1a64(part, h ^ 0x9e3779b97f4a7c15ull);
  char key[17];
  std::snprintf(key, sizeof key, "%016llx", static_cast<unsigned long long>(h));

  std::lock_guard<std::mutex> lock(mutex_);
  auto done = [&](const cl::Program& p, const char* origin) {
    last_origin_ = origin;
    if (seconds)
      seconds[0] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return p;
  };
  if (auto it = programs_.find(key); it != programs_.end()) return done(it->second, "memory");

  const std::string dir = is_pocl(info) ? "" : kernel_cache_dir();
  const std::string file = dir.empty() ? "" : dir + "/" + key + ".bin";
  if (cl::Program cached = load_binary(context, device, file, options); cached()) {
    programs_[key] = cached;
    return done(cached, "disk");
  }

  cl::Program program =
      cl_call("creating program " + label, [&] { return cl::Program(context, source); });
  try {
    program.build({device}, options.c_str());
  } catch (const cl::Error& e) {
    if (e.err() != CL_BUILD_PROGRAM_FAILURE && e.err() != CL_INVALID_BUILD_OPTIONS)
      throw_cl(e, "building " + label);
    std::ostringstream msg;
    msg << "building kernel " << label << " failed on " << info.name << " with "
        << cl_error_name(e.err()) << "; build log:\n"
        << build_log(program, device);
    throw Error(Status::build, msg.str());
  }
  store_binary(program, file);
  programs_[key] = program;
  return done(program, "compiled");
}

cl::Program ProgramCache::recall(const std::string& key) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = by_key_.find(key);
  return it == by_key_.end() ? cl::Program() : it->second;
}

void ProgramCache::remember(const std::string& key, const cl::Program& program) {
  std::lock_guard<std::mutex> lock(mutex_);
  by_key_[key] = program;
}

}  // namespace ivr
