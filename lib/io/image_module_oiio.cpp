// image_module_oiio.cpp — libivr_image: the image module that writes PNG/EXR/TIFF through
// OpenImageIO, loaded by libivr on the first image-file write (lib/io/image_module.cpp).
#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <string>

#include "io/image_module_abi.h"

namespace {

int fail(char* error, std::size_t size, const std::string& reason) {
  if (error && size) std::snprintf(error, size, "%s", reason.c_str());
  return 1;
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int ivr_image_module_abi() {
  return IVR_IMAGE_MODULE_ABI;
}

extern "C" __attribute__((visibility("default"))) int ivr_image_write(
    const char* path, int width, int height, int channels, int uint8, const void* pixels,
    char* error, std::size_t error_size) {
  try {
    auto out = OIIO::ImageOutput::create(path);
    if (!out) return fail(error, error_size, OIIO::geterror());
    const OIIO::TypeDesc type = uint8 ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT;
    OIIO::ImageSpec spec(width, height, channels, type);
    if (!uint8 && channels == 4) spec.alpha_channel = 3;
    if (out->open(path, spec) && out->write_image(type, pixels) && out->close()) return 0;
    return fail(error, error_size, out->geterror());
  } catch (const std::exception& e) {  // nothing may cross the C boundary
    return fail(error, error_size, e.what());
  }
}
