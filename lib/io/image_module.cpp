// image_module.cpp — finds and loads libivr_image on the first PNG/EXR/TIFF write, so that a
// process that writes no image file never loads OpenImageIO (~260 shared libraries).
#include "io/image_module.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <vector>

#include "io/image_module_abi.h"
#include "ivr/error.hpp"

#ifndef IVR_IMAGE_MODULE_NAME
#define IVR_IMAGE_MODULE_NAME "libivr_image.so"
#endif

namespace ivr {
namespace {

struct Module {
  ivr_image_write_fn write = nullptr;
};

// Folder of the file this code was loaded from: libivr.so's, or a static program's own.
std::string own_folder() {
  Dl_info info{};
  if (!dladdr(reinterpret_cast<void*>(&own_folder), &info) || !info.dli_fname) return {};
  return std::filesystem::path(info.dli_fname).parent_path().string();
}

std::vector<std::string> candidates(bool& from_environment) {
  const char* env = std::getenv("IVR_IMAGE_MODULE");
  from_environment = env && *env;
  if (from_environment) return {env};
  std::vector<std::string> paths;
  const std::string own = own_folder();
  if (!own.empty()) paths.push_back(own + "/" IVR_IMAGE_MODULE_NAME);
#ifdef IVR_IMAGE_MODULE_INSTALL_DIR
  paths.push_back(IVR_IMAGE_MODULE_INSTALL_DIR "/" IVR_IMAGE_MODULE_NAME);
#endif
  return paths;
}

// Loads the module once per path (a handle is kept for the process's life; failures are not
// cached, so a module installed later, or another $IVR_IMAGE_MODULE, is found).
Module load(const std::string& what) {
  static std::mutex mutex;
  static std::map<std::string, Module> loaded;
  std::lock_guard<std::mutex> lock(mutex);
  bool from_environment = false;
  std::string tried;
  for (const std::string& path : candidates(from_environment)) {
    if (auto it = loaded.find(path); it != loaded.end()) return it->second;
    if (!from_environment && !std::filesystem::exists(path)) {
      tried += (tried.empty() ? "" : ", ") + path;
      continue;
    }
    // Lazy binding: OpenImageIO and its ~260 libraries resolve only the symbols a write uses.
    void* handle = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
    const char* reason = handle ? nullptr : dlerror();
    auto abi = handle ? reinterpret_cast<ivr_image_module_abi_fn>(dlsym(handle, "ivr_image_module_abi"))
                      : nullptr;
    auto write = handle ? reinterpret_cast<ivr_image_write_fn>(dlsym(handle, "ivr_image_write"))
                        : nullptr;
    if (handle && (!abi || !write || abi() != IVR_IMAGE_MODULE_ABI)) {
      dlclose(handle);
      throw Error(Status::unsupported,
                  "cannot write '" + what + "': '" + path +
                      "' is not an image module of this ivr (ABI " +
                      std::to_string(IVR_IMAGE_MODULE_ABI) + ")");
    }
    if (!handle)
      throw Error(Status::unsupported, "cannot write '" + what + "': cannot load the image module '" +
                                           path + "': " + (reason ? reason : "unknown reason"));
    return loaded[path] = Module{write};
  }
  throw Error(Status::unsupported,
              "cannot write '" + what +
                  "': PNG, EXR and TIFF need ivr's image module " IVR_IMAGE_MODULE_NAME
                  " (OpenImageIO), which is not installed (looked for " +
                  (tried.empty() ? std::string("it nowhere") : tried) +
                  "; set IVR_IMAGE_MODULE to its path, or write .npy)");
}

}  // namespace

void write_image_through_module(const std::string& path, const std::string& what, int width,
                                int height, int channels, bool uint8, const void* pixels) {
  const Module module = load(what);
  char reason[512] = {0};
  if (module.write(path.c_str(), width, height, channels, uint8 ? 1 : 0, pixels, reason,
                   sizeof reason) != 0)
    throw Error(Status::io, "cannot write '" + what + "': " + reason);
}

}  // namespace ivr
