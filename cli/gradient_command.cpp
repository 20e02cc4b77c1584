// gradient_command.cpp — `ivr gradient SCENE.json --target T.npy --wrt GROUPS -o PREFIX`: loss gradients.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "commands.hpp"
#include "mpi_world.hpp"
#include "ivr/core.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

namespace {

struct GradientArgs {
  std::string scene, target, wrt, mode = "auto", loss = "mse", prefix, split = "views";
  MarchOptions march;
  bool json = false;
};

}  // namespace

// Under mpirun, each rank differentiates the loss of its share of the views (a ray list: rays);
// the loss and the gradients are the shares' weighted by their sizes (dot: summed) and summed
// over the ranks (MPI_Allreduce); per-view groups (camera, rays) are gathered in order. Rank 0
// gets the result; else the gradient itself.
// With --split slabs each rank differentiates over its slab: rank 0 joins the density's slabs, the
// TF gradient's parts are summed over the ranks; the background's and the forward lanes' (camera,
// …) are whole on every rank.
Gradient gradient_slabs(const std::vector<Device*>& devices, const Scene& scene,
                        const Image& target, const std::vector<std::string>& groups,
                        const GradientOptions& options) {
  const World& w = world();
  Gradient mine = gradient_domain(one_device_per_rank(devices), domain_share(scene, w.rank, w.size),
                                  target, domain_part(), options, nullptr, groups);
  for (GroupGradient& g : mine.groups) {  // every rank takes part in each collective
    if (g.name == "tf") {  // each rank's part: its slab's samples
      sum_all(g.values);
      continue;
    }
    if (g.name != "density") continue;  // whole on every rank (background, forward lanes)
    const std::vector<std::vector<double>> slabs = gather_parts(g.values);
    if (w.rank != 0) continue;
    g.values = domain_join(scene.volume.nx, scene.volume.ny, scene.volume.nz, slabs);
    g.shape[0] = std::size_t(scene.volume.nz);
  }
  if (w.rank != 0) return {};
  mine.parameters = 0;
  for (const GroupGradient& g : mine.groups) mine.parameters += g.values.size();
  return mine;
}

Gradient gradient_ranks(const std::vector<Device*>& devices, const Scene& scene, const Image& target,
                        const std::vector<std::string>& groups, const GradientOptions& options,
                        const std::string& split) {
  if (split == "slabs") return gradient_slabs(devices, scene, target, groups, options);
  const World& w = world();
  if (w.size == 1) return gradient(devices, scene, target, groups, options);
  const std::size_t n = share_items(scene);
  const auto parts = view_shares(n, std::size_t(w.size));
  const bool active = std::size_t(w.rank) < parts.size();
  // Every rank needs the groups' shapes: rank 0's share always exists; the others' zeros.
  Gradient mine;
  if (active) {
    const auto [first, count] = parts[w.rank];
    mine = gradient(devices, scene_share(scene, first, count),
                    target_share(scene, target, first, count), groups, options);
  } else {
    mine = gradient(devices, scene_share(scene, 0, 1), target_share(scene, target, 0, 1), groups,
                    options);
  }
  const double weight = !active ? 0.0
                        : options.loss == Loss::dot ? 1.0
                                                    : double(parts[w.rank].second) / double(n);
  std::vector<double> sums{weight * mine.loss};
  for (const GroupGradient& g : mine.groups)
    if (!per_view_group(g.name))
      for (double v : g.values) sums.push_back(weight * v);
  sum_all(sums);
  Gradient out = mine;
  out.loss = sums[0];
  std::size_t at = 1;
  for (GroupGradient& g : out.groups) {
    if (per_view_group(g.name)) {
      std::vector<double> rows;
      if (active)
        for (double v : g.values) rows.push_back(weight * v);
      g.values = gather(rows);
      g.shape[0] = n;
    } else {
      for (double& v : g.values) v = sums[at++];
    }
  }
  return out;
}

