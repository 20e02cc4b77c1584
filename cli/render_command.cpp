// render_command.cpp — `ivr render SCENE.json -o OUT`: renders every view to .npy or images.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "commands.hpp"
#include "mpi_world.hpp"
#include "ivr/core.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

namespace {

struct RenderArgs {
  std::string scene, output;
  MarchOptions march;
  bool json = false;
  std::string empty_space = "auto";
  int volume_brick = 0;
  std::string split = "views";
  std::vector<double> shares;
};

std::string lower_ext(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext;
}

// Output files for the image: OUT itself for .npy or a single view, else OUT_<view>.ext.
std::vector<std::string> output_paths(const std::string& out, int views) {
  if (lower_ext(out) == ".npy" || views == 1) return {out};
  const fs::path p(out);
  std::vector<std::string> paths;
  for (int v = 0; v < views; ++v)
    paths.push_back(
        (p.parent_path() / (p.stem().string() + "_" + std::to_string(v) + p.extension().string()))
            .string());
  return paths;
}

// Under mpirun, each rank renders its share of the views (a ray list: rays; `rank_counts`, from
// checked_shares) and rank 0 gathers
// the images in view order (the other ranks get an empty image); with --split slabs each rank its
// slab, every rank getting the image (one process with several devices: each device a slab);
// else the render itself.
Image render_ranks(const std::vector<Device*>& devices, const Scene& scene,
                   const RenderOptions& options, RenderStats* stats, const std::string& split,
                   DomainStats* domain, const std::vector<std::size_t>& rank_counts) {
  const World& w = world();
  if (split != "views") {
    if (w.size == 1 && devices.size() > 1)  // one process: its devices share the slabs
      return render_domain(devices, scene, domain_part(split).march, options, stats, domain);
    return render_domain(one_device_per_rank(devices), scene,  // (its slab: load_scene_for)
                         domain_part(split), options, stats, domain);
  }
  if (w.size == 1) return render(devices, scene, options, stats);
  const auto [first, count] = rank_part(rank_counts, share_items(scene));
  Image mine;  // (rank 0 always has a view: view_shares_each)
  if (count) mine = render(devices, scene_share(scene, first, count), options, stats);
  const bool f64 = options.precision == Precision::f64;
  const std::vector<double> values =
      f64 ? mine.pixels_f64 : std::vector<double>(mine.pixels.begin(), mine.pixels.end());
  std::vector<double> samples{double(stats->samples)};
  sum_all(samples);
  stats->samples = std::uint64_t(samples[0]);
  const std::vector<double> all = gather(values);
  if (w.rank != 0) return {};
  Image out = mine;
  if (scene.has_ray_list())
    out.width = int(scene.rays.count());
  else
    out.views = int(scene.cameras.size());
  out.pixels.assign(all.begin(), all.end());
  if (f64) out.pixels_f64 = all;
  return out;
}

}  // namespace

