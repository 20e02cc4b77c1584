// image_module.hpp — the image module (libivr_image, OpenImageIO) found and loaded on first use.
#pragma once
#include <string>

namespace ivr {

// Writes width × height × channels interleaved pixels (unsigned char when `uint8`, else float)
// to `path` in the format of its extension, through the image module. The module is looked up
// as $IVR_IMAGE_MODULE when that is set, else as libivr_image.so next to libivr, else in the
// install's library folder; throws Error(unsupported) naming where it looked when it is missing,
// Error(io) when the write fails. `what` names the file in messages (the user's path, where
// `path` is a temporary one).
void write_image_through_module(const std::string& path, const std::string& what, int width,
                                int height, int channels, bool uint8, const void* pixels);

}  // namespace ivr