Runner add_gradient_command(CLI::App& app) {
  auto args = std::make_shared<GradientArgs>();
  CLI::App* cmd = app.add_subcommand(
      "gradient", "Gradient of an image loss with respect to groups of scene parameters");
  cmd->add_option("scene", args->scene, "Scene JSON file (see docs/design.md)")->required();
  cmd->add_option("--target", args->target,
                  "Target images, .npy of the render's shape (views, H, W, C); (H, W, C) for one "
                  "view, (views, H, W) or (H, W) for one channel")
      ->required();
  cmd->add_option("--wrt", args->wrt,
                  "Comma-separated parameter groups: density, tf, tf_points, scales, background, "
                  "camera, step, voxels:LIST (indices and ranges a-b), rays (a ray list's (R, 8))")
      ->required();
  cmd->add_option("--mode", args->mode, "auto (default: the planner's choice), forward or adjoint");
  cmd->add_option("--loss", args->loss, "Image loss: mse (default), l1, or dot (the sum of target * image: the "
                  "gradient is the vector-Jacobian product with the target as dL/dimage)");
  add_march_options(cmd, args->march);
  add_split_option(cmd, args->split);
  cmd->add_option("-o,--output", args->prefix,
                  "Output prefix: writes PREFIX_<group>.npy for every group asked for (float32; "
                  "float64 with --precision f64)")
      ->required();
  cmd->add_flag("--json", args->json,
                "Print one JSON object with the loss, mode, plan, timings and outputs");
  return [args] {
    // Every option and the output folder are checked before any work, so that a bad call wastes
    // nothing and writes nothing.
    if (args->prefix.empty()) throw input_error("-o: the output prefix is empty");
    const fs::path folder =
        fs::path(args->prefix).has_parent_path() ? fs::path(args->prefix).parent_path() : ".";
    if (!fs::is_directory(folder))
      throw Error(Status::io, "output folder '" + folder.string() + "' does not exist");
    const std::vector<std::string> groups = parse_groups(args->wrt);
    GradientOptions options;
    if (args->mode == "auto")
      options.mode = Mode::automatic;
    else if (args->mode == "forward")
      options.mode = Mode::forward;
    else if (args->mode == "adjoint")
      options.mode = Mode::adjoint;
    else
      throw input_error("--mode: unknown mode '" + args->mode +
                        "' (known: auto, forward, adjoint)");
    if (args->loss != "mse" && args->loss != "l1" && args->loss != "dot")
      throw input_error("--loss: unknown loss '" + args->loss + "' (known: mse, l1, dot)");
    const Precision precision = checked_precision(args->march);
    const Scene scene = with_integrator(load_scene(args->scene), args->march);
    const Image target = load_target(args->target, scene);
    const std::vector<std::unique_ptr<Device>> devices = open_devices(args->march.device);
    Device& device = *devices[0];
    options.precision = precision;
    options.step = args->march.step;
    options.loss = args->loss == "l1" ? Loss::l1 : args->loss == "dot" ? Loss::dot : Loss::mse;
    const Gradient d =
        gradient_ranks(pointers(devices), scene, target, groups, options, args->split);
    if (world().rank != 0) return 0;  // rank 0 writes (mpirun: docs/scaling.md)

    std::vector<Output> outputs;
    std::vector<std::string> paths, names;
    for (const GroupGradient& g : d.groups) {
      outputs.emplace_back(args->prefix + "_" + g.name + ".npy", g.shape, g.values,
                           precision == Precision::f64);
      paths.push_back(outputs.back().path);
      names.push_back(g.name);
    }
    write_outputs(outputs);

    const char* mode = mode_name(d.plan.mode);
    if (args->json) {
      const auto seconds = [](double s) {
        return std::isfinite(s) ? nlohmann::json(s) : nlohmann::json(nullptr);
      };
      nlohmann::json out = {{"loss", d.loss},
                            {"loss_function", args->loss},
                            {"mode", mode},
                            {"requested_mode", args->mode},
                            {"wrt", names},
                            {"parameters", d.parameters},
                            {"seconds", d.kernel_seconds},
                            {"device_bytes", d.device_bytes},
                            {"device", device.info().name}, {"bricks", d.bricks}, {"devices", d.devices}, {"ranks", world().size}, {"split", args->split},
                            {"precision", args->march.precision},
                            {"scheme", scheme_name(scene.integrator.scheme)},
                            {"step", d.step},
                            {"plan",
                             {{"forward_seconds", seconds(d.plan.forward_seconds)},
                              {"adjoint_seconds", seconds(d.plan.adjoint_seconds)},
                              {"forward_passes", d.plan.passes},
                              {"forward_lanes", d.plan.lanes},
                              {"cost_model", d.plan.model}}},
                            {"outputs", paths}};
      if (!d.atomics.empty()) out["atomics"] = d.atomics;
      std::cout << out.dump() << "\n";
    } else {
      std::string files;
      for (const std::string& p : paths) files += (files.empty() ? "" : ", ") + p;
      std::cout << args->loss << " loss " << d.loss << "; " << mode << " gradient of "
                << d.parameters << " parameter(s) on " << device.info().name << ": "
                << d.kernel_seconds * 1e3 << " ms, " << bytes_text(d.device_bytes)
                << " of device memory -> " << files << "\n";
    }
    return 0;
  };
}

}  // namespace ivr::cli