Runner add_render_command(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "Render every view of a scene");
  cmd->add_option("scene", args->scene, "Scene JSON file (see docs/design.md)")->required();
  cmd->add_option("-o,--output", args->output,
                  "Output: .npy (views, H, W, C) float32 (float64 with --precision f64), or .png/.exr/.tif (one file per view: "
                  "OUT_<v>.ext); a scene of rays: .npy (rays, C)")
      ->required();
  add_march_options(cmd, args->march);
  cmd->add_option("--empty-space", args->empty_space,
                  "Empty-space skipping: auto (when the TF is 0 somewhere and >= 5% of the bricks "
                  "are empty), on or off; the image is the same up to rounding")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  cmd->add_option("--volume-brick", args->volume_brick,
                  "Out-of-core: stream the volume through the device in bricks of N cells per edge "
                  "(docs/scaling.md); by default only where it does not fit the device memory or "
                  "$IVR_DEVICE_MEMORY_LIMIT")
      ->check(CLI::PositiveNumber);
  add_split_option(cmd, args->split);
  add_shares_option(cmd, args->shares);
  cmd->add_flag("--json", args->json,
                "Print one JSON object with device, timings and sample counts");
  return [args] {
    // Check the output name before any work, so that a bad name wastes nothing and writes nothing.
    const std::string ext = lower_ext(args->output);
    if (ext != ".npy" && ext != ".png" && ext != ".exr" && ext != ".tif" && ext != ".tiff")
      throw Error(
          Status::invalid_argument,
          "output '" + args->output + "' needs the extension .npy, .png, .exr, .tif or .tiff");
    const fs::path folder =
        fs::path(args->output).has_parent_path() ? fs::path(args->output).parent_path() : ".";
    if (!fs::is_directory(folder))
      throw Error(Status::io, "output folder '" + folder.string() + "' does not exist");
    const Precision precision = checked_precision(args->march);

    // (the devices first: under mpirun over slabs their speeds size the ranks' slabs, read next)
    const std::vector<std::unique_ptr<Device>> devices = open_devices(args->march.device);
    Device& device = *devices[0];
    weigh_rank_slabs(args->shares, pointers(devices), args->split);
    const Scene scene = with_integrator(load_scene_for(args->scene, args->split), args->march);
    RenderOptions options;
    options.precision = precision;
    options.step = args->march.step;
    options.empty_space = args->empty_space == "on"    ? EmptySpace::on
                          : args->empty_space == "off" ? EmptySpace::off
                                                       : EmptySpace::automatic;
    if (scene.has_ray_list() && ext != ".npy")
      throw Error(Status::invalid_argument,
                  "output '" + args->output +
                      "': a scene of rays renders one value per ray: write .npy (rays, C)");
    options.volume_brick = args->volume_brick;
    const std::vector<std::size_t> shares =
        checked_shares(args->shares, pointers(devices), share_items(scene), args->split);
    options.shares = device_shares(args->shares);
    RenderStats stats;
    DomainStats domain;
    const Image image =
        render_ranks(pointers(devices), scene, options, &stats, args->split, &domain, shares);
    if (world().rank != 0) return 0;  // rank 0 writes (mpirun: docs/scaling.md)

    const std::vector<std::string> paths = output_paths(args->output, image.views);
    if (scene.has_ray_list()) {  // (rays, C), in the precision it was computed in
      if (image.pixels_f64.empty())
        save_npy(paths[0], image_file_shape(scene), image.pixels.data());
      else
        save_npy(paths[0], image_file_shape(scene), image.pixels_f64.data());
    } else if (ext == ".npy")
      save_image_npy(paths[0], image);
    else
      for (int v = 0; v < int(paths.size()); ++v) save_image_file(paths[v], image, v);

    const double rate =
        stats.kernel_seconds > 0 ? double(stats.samples) / stats.kernel_seconds : 0.0;
    if (args->json) {
      const DeviceInfo& d = device.info();
      nlohmann::json out = {{"device", d.name},
                            {"platform", d.platform},
                            {"device_type", d.type},
                            {"precision", args->march.precision},
                            {"variant", stats.variant},
                            {"views", image.views},
                            {"rays", scene.rays.count()},
                            {"width", image.width},
                            {"height", image.height},
                            {"channels", image.channels},
                            {"scheme", stats.scheme},
                            {"step", stats.step},
                            {"kernel_seconds", stats.kernel_seconds},
                            {"build_seconds", stats.build_seconds},
                            {"samples", stats.samples},
                            {"samples_per_second", rate},
                            {"empty_space",
                             {{"skipped", stats.skipped_empty},
                              {"empty_fraction", stats.empty_fraction},
                              {"grid_seconds", stats.grid_seconds}}},
                            {"bricks", stats.bricks},
                            {"devices", stats.devices},
                            {"shares", shares},
                            {"slabs", device_slabs(pointers(devices), scene.volume.nz,
                                                   args->shares, args->split)},
                            {"ranks", world().size},
                            {"split", args->split},
                            {"exchanges", domain.exchanges},
                            {"exchanged_bytes", domain.sent_bytes},
                            {"brick_edge", stats.brick_edge},
                            {"sweeps", stats.sweeps},
                            {"device_bytes", stats.device_bytes},
                            {"uploaded_bytes", stats.uploaded_bytes},
                            {"outputs", paths}};
      if (scene.integrator.tolerance > 0 && options.step == 0)
        out["tolerance"] = {{"requested", scene.integrator.tolerance},
                            {"estimated_error", stats.estimated_error},
                            {"seconds", stats.step_seconds}};
      std::cout << out.dump() << "\n";
    } else {
      std::cout << "rendered " << image.views << " view(s) of " << image.width << "x"
                << image.height << " on " << device.info().name << ": "
                << stats.kernel_seconds * 1e3 << " ms, " << stats.samples << " samples ("
                << rate / 1e6 << " M/s) -> " << paths[0] << (paths.size() > 1 ? " ..." : "")
                << "\n";
    }
    return 0;
  };
}

}  // namespace ivr::cli
