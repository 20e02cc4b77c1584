// viewpoint_command.cpp — `ivr viewpoint`: the camera of highest image entropy on a scene
// camera's orbit (ivr/viewpoint.hpp), written as a scene-file camera object.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "cli_support.hpp"
#include "commands.hpp"
#include "ivr/core.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

namespace {

struct ViewpointArgs {
  std::string scene, output, optimizer = "adam", precision = "f32", render, device;
  ViewpointOptions options;  // --view and --iterations, at the library's defaults
  double lr = 0, step = 0;
  bool json = false;
  CLI::Option* lr_option = nullptr;
  CLI::Option* step_option = nullptr;
};

std::string text(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

std::string lower_ext(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// The options as ViewpointOptions, checked under their command-line names before any work.
ViewpointOptions checked_options(const ViewpointArgs& a) {
  ViewpointOptions o = a.options;
  if (lower_ext(a.output) != ".json")
    throw input_error("-o: output '" + a.output + "' needs the extension .json");
  check_output_folder(a.output);
  if (!a.render.empty()) {
    const std::string ext = lower_ext(a.render);
    if (ext != ".png" && ext != ".exr" && ext != ".tif" && ext != ".tiff")
      throw input_error("--render: '" + a.render + "' needs the extension .png, .exr or .tif");
    check_output_folder(a.render);
  }
  if (a.options.iterations < 0)
    throw input_error("--iterations must be >= 0, got " + std::to_string(a.options.iterations));
  if (a.lr_option->count() > 0 && !(a.lr > 0 && std::isfinite(a.lr)))
    throw input_error("--lr must be > 0, got " + text(a.lr));
  o.optimizer.lr = a.lr_option->count() > 0 ? a.lr : 0;  // 0: the library's 0.05 rad
  o.optimizer.kind = parse_optimizer(a.optimizer, "--optimizer");
  if (a.precision != "f32" && a.precision != "f64")
    throw input_error("--precision: unknown precision '" + a.precision + "' (known: f32, f64)");
  o.precision = a.precision == "f64" ? Precision::f64 : Precision::f32;
  if (a.step_option->count() > 0 && !(a.step > 0 && std::isfinite(a.step)))
    throw input_error("--step must be > 0, got " + text(a.step));
  o.step = a.step;
  return o;
}

}  // namespace

Runner add_viewpoint_command(CLI::App& app) {
  auto args = std::make_shared<ViewpointArgs>();
  ViewpointArgs& a = *args;
  CLI::App* cmd = app.add_subcommand(
      "viewpoint",
      "Find the camera of highest image entropy on the orbit of one of the scene's cameras "
      "(gradient ascent over azimuth and elevation, forward mode)");
  cmd->add_option("scene", a.scene, "Scene JSON file (see docs/design.md)")->required();
  cmd->add_option("-o,--output", a.output,
                  "Output CAMERA.json: the best camera as a scene file's camera object")
      ->required();
  cmd->add_option("--view", a.options.view,
                  "The camera to start from; its distance to its target is kept")
      ->capture_default_str();
  cmd->add_option("--iterations", a.options.iterations, "Ascent steps")->capture_default_str();
  a.lr_option = cmd->add_option("--lr", a.lr, "Step size in radians (default 0.05)");
  cmd->add_option("--optimizer", a.optimizer, "adam (default), sgd or lbfgs");
  cmd->add_option("--precision", a.precision, "Arithmetic precision: f32 (default) or f64");
  a.step_option =
      cmd->add_option("--step", a.step, "Integrator step in voxel units (overrides the scene's)");
  cmd->add_option("--render", a.render, "Also write the best view as an image (.png/.exr/.tif)");
  cmd->add_option("--device", a.device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE)");
  cmd->add_flag("--json", a.json, "Print one JSON object with the entropies, path and camera");

  return [args] {
    const ViewpointArgs& a = *args;
    const ViewpointOptions options = checked_options(a);
    const Scene scene = load_scene(a.scene);
    const int cameras = int(scene.cameras.size());
    if (a.options.view < 0 || a.options.view >= cameras)
      throw input_error("--view " + std::to_string(a.options.view) +
                        " does not exist: the scene has " + std::to_string(cameras) +
                        " camera(s), 0 .. " + std::to_string(cameras - 1));

    Device device(a.device);
    const int total = options.iterations;
    const Viewpoint best = select_viewpoint(device, scene, options, [&](const ViewpointStep& s) {
      char line[160];
      std::snprintf(line, sizeof line, "iteration %d/%d entropy %.6f azimuth %.2f elevation %.2f\n",
                    s.iteration, total, s.entropy, s.azimuth, s.elevation);
      std::cerr << line << std::flush;
      return true;
    });
    // The iteration where the best camera was seen (the first of equal entropies).
    std::size_t at = 0;
    for (std::size_t i = 1; i < best.history.size(); ++i)
      if (best.history[i].entropy > best.history[at].entropy) at = i;
    const ViewpointStep& start = best.history.front();
    const ViewpointStep& top = best.history[at];

    Image image;
    if (!a.render.empty()) {
      Scene one = scene;
      one.cameras = {best.camera};
      RenderOptions r;
      r.precision = options.precision;
      r.step = options.step;
      image = render(device, one, r);
    }
    const std::string camera = camera_json(best.camera);
    write_text_atomically(a.output, camera + "\n");
    std::vector<std::string> outputs = {a.output};
    if (!a.render.empty()) {
      save_image_file(a.render, image, 0);
      outputs.push_back(a.render);
    }

    if (a.json) {
      nlohmann::json history = nlohmann::json::array();
      for (const ViewpointStep& s : best.history)
        history.push_back({s.iteration, s.entropy, s.azimuth, s.elevation});
      std::cout << nlohmann::json{{"entropy_start", start.entropy},
                                  {"entropy", best.entropy},
                                  {"best_iteration", top.iteration},
                                  {"history", history},
                                  {"camera", nlohmann::json::parse(camera)},
                                  {"device", device.info().name}, {"bricks", 1},
                                  {"outputs", outputs}}
                       .dump()
                << "\n";
    } else {
      std::ostringstream s;
      s << std::fixed << std::setprecision(6) << "entropy " << start.entropy
        << " at the start, best " << best.entropy << " at iteration " << top.iteration << " of "
        << total << "\n"
        << std::setprecision(2) << "azimuth/elevation (degrees):";
      for (const ViewpointStep& h : best.history) s << " " << h.azimuth << "/" << h.elevation;
      s << "\n";
      for (const std::string& o : outputs) s << "-> " << o << "\n";
      std::cout << s.str();
    }
    return 0;
  };
}

}  // namespace ivr::cli
