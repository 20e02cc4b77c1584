// grad_command.cpp — `ivr grad SCENE.json --target T.npy --wrt GROUPS -o PREFIX`: loss gradients.
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

#include "commands.hpp"
#include "ivr/ivr.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

namespace {

struct GradArgs {
  std::string scene, target, wrt, mode = "adjoint", loss = "mse", precision = "f32", prefix, device;
  double step = 0;
  bool json = false;
};

const char* const known_groups = "density, tf, background";

Error input_error(const std::string& what) {
  return Error(Status::invalid_argument, what);
}

// The --wrt list as a set of known groups; later parameter groups are named as not built yet.
std::set<std::string> parse_groups(const std::string& wrt) {
  std::set<std::string> groups;
  std::stringstream list(wrt);
  std::string g;
  while (std::getline(list, g, ',')) {
    if (g.empty()) {
      throw input_error("--wrt: empty group in '" + wrt + "' (known: " + known_groups + ")");
    } else if (g == "density" || g == "tf" || g == "background") {
      groups.insert(g);
    } else if (g == "camera" || g == "step" || g == "scales" || g.rfind("voxels:", 0) == 0) {
      throw input_error("--wrt: gradients with respect to '" + g +
                        "' are not available yet (available: " + known_groups + ")");
    } else {
      throw input_error("--wrt: unknown parameter group '" + g + "' (known: " + known_groups +
                        "; not available yet: camera, step, scales, voxels:LIST)");
    }
  }
  if (groups.empty() || wrt.back() == ',')
    throw input_error("--wrt: empty group in '" + wrt + "' (known: " + known_groups + ")");
  return groups;
}

std::string shape_text(const std::vector<std::size_t>& shape) {
  std::string s = "(";
  for (std::size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// Reads TARGET.npy as an image of the scene's render shape (views, H, W, C); also accepts
// (H, W, C) for one view, and (views, H, W) / (H, W) for one channel. Values must be finite
// and fit float32; the first bad one is named by its index.
Image load_target(const std::string& path, const Scene& scene) {
  const NpyArray a = load_npy(path);
  const Camera& cam = scene.cameras.front();
  const std::size_t v = scene.cameras.size(), h = std::size_t(cam.height),
                    w = std::size_t(cam.width), c = std::size_t(scene.channels());
  const std::vector<std::size_t> full{v, h, w, c};
  std::vector<std::vector<std::size_t>> accepted{full};
  if (v == 1) accepted.push_back({h, w, c});
  if (c == 1) accepted.push_back({v, h, w});
  if (v == 1 && c == 1) accepted.push_back({h, w});
  bool ok = false;
  for (const auto& s : accepted) ok = ok || a.shape == s;
  if (!ok)
    throw input_error("target '" + path + "' has shape " + shape_text(a.shape) +
                      " but the scene renders " + shape_text(full));
  Image image;
  image.views = int(v);
  image.height = int(h);
  image.width = int(w);
  image.channels = int(c);
  image.pixels.resize(a.data.size());
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    const double x = a.data[i];
    if (!std::isfinite(x) || std::abs(x) > double(std::numeric_limits<float>::max())) {
      std::vector<std::size_t> index(a.shape.size());
      std::size_t rest = i;
      for (std::size_t d = a.shape.size(); d-- > 0;) {
        index[d] = rest % a.shape[d];
        rest /= a.shape[d];
      }
      std::ostringstream value;
      value << x;
      throw input_error("target '" + path + "' has " +
                        (std::isfinite(x) ? "a value beyond float32 range" : "a non-finite value") +
                        " (" + value.str() + ") at index " + shape_text(index));
    }
    image.pixels[i] = float(x);
  }
  return image;
}

std::string bytes_text(std::uint64_t bytes) {
  std::ostringstream text;
  text.precision(3);
  if (bytes < (1u << 20))
    text << double(bytes) / 1024 << " KiB";
  else
    text << double(bytes) / (1u << 20) << " MiB";
  return text.str();
}

struct Output {
  std::string path;
  std::vector<std::size_t> shape;
  std::vector<float> data;
};

// Writes every output under a hidden staging name first, then renames them all, so that a
// failure leaves none of them behind.
void write_outputs(const std::vector<Output>& outputs) {
  std::vector<std::string> staged;
  try {
    for (const Output& o : outputs) {
      const fs::path p(o.path);
      staged.push_back(
          (p.parent_path() / ("." + p.filename().string() + ".tmp" + std::to_string(::getpid())))
              .string());
      save_npy(staged.back(), o.shape, o.data.data());
    }
    for (std::size_t i = 0; i < outputs.size(); ++i) fs::rename(staged[i], outputs[i].path);
  } catch (...) {
    std::error_code ec;
    for (const std::string& s : staged) fs::remove(s, ec);
    throw;
  }
}

}  // namespace

Runner add_grad_command(CLI::App& app) {
  auto args = std::make_shared<GradArgs>();
  CLI::App* cmd = app.add_subcommand(
      "grad", "Gradient of an image loss with respect to the density, TF and background");
  cmd->add_option("scene", args->scene, "Scene JSON file (see DESIGN.md)")->required();
  cmd->add_option("--target", args->target,
                  "Target images, .npy of the render's shape (views, H, W, C); (H, W, C) for one "
                  "view, (views, H, W) or (H, W) for one channel")
      ->required();
  cmd->add_option("--wrt", args->wrt, "Comma-separated parameter groups: density, tf, background")
      ->required();
  cmd->add_option("--mode", args->mode, "Differentiation mode: adjoint (default)");
  cmd->add_option("--loss", args->loss, "Image loss: mse (default) or l1");
  cmd->add_option("--precision", args->precision, "Arithmetic precision: f32 (default) or f64");
  CLI::Option* step =
      cmd->add_option("--step", args->step, "Integrator step in voxel units (overrides the scene)");
  cmd->add_option("--device", args->device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE)");
  cmd->add_option("-o,--output", args->prefix,
                  "Output prefix: writes PREFIX_density.npy, PREFIX_tf.npy, PREFIX_background.npy "
                  "(float32) for the groups asked for")
      ->required();
  cmd->add_flag("--json", args->json,
                "Print one JSON object with the loss, timings, device memory and outputs");
  return [args, step] {
    // Every option and the output folder are checked before any work, so that a bad call wastes
    // nothing and writes nothing.
    if (args->prefix.empty()) throw input_error("-o: the output prefix is empty");
    const fs::path folder =
        fs::path(args->prefix).has_parent_path() ? fs::path(args->prefix).parent_path() : ".";
    if (!fs::is_directory(folder))
      throw Error(Status::io, "output folder '" + folder.string() + "' does not exist");
    const std::set<std::string> groups = parse_groups(args->wrt);
    if (args->mode == "forward" || args->mode == "auto")
      throw Error(Status::unsupported, "--mode " + args->mode +
                                           ": forward-mode differentiation is not built yet; "
                                           "use --mode adjoint");
    if (args->mode != "adjoint")
      throw input_error("--mode: unknown mode '" + args->mode + "' (known: adjoint)");
    if (args->loss != "mse" && args->loss != "l1")
      throw input_error("--loss: unknown loss '" + args->loss + "' (known: mse, l1)");
    if (args->precision != "f32" && args->precision != "f64")
      throw input_error("--precision: unknown precision '" + args->precision +
                        "' (known: f32, f64)");
    if (step->count() > 0 && !(args->step > 0 && std::isfinite(args->step)))
      throw input_error("--step must be > 0, got " + std::to_string(args->step));

    const Scene scene = load_scene(args->scene);
    const Image target = load_target(args->target, scene);
    Device device(args->device);
    GradientOptions options;
    options.precision = args->precision == "f64" ? Precision::f64 : Precision::f32;
    options.step = args->step;
    options.loss = args->loss == "l1" ? Loss::l1 : Loss::mse;
    options.density = groups.count("density") > 0;
    options.tf = groups.count("tf") > 0;
    options.background = groups.count("background") > 0;
    const Gradient g = gradient(device, scene, target, options);

    std::vector<Output> outputs;
    const Volume& vol = scene.volume;
    if (options.density)
      outputs.push_back({args->prefix + "_density.npy",
                         {std::size_t(vol.nz), std::size_t(vol.ny), std::size_t(vol.nx)},
                         g.density});
    if (options.tf)
      outputs.push_back({args->prefix + "_tf.npy", tf_gradient_shape(scene.tf),
                         std::vector<float>(g.tf.begin(), g.tf.end())});
    if (options.background)
      outputs.push_back({args->prefix + "_background.npy",
                         {g.background.size()},
                         std::vector<float>(g.background.begin(), g.background.end())});
    std::size_t parameters = 0;
    std::vector<std::string> paths;
    for (const Output& o : outputs) {
      parameters += o.data.size();
      paths.push_back(o.path);
    }
    write_outputs(outputs);

    if (args->json) {
      const nlohmann::json out = {{"loss", g.loss},
                                  {"loss_function", args->loss},
                                  {"mode", "adjoint"},
                                  {"wrt", groups},
                                  {"parameters", parameters},
                                  {"seconds", g.kernel_seconds},
                                  {"device_bytes", g.device_bytes},
                                  {"device", device.info().name},
                                  {"precision", args->precision},
                                  {"samples", g.samples},
                                  {"atomics", g.atomics},
                                  {"outputs", paths}};
      std::cout << out.dump() << "\n";
    } else {
      std::string files;
      for (const std::string& p : paths) files += (files.empty() ? "" : ", ") + p;
      std::cout << args->loss << " loss " << g.loss << "; adjoint gradient of " << parameters
                << " parameter(s) on " << device.info().name << ": " << g.kernel_seconds * 1e3
                << " ms, " << g.samples << " samples, " << bytes_text(g.device_bytes)
                << " of device memory -> " << files << "\n";
    }
    return 0;
  };
}

}  // namespace ivr::cli
