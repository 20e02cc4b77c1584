// devices_command.cpp — `ivr devices [--json]`: every OpenCL device ivr can use.
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "ivr/ivr.hpp"

namespace ivr::cli {

Runner add_devices_command(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "devices", "List the OpenCL devices (select one with --device or IVR_DEVICE)");
  auto json_out = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json_out, "Print one JSON object");
  return [json_out] {
    const std::vector<DeviceInfo> devices = list_devices();
    if (*json_out) {
      nlohmann::json list = nlohmann::json::array();
      for (const DeviceInfo& d : devices)
        list.push_back({{"index", d.index},
                        {"platform_index", d.platform_index},
                        {"device_index", d.device_index},
                        {"platform", d.platform},
                        {"name", d.name},
                        {"vendor", d.vendor},
                        {"type", d.type},
                        {"version", d.version},
                        {"driver", d.driver},
                        {"fp64", d.fp64},
                        {"float_atomic_add", d.float_atomic_add},
                        {"double_atomic_add", d.double_atomic_add},
                        {"global_memory", d.global_memory},
                        {"max_allocation", d.max_allocation},
                        {"compute_units", d.compute_units}});
      std::cout << nlohmann::json{{"devices", list}}.dump() << "\n";
      return 0;
    }
    for (const DeviceInfo& d : devices)
      std::cout << "[" << d.index << "] " << d.name << "  (" << d.type << ", " << d.platform << ", "
                << d.version << ", " << d.compute_units << " CUs, " << (d.global_memory >> 20)
                << " MiB" << (d.fp64 ? ", fp64" : "") << ")\n";
    return 0;
  };
}

}  // namespace ivr::cli
