// jacobian_command.cpp — `ivr jacobian SCENE.json --wrt GROUPS -o J.npy`: the derivative of every
// pixel with respect to a few parameters (forward mode), for sensitivity analysis.
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "commands.hpp"

namespace ivr::cli {

namespace {

struct JacobianArgs {
  std::string scene, wrt, output;
  MarchOptions march;
  bool json = false;
};

// The parameters of a --wrt list, in order, with each group's name and count.
std::vector<Parameter> jacobian_parameters(const Scene& scene, const std::string& wrt,
                                           nlohmann::json* groups) {
  std::vector<Parameter> params;
  for (const std::string& g : parse_groups(wrt)) {
    const std::vector<Parameter> some = parameters_of(scene, g);
    const std::string name = g.rfind("voxels:", 0) == 0 ? "voxels" : g;
    groups->push_back({{"group", name}, {"first", params.size()}, {"count", some.size()}});
    params.insert(params.end(), some.begin(), some.end());
  }
  return params;
}

}  // namespace

Runner add_jacobian_command(CLI::App& app) {
  auto args = std::make_shared<JacobianArgs>();
  CLI::App* cmd = app.add_subcommand(
      "jacobian", "Derivative of every pixel with respect to a few parameters (forward mode)");
  cmd->add_option("scene", args->scene, "Scene JSON file (see docs/design.md)")->required();
  cmd->add_option("--wrt", args->wrt,
                  "Comma-separated parameter groups: tf, tf_points, scales, background, camera, "
                  "step, voxels:LIST, density")
      ->required();
  add_march_options(cmd, args->march);
  cmd->add_option("-o,--output", args->output,
                  "Output .npy: float32 (float64 with --precision f64) of shape (views, H, W, C, P), P in "
                  "--wrt order")
      ->required();
  cmd->add_flag("--json", args->json, "Print one JSON object with the layout and timings");
  return [args] {
    check_output_folder(args->output);
    const Precision precision = checked_precision(args->march);
    const Scene scene = with_integrator(load_scene(args->scene), args->march);
    nlohmann::json groups = nlohmann::json::array();
    const std::vector<Parameter> params = jacobian_parameters(scene, args->wrt, &groups);
    const ImageExtent cam = image_extent(scene);
    const std::vector<std::size_t> shape{std::size_t(cam.views), std::size_t(cam.height),
                                         std::size_t(cam.width), std::size_t(scene.channels()),
                                         params.size()};
    const double bytes = (precision == Precision::f64 ? 8.0 : 4.0) * double(shape[0]) * double(shape[1]) * double(shape[2]) *
                         double(shape[3]) * double(shape[4]);
    if (bytes > double(1ull << 34))
      throw Error(Status::out_of_memory, "a Jacobian of shape " + shape_text(shape) + " needs " +
                                             bytes_text(std::uint64_t(bytes)) +
                                             "; ask for fewer parameters (voxels:LIST)");
    Device device(args->march.device);
    JacobianOptions options;
    options.precision = precision;
    options.step = args->march.step;
    options.jacobian = true;
    Jacobian t = jacobian(device, scene, params, nullptr, options);
    if (precision == Precision::f64)
      write_outputs({{args->output, shape, std::move(t.jacobian_f64), true}});
    else
      write_outputs({{args->output, shape, std::move(t.jacobian)}});
    if (args->json) {
      std::cout << nlohmann::json{{"mode", "forward"},
                                  {"parameters", params.size()},
                                  {"groups", groups},
                                  {"shape", shape},
                                  {"seconds", t.kernel_seconds},
                                  {"passes", t.passes},
                                  {"lanes", t.lanes},
                                  {"device_bytes", t.device_bytes},
                                  {"device", device.info().name}, {"bricks", 1},
                                  {"precision", args->march.precision},
                                  {"scheme", scheme_name(scene.integrator.scheme)},
                                  {"step", t.step},
                                  {"outputs", {args->output}}}
                       .dump()
                << "\n";
    } else {
      std::cout << "Jacobian " << shape_text(shape) << " on " << device.info().name << ": "
                << t.kernel_seconds * 1e3 << " ms in " << t.passes << " pass(es) of " << t.lanes
                << " lanes -> " << args->output << "\n";
    }
    return 0;
  };
}

}  // namespace ivr::cli
