// ivr/render.hpp — the forward renderer: every view of a scene in one kernel launch.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/scene.hpp"

namespace ivr {

enum class Precision { f32, f64 };

// Empty-space skipping: rays jump over bricks of cells where σ is 0 everywhere (same image up
// to rounding, fewer samples). automatic: on when the TF is 0 on some density range and at
// least `min_empty_fraction` of the bricks are empty.
enum class EmptySpace { automatic, on, off };

struct RenderOptions {
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step and tolerance (voxel units)
  EmptySpace empty_space = EmptySpace::automatic;
  double min_empty_fraction = 0.05;
  int brick_size = 0;  // cells per brick edge; 0: 4 for volumes up to 128 voxels across, else 8
  // Out-of-core (docs/scaling.md): cells per edge of the bricks the volume is streamed through the
  // device in; 0: in core where the volume and the render's buffers fit the device memory (or
  // $IVR_DEVICE_MEMORY_LIMIT), else bricks chosen to fit. $IVR_VOLUME_BRICK forces one as well.
  int volume_brick = 0;
  // Several devices (render, gradient, tomo over a vector of devices; docs/scaling.md): each
  // device's weight, its share of the views in proportion (view_shares) — or over slabs
  // (render_domain, tomo_domain over devices) of the volume's planes (domain_slab); one a device,
  // each > 0 and finite. Empty: each device's samples_per_second() (its calibration, else an
  // estimate from its size), so a GPU beside the CPU takes most views, or the longest slab.
  std::vector<double> shares{};
};

// Images of shape (views, height, width, channels), float32, row 0 at the top.
// channels: 1 (absorption: I) or 4 (emission-absorption: premultiplied RGB over the background, A).
// A float64 render also keeps its pixels unrounded in pixels_f64 (empty otherwise; inputs such as
// targets are read from `pixels` alone).
struct Image {
  int views = 0, height = 0, width = 0, channels = 0;
  std::vector<float> pixels;
  std::vector<double> pixels_f64;
  Image() = default;
  Image(int views, int height, int width, int channels, std::vector<float> pixels = {},
        std::vector<double> pixels_f64 = {})
      : views(views), height(height), width(width), channels(channels), pixels(std::move(pixels)),
        pixels_f64(std::move(pixels_f64)) {}
  float at(int view, int y, int x, int c) const {
    return pixels[((std::size_t(view) * height + y) * width + x) * channels + c];
  }
};

struct RenderStats {
  double kernel_seconds = 0;       // device time of the render kernel (profiling events)
  double build_seconds = 0;        // program lookup/compile time (0 when cached in-process)
  std::uint64_t samples = 0;       // density samples taken over all rays
  std::string variant;             // the compiled feature set, e.g. "model=ea tf=gaussian f32"
  bool skipped_empty = false;      // empty-space skipping ran
  double empty_fraction = 0;       // of the bricks, when the grid was built
  double grid_seconds = 0;         // host time to build the occupancy grid
  std::string scheme;              // the integrator
  double step = 0;                 // the step used (voxel units; `exact` has none to use)
  double estimated_error = 0;      // integrator.tolerance: the chosen step's estimated error
  double step_seconds = 0;         // integrator.tolerance: host time choosing the step
  std::uint64_t device_bytes = 0;  // device memory of the render's buffers (scene, image, counts)
  int bricks = 1;                  // bricks the volume was split into (1: in core)
  int brick_edge = 0;              // their edge in cells (0: in core)
  int sweeps = 0;                  // passes over the bricks (1 when every ray met them in order)
  std::uint64_t uploaded_bytes = 0;  // bricks uploaded (each brick once where all fit at once)
  std::uint64_t brick_uploads = 0;
  int devices = 1;                   // the devices the views were spread over
};

// Validates the scene and renders it; throws ivr::Error.
IVR_API Image render(Device& device, const Scene& scene, const RenderOptions& options = {},
                     RenderStats* stats = nullptr);

// The same on several devices (docs/scaling.md): the views (a ray list's rays) split into
// contiguous shares, one per device in proportion to share_weights(devices, options.shares) (a
// device whose share is empty does not run), rendered at once on threads of their own and joined
// in view order — each view's pixels are the one-device render's. Stats: samples summed, the
// slowest device's kernel time, the largest device's memory, `devices` those that ran.
IVR_API Image render(const std::vector<Device*>& devices, const Scene& scene,
                     const RenderOptions& options = {}, RenderStats* stats = nullptr);

// The weights several devices' shares of the views take (the options' `shares`): `given` where
// not empty, one a device, each > 0 and finite; else each device's samples_per_second(). Throws
// Error(invalid_argument) naming a missing or bad weight.
IVR_API std::vector<double> share_weights(const std::vector<Device*>& devices,
                                          const std::vector<double>& given = {});

// Writes the images as .npy (views, H, W, C): float64 when the image has pixels_f64, else float32.
IVR_API void save_image_npy(const std::string& path, const Image& image);

// Writes one view as EXR/PNG/TIFF by the file extension through OpenImageIO. EXR and TIFF keep
// the float values and every channel; PNG is 8-bit, tone-mapped by tone_map_8bit().
IVR_API void save_image_file(const std::string& path, const Image& image, int view = 0);

// The documented PNG rule: clamp to [0, 1], then the sRGB transfer curve, then round to 8 bits.
// Emission-absorption writes RGB (already composited over the background) and drops alpha;
// absorption writes one grey channel, I itself (I_in = background, 1 by default).
IVR_API unsigned char tone_map_8bit(double linear);

}  // namespace ivr
