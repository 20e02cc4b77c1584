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
  bool json = false, deterministic = false;
  std::vector<double> shares;
};

}  // namespace

// Under mpirun with --split slabs each rank differentiates over its slab: rank 0 joins the density's slabs, the
// TF gradient's parts are summed over the ranks; the background's and the forward lanes' (camera,
// …) are whole on every rank. One process with several devices: each device a slab, joined alike.
Gradient gradient_slabs(const std::vector<Device*>& devices, const Scene& scene,
                        const Image& target, const std::vector<std::string>& groups,
                        const GradientOptions& options, const std::string& split,
                        DomainStats* domain) {
  const World& w = world();
  if (w.size == 1 && devices.size() > 1)  // one process: its devices share the slabs
    return gradient_domain(devices, scene, target, domain_part(split).march, options, domain,
                           groups);
  Gradient mine = gradient_domain(one_device_per_rank(devices), scene,  // (its slab: load_scene_for)
                                  target, domain_part(split), options, domain, groups);
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
                        const std::vector<std::string>& groups, GradientOptions options,
                        const std::string& split, DomainStats* domain,
                        const std::vector<std::size_t>& rank_counts) {
  if (split != "views")
    return gradient_slabs(devices, scene, target, groups, options, split, domain);
  const World& w = world();
  if (w.size == 1) return gradient(devices, scene, target, groups, options);
  // Each rank a worker of the data-parallel gradient (GradientOptions::workers), summing over
  // MPI_COMM_WORLD: every rank gets the whole gradient (with --deterministic the one process's
  // density gradient bit for bit); rank 0 writes it.
  if (devices.size() > 1)
    throw Error(Status::invalid_argument, "mpirun: one device per rank, not --device with " +
                                              std::to_string(devices.size()));
  options.worker = w.rank, options.workers = w.size;
  options.shares = worker_weights(rank_counts);  // (the ranks' shares: checked_shares)
  options.sum = [](std::vector<double>& v) { sum_all(v); };
  return gradient(*devices[0], scene, target, groups, options);
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
  cmd->add_flag("--deterministic", args->deterministic,
                "Sum the density gradient in fixed point (adjoint mode, where the device has 64-bit "
                "integer atomics): the same bits on every run, and under mpirun or with several "
                "devices the one process's bits");
  add_march_options(cmd, args->march);
  add_split_option(cmd, args->split);
  add_shares_option(cmd, args->shares);
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
    // (the devices first: under mpirun over slabs their speeds size the ranks' slabs, read next)
    const std::vector<std::unique_ptr<Device>> devices = open_devices(args->march.device);
    Device& device = *devices[0];
    weigh_rank_slabs(args->shares, pointers(devices), args->split);
    const Scene scene = with_integrator(load_scene_for(args->scene, args->split), args->march);
    const Image target = load_target(args->target, scene);
    options.precision = precision;
    options.step = args->march.step;
    options.loss = args->loss == "l1" ? Loss::l1 : args->loss == "dot" ? Loss::dot : Loss::mse;
    options.deterministic = args->deterministic;
    const std::vector<std::size_t> shares =
        checked_shares(args->shares, pointers(devices), share_items(scene), args->split);
    options.shares = device_shares(args->shares);
    DomainStats domain;  // (over slabs: rank 0's exchanges of the rays' states or segments)
    const Gradient d = gradient_ranks(pointers(devices), scene, target, groups, options,
                                      args->split, &domain, shares);
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
                            {"device", device.info().name}, {"bricks", d.bricks}, {"devices", d.devices}, {"shares", shares},
                            {"slabs", device_slabs(pointers(devices), scene.volume.nz, args->shares,
                                                   args->split)},
                            {"ranks", world().size}, {"split", args->split},
                            {"exchanges", domain.exchanges},
                            {"exchanged_bytes", domain.sent_bytes},
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
      out["deterministic"] = d.deterministic;
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
