// calibrate_command.cpp — `ivr calibrate`: measures the device's cost model for the planner and
// stores it where `ivr gradient --mode auto` reads it.
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "commands.hpp"

namespace ivr::cli {

namespace {

struct CalibrateArgs {
  std::string device, output;
  CalibrateOptions options;
  bool json = false;
};

}  // namespace

Runner add_calibrate_command(CLI::App& app) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Measure forward- and adjoint-mode costs on a device for the mode planner");
  cmd->add_option("--device", args->device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE)");
  cmd->add_option("--volume", args->options.volume, "Edge of the calibration volume")
      ->capture_default_str();
  cmd->add_option("--image", args->options.image, "Edge of the calibration image")
      ->capture_default_str();
  cmd->add_option("--repeats", args->options.repeats, "Timed runs per measurement")
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output,
                  "Where to write the model (default: the device's file in the user's cache, "
                  "$IVR_COST_MODEL if set)");
  cmd->add_flag("--json", args->json, "Print one JSON object with the measurements");
  return [args] {
    if (!args->output.empty()) check_output_folder(args->output);
    Device device(args->device);
    const Calibration c = calibrate(device, args->options);
    const std::string path = args->output.empty() ? cost_model_path(device.info()) : args->output;
    save_cost_model(path, c.model, device.info());
    if (args->json) {
      std::cout << nlohmann::json{{"device", device.info().name},
                                  {"path", path},
                                  {"forward_base", c.model.forward_base},
                                  {"forward_per_lane", c.model.forward_per_lane},
                                  {"forward_ray_base", c.model.forward_ray_base},
                                  {"forward_ray_per_lane", c.model.forward_ray_per_lane},
                                  {"adjoint", c.model.adjoint},
                                  {"seconds_per_sample", c.model.seconds_per_sample},
                                  {"render_seconds", c.render_seconds},
                                  {"adjoint_seconds", c.adjoint_seconds},
                                  {"lanes", c.lanes},
                                  {"forward_seconds", c.forward_seconds},
                                  {"ray_lanes", c.ray_lanes},
                                  {"forward_ray_seconds", c.forward_ray_seconds}}
                       .dump()
                << "\n";
    } else {
      std::cout << "render " << c.render_seconds * 1e3 << " ms, adjoint " << c.model.adjoint
                << "x, forward " << c.model.forward_base << " + " << c.model.forward_per_lane
                << " x lanes renders (camera and voxel lanes " << c.model.forward_ray_base << " + "
                << c.model.forward_ray_per_lane << " x lanes) on " << device.info().name << " -> "
                << path << "\n";
    }
    return 0;
  };
}

}  // namespace ivr::cli
