// image_io.cpp — rendered images out: .npy of every view (float64 for a float64 render), or one
// view as EXR/PNG/TIFF through the image module, with PNG tone-mapped by the documented rule.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "io/files.hpp"
#include "io/image_module.hpp"
#include "ivr/error.hpp"
#include "ivr/render.hpp"
#include "ivr/volume_io.hpp"

namespace ivr {

unsigned char tone_map_8bit(double linear) {
  const double v = std::isnan(linear) ? 0.0 : std::clamp(linear, 0.0, 1.0);
  const double srgb = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
  return static_cast<unsigned char>(std::lround(255.0 * srgb));
}

void save_image_npy(const std::string& path, const Image& image) {
  const std::vector<std::size_t> shape{std::size_t(image.views), std::size_t(image.height),
                                       std::size_t(image.width), std::size_t(image.channels)};
  const std::size_t count = shape[0] * shape[1] * shape[2] * shape[3];
  const bool f64 = !image.pixels_f64.empty();
  if ((f64 ? image.pixels_f64.size() : image.pixels.size()) != count)
    throw Error(Status::invalid_argument,
                "cannot write '" + path + "': the image holds " +
                    std::to_string(f64 ? image.pixels_f64.size() : image.pixels.size()) +
                    " values, its shape needs " + std::to_string(count));
  if (f64)
    save_npy(path, shape, image.pixels_f64.data());
  else
    save_npy(path, shape, image.pixels.data());
}

void save_image_file(const std::string& path, const Image& image, int view) {
  if (view < 0 || view >= image.views)
    throw Error(Status::invalid_argument, "view " + std::to_string(view) +
                                              " does not exist (the image has " +
                                              std::to_string(image.views) + ")");
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  const bool png = ext == ".png";
  if (!png && ext != ".exr" && ext != ".tif" && ext != ".tiff")
    throw Error(Status::invalid_argument, "cannot write '" + path + "': unknown image format '" +
                                              ext + "' (use .npy, .png, .exr, .tif)");

  const std::size_t count = std::size_t(image.height) * image.width;
  const float* src = image.pixels.data() + std::size_t(view) * count * image.channels;
  // PNG: RGB of emission-absorption (composited over the background already), or grey I for
  // absorption; EXR/TIFF: every channel as float.
  const int channels = png ? (image.channels == 4 ? 3 : 1) : image.channels;
  std::vector<unsigned char> bytes;
  if (png) {
    bytes.resize(count * channels);
    for (std::size_t i = 0; i < count; ++i)
      for (int c = 0; c < channels; ++c)
        bytes[i * channels + c] = tone_map_8bit(src[i * image.channels + c]);
  }
  write_atomically(path, [&](const std::string& tmp) {
    write_image_through_module(tmp, path, image.width, image.height, channels, png,
                               png ? static_cast<const void*>(bytes.data()) : src);
  });
}

}  // namespace ivr
