// cli_support.hpp — what several subcommands share: input errors, reading a loss target, and
// writing .npy outputs all or nothing.
#pragma once
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::cli {

Error input_error(const std::string& what);

// "(2, 3, 4)", "(5,)".
std::string shape_text(const std::vector<std::size_t>& shape);

// Reads TARGET.npy as an image of the scene's render shape (views, H, W, C); also accepts
// (H, W, C) for one view, and (views, H, W) / (H, W) for one channel. Values must be finite
// and fit float32; the first bad one is named by its index.
Image load_target(const std::string& path, const Scene& scene);

// "12.3 KiB", "4.5 MiB".
std::string bytes_text(std::uint64_t bytes);

struct Output {
  std::string path;
  std::vector<std::size_t> shape;
  std::vector<float> data;
};

// Writes every output under a hidden staging name first, then renames them all, so that a
// failure leaves none of them behind.
void write_outputs(const std::vector<Output>& outputs);

// The options of the marching commands (render, grad, jacobian): --precision, --step, --scheme,
// --tolerance, --device.
struct MarchOptions {
  std::string precision = "f32", device, scheme;
  double step = 0, tolerance = 0;
  CLI::Option* step_option = nullptr;
  CLI::Option* tolerance_option = nullptr;
};
void add_march_options(CLI::App* cmd, MarchOptions& options);
// Checks them before any work (one-line errors); returns the precision.
Precision checked_precision(const MarchOptions& options);
// The scene with --scheme and --tolerance applied (--step is passed to the operations).
Scene with_integrator(Scene scene, const MarchOptions& options);

// The folder of an output path or prefix must exist (checked before any work).
void check_output_folder(const std::string& path_or_prefix);

}  // namespace ivr::cli
