// devices_command.cpp — `ivr devices [--json]`: every OpenCL device ivr can use.
#include <iostream>

#include "commands.hpp"
#include "ivr/core.hpp"

namespace ivr::cli {

Runner add_devices_command(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "devices", "List the OpenCL devices (select one with --device or IVR_DEVICE)");
  auto json_out = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json_out, "Print one JSON object");
  return [json_out] {
    const std::vector<DeviceInfo> devices = list_devices();
    if (*json_out) {
      std::cout << devices_json() << "\n";
      return 0;
    }
    for (const DeviceInfo& d : devices) {
      // The speed several devices' shares of the views follow (--shares' default); a calibration
      // file that cannot be read is said, and the other devices listed.
      std::string speed;
      try {
        const CostModel model = load_cost_model(d);
        speed = std::to_string(1e-6 / model.seconds_per_sample) + " M samples/s, " +
                (model.source == "default" ? "estimated" : "calibrated");
      } catch (const Error& e) {
        speed = std::string("speed unknown: ") + e.what();
      }
      std::cout << "[" << d.index << "] " << d.name << "  (" << d.type << ", " << d.platform << ", "
                << d.version << ", " << d.compute_units << " CUs, " << (d.global_memory >> 20)
                << " MiB" << (d.fp64 ? ", fp64" : "") << "; " << speed << ")\n";
    }
    return 0;
  };
}

}  // namespace ivr::cli
