// devices_json.cpp — every OpenCL device as one JSON document, for `ivr devices --json` and the
// C API's ivr_devices_json().
#include <nlohmann/json.hpp>

#include "ivr/device.hpp"
#include "ivr/error.hpp"
#include "ivr/planner.hpp"

namespace ivr {

std::string devices_json() {
  nlohmann::json list = nlohmann::json::array();
  for (const DeviceInfo& d : list_devices()) {
    // The render speed several devices' shares of the views follow (share_weights): from the
    // device's calibration file, else estimated; a file that cannot be read is said, not thrown.
    nlohmann::json speed, model;
    try {
      const CostModel m = load_cost_model(d);
      speed = 1.0 / m.seconds_per_sample;
      model = m.source;
    } catch (const Error& e) {
      model = std::string("unreadable: ") + e.what();
    }
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
                    {"correctly_rounded_divide_sqrt", d.correctly_rounded_divide_sqrt},
                    {"float_atomic_add", d.float_atomic_add},
                    {"double_atomic_add", d.double_atomic_add},
                    {"global_memory", d.global_memory},
                    {"max_allocation", d.max_allocation},
                    {"compute_units", d.compute_units},
                    {"max_clock_mhz", d.max_clock_mhz},
                    {"host_unified_memory", d.host_unified_memory},
                    {"samples_per_second", speed},
                    {"cost_model", model}});
  }
  return nlohmann::json{{"devices", list}}.dump();
}

}  // namespace ivr
