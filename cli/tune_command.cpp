// tune_command.cpp — `ivr tune`: times work-group shapes per kernel on a device and prints the
// launch database's rows for it (lib/runtime/device_params_db.inc), with a JSON record of every
// timing.
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_support.hpp"
#include "commands.hpp"
#include "ivr/tune.hpp"

namespace ivr::cli {

namespace {

struct TuneArgs {
  std::string device, json_path, candidates, statistic = "median";
  std::vector<std::string> kernels;
  TuneOptions options;
  bool quick = false, emit = false, progress = false;
  CLI::App* cmd = nullptr;
};

// "0x0,8x8,16x16" → shapes; one line naming the bad one.
std::vector<std::pair<int, int>> parse_shapes(const std::string& text) {
  std::vector<std::pair<int, int>> shapes;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    int x = -1, y = -1;
    char tail = 0;
    if (std::sscanf(item.c_str(), "%dx%d%c", &x, &y, &tail) != 2 || x < 0 || y < 0)
      throw input_error("--candidates: '" + item +
                        "' is no work-group shape like 16x8 (0x0: the "
                        "driver's choice)");
    shapes.push_back({x, y});
  }
  if (shapes.empty()) throw input_error("--candidates: no shape given");
  return shapes;
}

bool by_minimum(const TuneOptions& o) {
  return o.statistic == TuneStatistic::minimum;
}

std::string shape(int x, int y) {
  return std::to_string(x) + "x" + std::to_string(y);
}

nlohmann::json to_json(const TuneResult& r, const std::string& command) {
  using nlohmann::json;
  const DeviceInfo& d = r.device;
  json kernels = json::array();
  for (const KernelTuning& k : r.kernels) {
    json j = {{"kernel", k.kernel}, {"operation", k.operation}};
    if (!k.skipped.empty()) j["skipped"] = k.skipped;
    if (k.failed) j["failed"] = true;
    if (!k.skipped.empty() && !k.failed) {
      kernels.push_back(j);
      continue;
    }
    j["needs_group"] = k.needs_group;
    j["kernel_max_group"] = k.kernel_max_group;
    j["check"] = k.check;
    j["current"] = {{"local", shape(k.current_x, k.current_y)}, {"source", k.current_source}};
    json candidates = json::array();
    for (const TuneCandidate& c : k.candidates) {
      json cj = {
          {"local", shape(c.local_x, c.local_y)}, {"local_x", c.local_x}, {"local_y", c.local_y}};
      if (c.skipped.empty()) {
        cj["median_ms"] = c.median_seconds * 1e3;
        cj["min_ms"] = c.min_seconds * 1e3;
        json runs = json::array();
        for (const double s : c.seconds) runs.push_back(s * 1e3);
        cj["runs_ms"] = runs;
      } else {
        cj["skipped"] = c.skipped;
      }
      candidates.push_back(cj);
    }
    j["candidates"] = candidates;
    if (k.fastest >= 0) {
      const TuneCandidate& f = k.candidates[std::size_t(k.fastest)];
      const TuneCandidate& w = k.candidates[std::size_t(k.winner)];
      j["fastest"] = shape(f.local_x, f.local_y);
      j["winner"] = shape(w.local_x, w.local_y);
      j["winner_ms"] = w.score_seconds * 1e3;
    }
    kernels.push_back(j);
  }
  return {{"schema", "ivr-tune/1"},
          {"ivr_version", IVR_VERSION_STRING},
          {"date", r.date},
          {"command", command},
          {"device",
           {{"name", d.name},
            {"vendor", d.vendor},
            {"platform", d.platform},
            {"type", d.type},
            {"version", d.version},
            {"driver", d.driver},
            {"compute_units", d.compute_units}}},
          {"options",
           {{"volume", r.options.volume},
            {"image", r.options.image},
            {"views", r.options.views},
            {"step", r.options.step},
            {"repeats", r.options.repeats},
            {"statistic", by_minimum(r.options) ? "min" : "median"},
            {"tie", r.options.tie}}},
          {"kernels", kernels},
          {"entries", tune_database_rows(r, command)}};
}

// The options that reproduce the run (the rows' comment names it).
std::string command_of(const TuneArgs& a) {
  std::ostringstream c;
  const TuneOptions& o = a.options;
  c << "ivr tune --volume " << o.volume << " --image " << o.image << " --views " << o.views
    << " --step " << o.step << " --repeats " << o.repeats;
  if (by_minimum(o)) c << " --statistic min";
  if (!a.candidates.empty()) c << " --candidates " << a.candidates;
  if (!a.kernels.empty()) {
    c << " --kernels ";
    for (std::size_t i = 0; i < a.kernels.size(); ++i) c << (i ? "," : "") << a.kernels[i];
  }
  return c.str();
}

void print_table(const TuneResult& r) {
  std::cout << "work-group shapes on " << r.device.name << " (" << r.device.platform << ", driver "
            << r.device.driver << "), " << (by_minimum(r.options) ? "minima" : "medians") << " of "
            << r.options.repeats << " runs:\n";
  for (const KernelTuning& k : r.kernels) {
    std::cout << "  " << k.kernel << ": ";
    if (k.winner < 0) {
      std::cout << k.skipped << "\n";
      continue;
    }
    for (const TuneCandidate& c : k.candidates) {
      if (!c.skipped.empty()) continue;
      char ms[32];
      std::snprintf(ms, sizeof ms, "%.4g", c.score_seconds * 1e3);
      std::cout << shape(c.local_x, c.local_y) << " " << ms << " ms  ";
    }
    const TuneCandidate& w = k.candidates[std::size_t(k.winner)];
    std::cout << "-> " << shape(w.local_x, w.local_y)
              << (k.winner == k.fastest ? "" : " (kept: within the tie of the fastest)") << "\n";
  }
}

}  // namespace

