// tomo_commands.cpp — `ivr project`, `ivr backproject` and `ivr tomo`: absorption tomography
// (ivr/tomo.hpp) from the command line, with .npy arrays in and out.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
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

// What the three commands share: the scene, one .npy output, precision, device, --json.
struct CommonArgs {
  std::string scene, output, precision = "f32", device;
  bool json = false;
};

void add_common(CLI::App* cmd, CommonArgs& a, const std::string& output_help) {
  cmd->add_option("scene", a.scene,
                  "Scene JSON file: its volume gives the grid, its cameras the rays (model, TF "
                  "and integrator are not used)")
      ->required();
  cmd->add_option("-o,--output", a.output, output_help)->required();
  cmd->add_option("--precision", a.precision, "Arithmetic precision: f32 (default) or f64");
  cmd->add_option("--device", a.device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE); "
                  "tomo: several, comma-separated, each a share of the views (with --split "
                  "slabs: each a slab)");
  cmd->add_flag("--json", a.json, "Print one JSON object with timings and the output path");
}

// Checks the precision and the output path before any work; returns the precision.
Precision checked_common(const CommonArgs& a) {
  if (a.precision != "f32" && a.precision != "f64")
    throw input_error("--precision: unknown precision '" + a.precision + "' (known: f32, f64)");
  if (fs::path(a.output).extension() != ".npy")
    throw input_error("-o: output '" + a.output + "' needs the extension .npy");
  check_output_folder(a.output);
  return a.precision == "f64" ? Precision::f64 : Precision::f32;
}

// One value per ray (view, y, x) from an .npy of shape (views, H, W, 1) or (views, H, W) that
// matches the scene's cameras; every value finite. `floats_only`: float32/float64 data only.
std::vector<double> load_rays(const std::string& path, const std::string& option,
                              const Scene& scene, bool floats_only) {
  const NpyArray a = load_npy(path);
  const std::string what = option + " '" + path + "'";
  if (floats_only && a.dtype != "float32" && a.dtype != "float64")
    throw input_error(what + " has dtype " + a.dtype + "; expected float32 or float64");
  const ImageExtent e = image_extent(scene);
  const std::size_t v = std::size_t(e.views), h = std::size_t(e.height), w = std::size_t(e.width);
  const std::vector<std::vector<std::size_t>> shapes = ray_file_shapes(scene);
  if (a.shape != shapes[0] && a.shape != shapes[1])
    throw input_error(what + " has shape " + shape_text(a.shape) + " but the scene's " +
                      (scene.has_ray_list() ? "ray list of " + std::to_string(w) + " rays"
                                            : std::to_string(v) + " camera(s) of " +
                                                  std::to_string(w) + "x" + std::to_string(h)) +
                      " need " + shape_text(shapes[0]) + " or " + shape_text(shapes[1]));
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    if (std::isfinite(a.data[i])) continue;
    std::ostringstream value;
    value << a.data[i];
    throw input_error(what + " has a non-finite value (" + value.str() + ") at (" +
                      (scene.has_ray_list()
                           ? "ray " + std::to_string(i)
                           : "view " + std::to_string(i / (h * w)) + ", y " +
                                 std::to_string(i / w % h) + ", x " + std::to_string(i % w)) +
                      ")");
  }
  return a.data;
}

std::vector<std::size_t> volume_shape(const Scene& s) {
  return {std::size_t(s.volume.nz), std::size_t(s.volume.ny), std::size_t(s.volume.nx)};
}

struct TomoArgs {
  CommonArgs common;
  std::string projections, intensities, solver = "cgls", split = "views";
  TomoOptions options;
  double clamp = 0;
  CLI::Option* clamp_option = nullptr;
};

// Every option's range, named as on the command line, before any work.
void check_tomo_args(TomoArgs& a) {
  if (a.projections.empty() == a.intensities.empty())
    throw input_error("give exactly one of --projections and --intensities");
  if (a.clamp_option->count() > 0 && a.intensities.empty())
    throw input_error("--clamp-intensity applies to --intensities only");
  a.options.solver = parse_solver(a.solver, "--solver");
  const TomoOptions& o = a.options;
  const auto text = [](double x) {
    std::ostringstream s;
    s << x;
    return s.str();
  };
  if (o.iterations < 1)
    throw input_error("--iterations must be >= 1, got " + std::to_string(o.iterations));
  if (!(o.tolerance >= 0 && std::isfinite(o.tolerance)))
    throw input_error("--tolerance must be >= 0, got " + text(o.tolerance));
  if (!(o.tv >= 0 && std::isfinite(o.tv)))
    throw input_error("--tv must be >= 0, got " + text(o.tv));
  if (!(o.tikhonov >= 0 && std::isfinite(o.tikhonov)))
    throw input_error("--tikhonov must be >= 0, got " + text(o.tikhonov));
  if (o.tv > 0 && o.tikhonov > 0) throw input_error("give either --tv or --tikhonov, not both");
  if (!(o.tv_epsilon > 0 && std::isfinite(o.tv_epsilon)))
    throw input_error("--tv-epsilon must be > 0, got " + text(o.tv_epsilon));
  if (o.tv_reweight < 1)
    throw input_error("--tv-reweight must be >= 1, got " + std::to_string(o.tv_reweight));
  if (!(o.relaxation > 0 && o.relaxation < 2))
    throw input_error("--relaxation must be in (0, 2), got " + text(o.relaxation));
  if (!(a.clamp >= 0 && a.clamp < 1))
    throw input_error("--clamp-intensity must be in [0, 1), got " + text(a.clamp));
}

