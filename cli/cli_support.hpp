// cli_support.hpp — what several subcommands share: input errors, reading a loss target, and
// writing .npy outputs all or nothing.
#pragma once
#include <array>
#include <memory>
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::cli {

Error input_error(const std::string& what);

// "(2, 3, 4)", "(5,)".
std::string shape_text(const std::vector<std::size_t>& shape);
// The shape of the scene's images in .npy files: (views, H, W, C), a ray list's (rays, C).
std::vector<std::size_t> image_file_shape(const Scene& scene);
// The shapes an .npy of one value per ray may have: (views, H, W, 1) or (views, H, W), a ray
// list's (rays, 1) or (rays,); the first is what the commands write.
std::vector<std::vector<std::size_t>> ray_file_shapes(const Scene& scene);

// Reads TARGET.npy as an image of the scene's render shape (views, H, W, C); also accepts
// (H, W, C) for one view, and (views, H, W) / (H, W) for one channel. Values must be finite
// and fit float32; the first bad one is named by its index.
Image load_target(const std::string& path, const Scene& scene);

// "12.3 KiB", "4.5 MiB".
std::string bytes_text(std::uint64_t bytes);

// An array output: stored as float64 when `float64` (a --precision f64 result the library
// computed in float64), else as float32.
struct Output {
  std::string path;
  std::vector<std::size_t> shape;
  std::vector<double> data;
  bool float64 = false;
  Output(std::string path, std::vector<std::size_t> shape, const std::vector<float>& values)
      : path(std::move(path)), shape(std::move(shape)), data(values.begin(), values.end()) {}
  Output(std::string path, std::vector<std::size_t> shape, std::vector<double> values,
         bool float64)
      : path(std::move(path)), shape(std::move(shape)), data(std::move(values)), float64(float64) {}
};

// Writes every output under a hidden staging name first, then renames them all, so that a
// failure leaves none of them behind.
void write_outputs(const std::vector<Output>& outputs);

// The options of the marching commands (render, gradient, jacobian): --precision, --step, --scheme,
// --tolerance, --device.
struct MarchOptions {
  std::string precision = "f32", device, scheme;
  double step = 0, tolerance = 0;
  CLI::Option* step_option = nullptr;
  CLI::Option* tolerance_option = nullptr;
};
void add_march_options(CLI::App* cmd, MarchOptions& options);
// --split views|slabs: how the ranks of an mpirun share the work (docs/scaling.md).
void add_split_option(CLI::App* cmd, std::string& split);
// --shares W,W,...: several --device's weights, each device's share of the views in proportion
// (RenderOptions::shares and the others'); under mpirun one a rank (docs/scaling.md).
void add_shares_option(CLI::App* cmd, std::vector<double>& shares);
// Checks --shares before any work (under mpirun over slabs: weigh_rank_slabs') and returns what --json
// reports as "shares": each device's count of the `items` views (or rays) where several devices
// of one process share them; under mpirun over views each rank's count — a collective, every rank
// calling it: in proportion to --shares (one a rank) or else to each rank's devices' speed summed
// (its cost models'), every rank at least one view where there are as many (view_shares_each);
// else nothing.
std::vector<std::size_t> checked_shares(const std::vector<double>& shares,
                                        const std::vector<Device*>& devices, std::size_t items,
                                        const std::string& split);
// This rank's (first, count) of checked_shares' counts under mpirun; (0, items) in one process.
std::pair<std::size_t, std::size_t> rank_part(const std::vector<std::size_t>& counts,
                                              std::size_t items);
// Under mpirun over slabs (a collective, every rank calling it before it loads its slab): sizes
// the ranks' slabs by --shares (one a rank) or else by each rank's devices' speed summed, gathered
// (set_slab_shares). Nothing in one process or over views.
void weigh_rank_slabs(const std::vector<double>& shares, const std::vector<Device*>& devices,
                      const std::string& split);
// What --json reports as "slabs": each device's planes [first, last] where several devices of one
// process share a volume of nz planes over --split slabs|segments (by --shares, else their
// speeds: domain_slab), or under mpirun each rank's (weigh_rank_slabs); else nothing.
std::vector<std::array<int, 2>> device_slabs(const std::vector<Device*>& devices, int nz,
                                             const std::vector<double>& shares,
                                             const std::string& split);
// The options' `shares` for this process's devices: --shares in one process; under mpirun (where
// --shares weighs the ranks) none, a rank's devices taking their speeds.
std::vector<double> device_shares(const std::vector<double>& shares);
// The ranks' counts as workers' weights (GradientOptions::shares, ReconstructOptions::shares):
// view_shares splits the same n by them back into those counts exactly.
std::vector<double> worker_weights(const std::vector<std::size_t>& counts);
// The devices of a --device value: one, or several comma-separated (each a selector).
std::vector<std::unique_ptr<Device>> open_devices(const std::string& selectors);
std::vector<Device*> pointers(const std::vector<std::unique_ptr<Device>>& devices);
// Checks them before any work (one-line errors); returns the precision.
Precision checked_precision(const MarchOptions& options);
// The scene with --scheme and --tolerance applied (--step is passed to the operations).
Scene with_integrator(Scene scene, const MarchOptions& options);

// The folder of an output path or prefix must exist (checked before any work).
void check_output_folder(const std::string& path_or_prefix);

// A text file that appears whole or not at all: written under a hidden name in its folder, then
// renamed over `path`; throws ivr::Error(io) naming it.
void write_text_atomically(const std::string& path, const std::string& content);

// SIGINT / SIGTERM while a long command runs (tomo, reconstruct): the handler only records the
// signal and puts the default back (a second Ctrl-C ends the process at once); the command stops
// after its current iteration. Installed for the guard's scope, then what was there is restored;
// a signal the parent set to be ignored (a background job's SIGINT) stays ignored.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
  int signal() const;  // 0, SIGINT or SIGTERM

 private:
  void (*previous_[2])(int) = {nullptr, nullptr};
};

}  // namespace ivr::cli