Runner add_tune_command(CLI::App& app) {
  auto args = std::make_shared<TuneArgs>();
  CLI::App* cmd = app.add_subcommand(
      "tune", "Time work-group shapes per kernel and print the launch database's rows");
  args->cmd = cmd;
  TuneOptions& o = args->options;
  cmd->add_option("--device", args->device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE)");
  cmd->add_option("--volume", o.volume, "Edge of the Marschner-Lobb volume")->capture_default_str();
  cmd->add_option("--image", o.image, "Edge of the image")->capture_default_str();
  cmd->add_option("--views", o.views, "Views around the volume")->capture_default_str();
  cmd->add_option("--step", o.step, "Integrator step in voxels")->capture_default_str();
  cmd->add_option("--repeats", o.repeats,
                  "Timed rounds, each running every shape once, after warm-ups")
      ->capture_default_str();
  cmd->add_option("--kernels", args->kernels,
                  "Kernels to tune, comma-separated (default: all of render, render_packet, "
                  "adjoint, adjoint_packet, jacobian, jacobian_packet, project, backproject, "
                  "bricked, bricked_packet that the device launches)")
      ->delimiter(',');
  cmd->add_option("--candidates", args->candidates,
                  "Shapes to try, e.g. 0x0,8x8,16x16 (0x0: the driver's choice; default: 0x0, "
                  "1x1, 2x2, 4x4, 8x8, 16x8, 16x16, 32x4, 32x8, 64x1, 64x4, 128x1, 256x1)");
  cmd->add_option("--statistic", args->statistic,
                  "What ranks the shapes: median of the rounds (default) or min (on a machine "
                  "others share: load only adds time)")
      ->check(CLI::IsMember({"median", "min"}));
  cmd->add_option("--tie", o.tie,
                  "Keep the shape in use unless the fastest beats it by more than this fraction")
      ->capture_default_str();
  cmd->add_flag("--quick", args->quick,
                "Small case for tests: 16³ volume, 32² image, step 1, 2 repeats, shapes 0x0, "
                "8x8 and 16x16 (options given explicitly still apply)");
  cmd->add_option("--json", args->json_path, "Write every timing and the winners to this file");
  cmd->add_flag("--emit-entries", args->emit,
                "Print only the database rows (to append to lib/runtime/device_params_db.inc)");
  cmd->add_flag("--progress", args->progress,
                "Report every shape on stderr once its kernel is timed");
  return [args] {
    TuneOptions& o = args->options;
    CLI::App& c = *args->cmd;
    if (args->quick) {  // explicit options win over the quick case's
      if (!c.count("--volume")) o.volume = 16;
      if (!c.count("--image")) o.image = 32;
      if (!c.count("--step")) o.step = 1;
      if (!c.count("--repeats")) o.repeats = 2;
      if (!c.count("--candidates")) args->candidates = "0x0,8x8,16x16";
    }
    if (!args->candidates.empty()) o.candidates = parse_shapes(args->candidates);
    o.statistic = args->statistic == "min" ? TuneStatistic::minimum : TuneStatistic::median;
    o.kernels = args->kernels;
    if (!args->json_path.empty()) check_output_folder(args->json_path);
    if (args->progress)
      o.progress = [](const std::string& kernel, const TuneCandidate& t) {
        std::cerr << "ivr tune: " << kernel << " " << shape(t.local_x, t.local_y) << ": "
                  << (t.skipped.empty() ? std::to_string(t.score_seconds * 1e3) + " ms" : t.skipped)
                  << std::endl;
      };
    Device device(args->device);
    const TuneResult result = tune(device, o);
    const std::string command = command_of(*args);
    if (!args->json_path.empty())
      write_text_atomically(args->json_path, to_json(result, command).dump(2) + "\n");
    if (args->emit)
      std::cout << tune_database_rows(result, command);
    else
      print_table(result);
    for (const KernelTuning& k : result.kernels)
      if (k.failed) throw Error(Status::opencl, "tune: " + k.kernel + ": " + k.skipped);
    return 0;
  };
}

}  // namespace ivr::cli