// Under mpirun: this rank's contiguous share (first, count) of the scene's views (a ray list: its
// rays), in proportion to the ranks' devices' speeds (checked_shares: a collective) — count 0
// where there are more ranks than views; the whole scene in one process.
std::pair<std::size_t, std::size_t> rank_share(const Scene& scene, Device& device) {
  const std::size_t items = share_items(scene);
  return rank_part(checked_shares({}, {&device}, items, "views"), items);
}

}  // namespace

// Under mpirun each rank projects its share of the views (a ray list: rays) and rank 0 gathers
// the lines in view order and writes them (docs/scaling.md).
Runner add_project_command(CLI::App& app) {
  auto args = std::make_shared<CommonArgs>();
  CLI::App* cmd = app.add_subcommand(
      "project", "Line integrals N v of the scene's volume along every camera ray (exact)");
  add_common(cmd, *args, "Output .npy: (views, H, W, 1), float32 (float64 with --precision f64)");
  return [args] {
    const Precision precision = checked_common(*args);
    const Scene scene = load_scene(args->scene);
    Device device(args->device);
    const auto [first, count] = rank_share(scene, device);
    std::vector<double> lines;
    std::unique_ptr<Projector> projector;  // none on a rank without views
    if (count) {
      projector = std::make_unique<Projector>(
          device, world().size > 1 ? scene_share(scene, first, count) : scene, precision);
      lines = projector->project({scene.volume.data.begin(), scene.volume.data.end()});
    }
    if (world().size > 1) {
      lines = gather(lines);
      if (world().rank != 0) return 0;  // rank 0 writes
    }
    const ImageExtent e = image_extent(scene);
    write_outputs({{args->output, ray_file_shapes(scene)[0], lines, precision == Precision::f64}});
    const double seconds = projector->last_kernel_seconds();  // (rank 0 has a view)
    if (args->json) {
      std::cout << nlohmann::json{{"device", device.info().name}, {"bricks", projector->bricks()},
                                  {"precision", args->precision},
                                  {"views", e.views},
                                  {"height", e.height},
                                  {"width", e.width},
                                  {"rays", e.pixels()},
                                  {"ranks", world().size},
                                  {"kernel_seconds", seconds},
                                  {"output", args->output}}
                       .dump()
                << "\n";
    } else {
      std::cout << "projected " << e.views << " view(s) of " << e.width << "x" << e.height
                << " (" << e.pixels() << " rays) on " << device.info().name << ": "
                << seconds * 1e3 << " ms -> " << args->output << "\n";
    }
    return 0;
  };
}

// Under mpirun each rank back-projects its share of the views' lines and the parts are summed
// (MPI_Allreduce); rank 0 writes.
Runner add_backproject_command(CLI::App& app) {
  struct Args {
    CommonArgs common;
    std::string images;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "backproject", "Back-projection N^T p of line integrals onto the scene's grid (exact)");
  add_common(cmd, args->common,
             "Output .npy: the volume's shape (Z, Y, X), float32 (float64 with --precision f64)");
  cmd->add_option("--images", args->images,
                  "Line integrals, .npy float32/float64 of shape (views, H, W, 1) or (views, H, W)")
      ->required();
  return [args] {
    const CommonArgs& c = args->common;
    const Precision precision = checked_common(c);
    const Scene scene = load_scene(c.scene);
    const std::vector<double> lines = load_rays(args->images, "--images", scene, true);
    Device device(c.device);
    const auto [first, count] = rank_share(scene, device);
    std::vector<double> volume(scene.volume.voxel_count(), 0.0);
    std::unique_ptr<Projector> projector;  // none on a rank without views
    if (count) {
      const std::size_t per_item = lines.size() / share_items(scene);
      projector = std::make_unique<Projector>(
          device, world().size > 1 ? scene_share(scene, first, count) : scene, precision);
      volume = projector->backproject(std::vector<double>(
          lines.begin() + first * per_item, lines.begin() + (first + count) * per_item));
    }
    if (world().size > 1) {  // N^T p = Σ over the ranks' views of their parts
      sum_all(volume);
      if (world().rank != 0) return 0;  // rank 0 writes
    }
    write_outputs({{c.output, volume_shape(scene), volume, precision == Precision::f64}});
    const double seconds = projector->last_kernel_seconds();  // (rank 0 has a view)
    const std::size_t rays = image_extent(scene).pixels();
    if (c.json) {
      std::cout << nlohmann::json{{"device", device.info().name}, {"bricks", projector->bricks()},
                                  {"precision", c.precision},     {"shape", volume_shape(scene)},
                                  {"rays", rays},                 {"ranks", world().size},
                                  {"kernel_seconds", seconds},    {"output", c.output}}
                       .dump()
                << "\n";
    } else {
      std::cout << "back-projected " << rays << " rays onto " << scene.volume.nx
                << "x" << scene.volume.ny << "x" << scene.volume.nz << " voxels on "
                << device.info().name << ": " << seconds * 1e3 << " ms -> " << c.output << "\n";
    }
    return 0;
  };
}

Runner add_tomo_command(CLI::App& app) {
  auto args = std::make_shared<TomoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "tomo",
      "Reconstruct the volume from line integrals (or intensities) by least squares; Ctrl-C "
      "stops after the current iteration, writes the last iterate and exits with status 130");
  add_common(cmd, args->common,
             "Output .npy: the volume's shape (Z, Y, X), float32 (float64 with --precision f64)");
  TomoOptions& o = args->options;
  cmd->add_option("--projections", args->projections,
                  "Line integrals p = N v, .npy float32/float64 of shape (views, H, W, 1) or "
                  "(views, H, W)");
  cmd->add_option("--intensities", args->intensities,
                  "Intensities I instead (same shapes, any numeric dtype): p = -log(I / I_in) / a "
                  "with I_in the scene's background and a its identity TF's extinction_scale");
  args->clamp_option =
      cmd->add_option("--clamp-intensity", args->clamp,
                      "Raise intensities to at least c * I_in before the log (0 <= c < 1; default "
                      "0: an intensity <= 0 is an error)");
  cmd->add_option("--solver", args->solver, "cgls (default), sirt or lsqr");
  cmd->add_option("--split", args->split,
                  "Under mpirun: views (default: each rank its share of the views and the whole "
                  "volume) or slabs (each rank one slab of z planes of the iterate, the lines "
                  "summed over the ranks; without mpirun, each --device one slab; "
                  "docs/scaling.md)")
      ->check(CLI::IsMember({"views", "slabs"}));
  add_shares_option(cmd, args->options.shares);
  cmd->add_option("--iterations", o.iterations, "Most iterations")->capture_default_str();
  cmd->add_flag("--nonneg", o.nonneg, "Keep every voxel >= 0");
  cmd->add_option("--tv", o.tv, "Weight of the smoothed total variation (>= 0)");
  cmd->add_option("--tikhonov", o.tikhonov, "Weight of lambda/2 |x|^2 (>= 0; not with --tv)");
  cmd->add_option("--tv-epsilon", o.tv_epsilon, "Smoothing epsilon of the TV")
      ->capture_default_str();
  cmd->add_option("--tv-reweight", o.tv_reweight, "CGLS/LSQR iterations between TV re-weightings")
      ->capture_default_str();
  cmd->add_option("--tolerance", o.tolerance, "Stop once |p - N x| / |p| <= this (0: never)")
      ->capture_default_str();
  cmd->add_option("--relaxation", o.relaxation, "SIRT's relaxation omega in (0, 2)")
      ->capture_default_str();
  return [args] {
    const CommonArgs& c = args->common;
    args->options.precision = checked_common(c);
    check_tomo_args(*args);
    const Scene scene = load_scene(c.scene);
    const bool from_intensities = !args->intensities.empty();
    std::vector<double> lines = from_intensities
                                    ? load_rays(args->intensities, "--intensities", scene, false)
                                    : load_rays(args->projections, "--projections", scene, true);
    if (from_intensities) lines = lines_from_intensities(scene, lines, args->clamp);
    const std::vector<std::unique_ptr<Device>> opened = open_devices(c.device);
    Device& device = *opened[0];
    if (opened.size() > 1 && world().size > 1)
      throw input_error("--device with " + std::to_string(opened.size()) +
                        " devices under mpirun: one device per rank");
    weigh_rank_slabs(args->options.shares, pointers(opened), args->split);
    const std::vector<std::size_t> shares =
        checked_shares(args->options.shares, pointers(opened), share_items(scene), args->split);

    const InterruptGuard interrupt;
    const int total = args->options.iterations;
    const TomoProgress progress = [&](const TomoIteration& it) {
      if (world().rank == 0) {
        std::ostringstream line;
        line << "iteration " << it.iteration << "/" << total << "  residual " << std::scientific
             << std::setprecision(3) << it.residual << "  " << std::fixed << std::setprecision(2)
             << it.seconds << " s\n";
        std::cerr << line.str() << std::flush;
      }
      return interrupt.signal() == 0;
    };
    TomoResult r;
    if (args->split == "slabs" && opened.size() > 1) {  // (several devices: no mpirun, above)
      // Each device its slab of the iterate, the whole iterate back (docs/scaling.md).
      r = tomo_domain(pointers(opened), scene, lines, args->options, progress);
    } else if (opened.size() > 1) {
      // Each device its share of the views and their projections, the whole iterate on each.
      r = tomo(pointers(opened), scene, lines, args->options, progress);
    } else if (args->split == "slabs") {
      // Each rank its slab of the iterate (docs/scaling.md); rank 0 joins the slabs.
      r = tomo_domain(device, scene, lines, domain_part(), args->options, progress);
      const std::vector<std::vector<double>> slabs =
          gather_parts(std::vector<double>(r.volume.begin(), r.volume.end()));
      const std::vector<std::vector<double>> slabs_f64 = gather_parts(r.volume_f64);
      if (world().rank != 0) return 0;  // rank 0 writes
      const int nx = scene.volume.nx, ny = scene.volume.ny, nz = scene.volume.nz;
      if (args->options.precision == Precision::f64)
        r.volume_f64 = domain_assemble(nx, ny, nz, slabs_f64);
      const std::vector<double> joined = domain_assemble(nx, ny, nz, slabs);
      r.volume.assign(joined.begin(), joined.end());
    } else if (world().size > 1) {
      // mpirun: each rank its share of the views and their projections (docs/scaling.md).
      const std::size_t items = share_items(scene);
      if (items < std::size_t(world().size))
        throw Error(Status::invalid_argument,
                    std::to_string(world().size) + " ranks for " + std::to_string(items) +
                        (scene.has_ray_list() ? " rays" : " views") + ": at most one rank each");
      const std::size_t per_item = lines.size() / items;
      const auto [first, count] = rank_part(shares, items);
      const std::vector<double> mine(lines.begin() + first * per_item,
                                     lines.begin() + (first + count) * per_item);
      r = tomo_shared(device, scene_share(scene, first, count), mine, args->options, sum_all,
                      progress);
      if (world().rank != 0) return 0;  // rank 0 writes
    } else {
      r = tomo(device, scene, lines, args->options, progress);
    }
    if (args->options.precision == Precision::f64)
      write_outputs({{c.output, volume_shape(scene), r.volume_f64, true}});
    else
      write_outputs({{c.output, volume_shape(scene), r.volume}});

    const double seconds = r.history.empty() ? 0.0 : r.history.back().seconds;
    if (c.json) {
      nlohmann::json history = nlohmann::json::array();
      for (const TomoIteration& it : r.history)
        history.push_back(
            {{"iteration", it.iteration}, {"residual", it.residual}, {"seconds", it.seconds}});
      std::cout << nlohmann::json{{"solver", solver_name(args->options.solver)},
                                  {"precision", c.precision},
                                  {"device", device.info().name}, {"bricks", r.bricks},
                                  {"devices", shares.empty() || world().size > 1
                                                  ? opened.size()
                                                             : std::size_t(std::count_if(
                                                                   shares.begin(), shares.end(),
                                                                   [](std::size_t c) { return c > 0; }))},
                                  {"shares", shares},
                                  {"slabs", device_slabs(pointers(opened), scene.volume.nz,
                                                         args->options.shares, args->split)},
                                  {"ranks", world().size},
                                  {"split", args->split},
                                  {"iterations", r.history.size()},
                                  {"max_iterations", total},
                                  {"stop_reason", r.stop_reason},
                                  {"residual", r.history.empty()
                                                   ? nlohmann::json(nullptr)
                                                   : nlohmann::json(r.history.back().residual)},
                                  {"history", history},
                                  {"seconds", seconds},
                                  {"setup_seconds", r.setup_seconds},
                                  {"output", c.output}}
                       .dump()
                << "\n";
    } else {
      std::cout << solver_name(args->options.solver) << ": " << r.history.size()
                << " iteration(s), stopped by " << r.stop_reason << ", residual "
                << (r.history.empty() ? 0.0 : r.history.back().residual) << ", " << seconds
                << " s -> " << c.output << "\n";
    }
    // 128 + the signal, as a shell reports a process that the signal ended.
    return interrupt.signal() == SIGINT ? 130 : interrupt.signal() == SIGTERM ? 143 : 0;
  };
}

}  // namespace ivr::cli
