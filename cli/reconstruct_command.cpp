// reconstruct_command.cpp — `ivr reconstruct`: densities and/or the TF from target images
// (ivr/reconstruct.hpp), with progress, checkpoints, Ctrl-C that --resume continues, and the
// result, loss curve and before/after images as files.
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "commands.hpp"
#include "ivr/core.hpp"
#include "loss_plot.hpp"
#include "mpi_world.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

namespace {

struct ReconstructArgs {
  std::string scene, targets, prefix, wrt = "density", optimizer, schedule = "constant",
                                      loss = "mse", init = "scene", precision = "f32",
                                      mode = "auto", device, truth, held_out, held_out_targets,
                                      split = "views";
  ReconstructOptions options;  // the numeric options, bound at the library's defaults
  int checkpoint_every = 25;
  double lr = 0, step = 0;
  bool resume = false, json = false;
  CLI::Option* lr_option = nullptr;
  CLI::Option* step_option = nullptr;
  CLI::Option* init_option = nullptr;
};

std::string text(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

// The options as ReconstructOptions, every range checked under its command-line name first (the
// library's own checks follow, for what only it knows).
ReconstructOptions checked_options(const ReconstructArgs& a) {
  ReconstructOptions o = a.options;
  o.density = false;
  std::stringstream groups(a.wrt);
  for (std::string g; std::getline(groups, g, ',');) {
    if (g == "density")
      o.density = true;
    else if (g == "tf")
      o.tf = true;
    else
      throw input_error("--wrt: unknown group '" + g + "' (known: density, tf, density,tf)");
  }
  if (!o.density && !o.tf) throw input_error("--wrt: give density, tf or density,tf");
  if (a.options.iterations < 1)
    throw input_error("--iterations must be >= 1, got " + std::to_string(a.options.iterations));
  if (a.lr_option->count() > 0 && !(a.lr > 0 && std::isfinite(a.lr)))
    throw input_error("--lr must be > 0, got " + text(a.lr));
  o.optimizer.lr = a.lr_option->count() > 0 ? a.lr : 0;  // 0: the library's automatic lr
  if (!a.optimizer.empty()) {
    o.optimizer.kind = parse_optimizer(a.optimizer, "--optimizer");
    o.automatic_optimizer = false;
  }
  o.optimizer.schedule = parse_schedule(a.schedule, "--schedule");
  if (a.loss != "mse" && a.loss != "l1")
    throw input_error("--loss: unknown loss '" + a.loss + "' (known: mse, l1)");
  o.loss = a.loss == "l1" ? Loss::l1 : Loss::mse;
  const std::pair<const char*, double> weights[] = {{"--tv", a.options.tv},
                                                    {"--smoothness", a.options.smoothness},
                                                    {"--tf-smoothness", a.options.tf_smoothness}};
  for (const auto& [name, value] : weights)
    if (!(value >= 0 && std::isfinite(value)))
      throw input_error(std::string(name) + " must be >= 0, got " + text(value));
  if ((a.options.tv > 0 || a.options.smoothness > 0) && !o.density)
    throw input_error("--tv and --smoothness are priors on the density: add it to --wrt");
  if (a.options.tf_smoothness > 0 && !o.tf)
    throw input_error("--tf-smoothness is a prior on the TF: add tf to --wrt");

  const std::string forms = "(known: scene, zeros, constant:X with X >= 0 the density)";
  if (a.init == "scene") {
    o.init = Init::scene;
  } else if (a.init == "zeros") {
    o.init = Init::zeros;
  } else if (a.init.rfind("constant:", 0) == 0) {
    const std::string value = a.init.substr(9);
    std::size_t used = 0;
    double x = NAN;
    try {
      x = std::stod(value, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (value.empty() || used != value.size() || !(x >= 0) || !std::isfinite(x))
      throw input_error("--init: bad constant '" + value + "' in '" + a.init + "' " + forms);
    o.init = Init::constant;
    o.init_value = x;
  } else {
    throw input_error("--init: unknown start '" + a.init + "' " + forms);
  }
  if (a.init_option->count() > 0 && !o.density)
    throw input_error("--init sets the starting density: add density to --wrt");

  if (a.options.batch < 0)
    throw input_error("--batch must be >= 0 (0: every view), got " +
                      std::to_string(a.options.batch));
  if (a.options.levels < 0 || a.options.levels > 8)
    throw input_error("--levels must be in 0 .. 8 (0: automatic), got " +
                      std::to_string(a.options.levels));
  if (a.precision != "f32" && a.precision != "f64")
    throw input_error("--precision: unknown precision '" + a.precision + "' (known: f32, f64)");
  o.precision = a.precision == "f64" ? Precision::f64 : Precision::f32;
  if (a.step_option->count() > 0 && !(a.step > 0 && std::isfinite(a.step)))
    throw input_error("--step must be > 0, got " + text(a.step));
  o.step = a.step;
  if (a.mode != "auto" && a.mode != "forward" && a.mode != "adjoint")
    throw input_error("--mode: unknown mode '" + a.mode + "' (known: auto, forward, adjoint)");
  o.mode = a.mode == "forward"   ? Mode::forward
           : a.mode == "adjoint" ? Mode::adjoint
                                 : Mode::automatic;
  if (o.mode != Mode::automatic && o.density)
    throw input_error("--mode applies to --wrt tf alone (densities take the adjoint)");
  if (a.checkpoint_every < 0)
    throw input_error("--checkpoint-every must be >= 0 (0: only on interrupt), got " +
                      std::to_string(a.checkpoint_every));
  if (a.held_out.empty() != a.held_out_targets.empty())
    throw input_error("give both --held-out and --held-out-targets, or neither");
  validate_reconstruct(o);
  return o;
}

// An .npy of float32/float64 images of exactly the scene's render shape (views, H, W, C).
Image load_images(const std::string& path, const std::string& option, const Scene& scene) {
  const NpyArray a = load_npy(path);
  const std::string what = option + " '" + path + "'";
  if (a.dtype != "float32" && a.dtype != "float64")
    throw input_error(what + " has dtype " + a.dtype + "; expected float32 or float64");
  const std::vector<std::size_t> shape = image_file_shape(scene);
  if (a.shape != shape)
    throw input_error(what + " has shape " + shape_text(a.shape) + " but the scene renders " +
                      shape_text(shape) + (scene.has_ray_list() ? " (rays, C)" : " (views, H, W, C)"));
  const ImageExtent e = image_extent(scene);
  Image image;
  image.views = e.views;
  image.height = e.height;
  image.width = e.width;
  image.channels = scene.channels();
  image.pixels.resize(a.data.size());
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    const double x = a.data[i];
    if (!std::isfinite(x) || std::abs(x) > double(std::numeric_limits<float>::max()))
      throw input_error(what + " has a non-finite or out-of-range value (" + text(x) +
                        ") at flat index " + std::to_string(i));
    image.pixels[i] = float(x);
  }
  return image;
}

std::string clock_text(double seconds) {
  const long s = std::lround(std::max(seconds, 0.0));
  char buf[32];
  if (s >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

// Progress on stderr: one line redrawn in place on a terminal, else a plain line every
// max(1, N/20) iterations and at the last. Rates count this run's iterations only (a resumed
// run's earlier ones took their time in another process).
class Progress {
 public:
  Progress(int total, int first)
      : tty_(::isatty(STDERR_FILENO) == 1),
        total_(total),
        first_(first),
        every_(std::max(1, total / 20)),
        start_(std::chrono::steady_clock::now()) {}

  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  double rate(int done) const {
    const double s = seconds();
    return s > 0 ? (done - first_) / s : 0.0;
  }

  void update(const IterationRecord& r) {
    const int k = r.iteration;
    const double per_second = rate(k), eta = per_second > 0 ? (total_ - k) / per_second : 0.0;
    char line[256];
    if (tty_) {
      const int width = 10, filled = int(double(width) * k / total_);
      const std::string bar =
          std::string(std::size_t(filled), '#') + std::string(std::size_t(width - filled), '-');
      std::snprintf(line, sizeof line, "\r[%s] it %d/%d  loss %.3e  %.1f it/s  ETA %s ",
                    bar.c_str(), k, total_, r.loss, per_second, clock_text(eta).c_str());
      drawn_ = true;
    } else {
      if (k % every_ != 0 && k != total_) return;
      std::snprintf(line, sizeof line,
                    "iteration %d/%d loss %.3e prior %g lr %g %.1f it/s eta %lds\n", k, total_,
                    r.loss, r.prior, r.lr, per_second, std::lround(eta));
    }
    std::cerr << line << std::flush;
  }
  // Ends the terminal's progress line before anything else is printed.
  void finish() {
    if (drawn_) std::cerr << "\n" << std::flush;
    drawn_ = false;
  }

 private:
  bool tty_;
  int total_, first_, every_;
  std::chrono::steady_clock::time_point start_;
  bool drawn_ = false;
};

// The scene's render at the reconstruction's precision and step; over slabs (o.slabs: the scene
// holds this rank's planes) by every rank together, each getting the image; over several devices
// (the scene whole) by the devices together, their slabs or their shares of the views.
Image render_with(const std::vector<Device*>& devices, const Scene& scene,
                  const ReconstructOptions& o) {
  RenderOptions r;
  r.precision = o.precision;
  r.step = o.step;
  // (several devices of one process: the reconstruction's own shares of the views or slabs;
  // under mpirun o.shares weighs the ranks, not this rank's one device)
  if (devices.size() > 1) r.shares = o.shares;
  if (!o.slabs) return render(devices, scene, r);  // (one device: that device's render)
  if (devices.size() > 1) return render_domain(devices, scene, o.slab_march, r);
  DomainPart part = domain_part();
  part.march = o.slab_march;
  return render_domain(*devices[0], scene, part, r);
}

// View 0 of the scene (its volume and TF as they are).
Image render_view0(const std::vector<Device*>& devices, Scene scene, const ReconstructOptions& o) {
  if (!scene.has_ray_list()) scene.cameras.resize(1);  // a ray list: every ray
  return render_with(devices, scene, o);
}

// The shortest text that reads back as the same double, so the CSV holds the exact values.
std::string exact(double x) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, x).ptr);
}

std::string csv_text(const std::vector<IterationRecord>& history) {
  std::string s = "iteration,level,views,loss,prior,lr,seconds\n";
  for (const IterationRecord& r : history)
    s += std::to_string(r.iteration) + "," + std::to_string(r.level) + "," +
         std::to_string(r.views) + "," + exact(r.loss) + "," + exact(r.prior) + "," + exact(r.lr) +
         "," + exact(r.seconds) + "\n";
  return s;
}

// The loss plot's data: the image loss and the priors per iteration, each level by its grid.
// The devices a reconstruction runs on (--json "devices").
int devices_of(const Reconstruction&) { return 1; }
int devices_of(const MultiDeviceReconstruction& r) { return r.devices(); }

template <class AnyReconstruction>  // Reconstruction or MultiDeviceReconstruction
LossCurve loss_curve(const AnyReconstruction& r, const ReconstructOptions& used) {
  LossCurve c;
  const std::vector<IterationRecord>& history = r.history();
  for (std::size_t i = 0; i < history.size(); ++i) {
    c.iterations.push_back(history[i].iteration);
    c.losses.push_back(history[i].loss);
    c.priors.push_back(history[i].prior);
    if (i == 0 || history[i].level != history[i - 1].level) {
      const std::vector<int> d = r.level_dims(history[i].level);
      c.levels.push_back(
          {double(history[i].iteration),
           d[0] == d[1] && d[1] == d[2]
               ? std::to_string(d[0]) + "³"
               : std::to_string(d[0]) + "×" + std::to_string(d[1]) + "×" + std::to_string(d[2])});
    }
  }
  c.loss_name = used.loss == Loss::l1 ? "L1" : "MSE";
  c.loss_label = "image loss";
  std::ostringstream title;
  title << "ivr reconstruct: "
        << (used.density && used.tf ? "density and TF"
            : used.density          ? "density"
                                    : "TF")
        << ", " << optimizer_name(used.optimizer.kind) << " lr " << used.optimizer.lr << ", "
        << history.size() << " iterations";
  c.title = title.str();
  return c;
}

}  // namespace

Runner add_reconstruct_command(CLI::App& app) {
  auto args = std::make_shared<ReconstructArgs>();
  ReconstructArgs& a = *args;
  CLI::App* cmd = app.add_subcommand(
      "reconstruct",
      "Recover the densities and/or the TF from target images by gradient descent; Ctrl-C "
      "stops after the current iteration, writes a checkpoint and exits with status 130");
  cmd->add_option("scene", a.scene,
                  "Scene JSON file: its cameras see the targets, its volume gives the grid (and "
                  "the start with --init scene), its TF the known or starting TF")
      ->required();
  cmd->add_option("--targets", a.targets,
                  "Target images, .npy float32/float64 of the render's shape (views, H, W, C)")
      ->required();
  cmd->add_option("-o,--output", a.prefix,
                  "Output prefix: PREFIX_density.{npy,nrrd}, PREFIX_tf.{npy,json}, "
                  "PREFIX_loss.{csv,svg}, PREFIX_{before,after,target}.png")
      ->required();
  cmd->add_option("--wrt", a.wrt, "What to optimise: density (default), tf or density,tf");
  cmd->add_option("--iterations", a.options.iterations, "Iterations in total over every level")
      ->capture_default_str();
  a.lr_option =
      cmd->add_option("--lr", a.lr, "Learning rate (default: automatic, 0.025 Adam, 0.05 L-BFGS)");
  cmd->add_option("--optimizer", a.optimizer,
                  "adam, sgd or lbfgs (default: adam, or lbfgs for the TF alone)");
  cmd->add_option("--schedule", a.schedule, "Learning-rate schedule: constant, step or cosine");
  cmd->add_option("--loss", a.loss, "Image loss: mse (default) or l1");
  cmd->add_option("--tv", a.options.tv, "Weight of the densities' smoothed total variation (>= 0)");
  cmd->add_option("--smoothness", a.options.smoothness,
                  "Weight of the densities' mean |grad|^2 (>= 0)");
  cmd->add_option("--tf-smoothness", a.options.tf_smoothness,
                  "Weight of the squared differences of consecutive TF rows (>= 0)");
  a.init_option =
      cmd->add_option("--init", a.init, "Starting density: scene (default), zeros or constant:X");
  cmd->add_option("--batch", a.options.batch,
                  "Views per iteration, drawn at random (0: every view)");
  cmd->add_option("--levels", a.options.levels, "Coarse-to-fine levels, 0 .. 8 (0: up to 3)");
  cmd->add_option("--seed", a.options.seed, "Seed of the view batches")->capture_default_str();
  cmd->add_option("--precision", a.precision, "Arithmetic precision: f32 (default) or f64");
  a.step_option =
      cmd->add_option("--step", a.step, "Integrator step in voxel units (overrides the scene's)");
  cmd->add_option("--mode", a.mode, "Gradient mode of the TF alone: auto, forward or adjoint");
  cmd->add_option("--checkpoint-every", a.checkpoint_every,
                  "Write PREFIX_checkpoint* every N iterations (25; 0: only on interrupt)");
  cmd->add_flag("--resume", a.resume,
                "Continue from PREFIX_checkpoint.json (same scene, targets and options)");
  cmd->add_option("--truth", a.truth, "True volume file: report the relative volume error");
  cmd->add_option("--held-out", a.held_out,
                  "Scene whose cameras render the result for a held-out PSNR");
  cmd->add_option("--held-out-targets", a.held_out_targets,
                  "The held-out views' images, .npy of that render's shape");
  cmd->add_option("--device", a.device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE); "
                  "several, comma-separated: each a share of every batch's views (with "
                  "--split slabs|segments: each a slab)");
  add_split_option(cmd, a.split);
  add_shares_option(cmd, a.options.shares);
  cmd->add_flag("--json", a.json, "Print one JSON object with timings, losses and outputs");

  return [args] {
    const ReconstructArgs& a = *args;
    // Every input is checked before any work, so that a bad call wastes nothing and writes
    // nothing.
    ReconstructOptions options = checked_options(a);
    // Under mpirun: data-parallel over each batch's views (docs/scaling.md); rank 0 reports and
    // writes (checkpoints too: every rank holds the same state). --split slabs: each rank its
    // slab of the densities, and its own checkpoint (PREFIX_rankR_checkpoint*).
    const World& w = world();
    const bool writer = w.rank == 0;
    // Several devices in one process (--device A,B): each a share of every batch's views, or
    // with --split slabs|segments a slab of the densities.
    const int devices_asked = int(std::count(a.device.begin(), a.device.end(), ',')) + 1;
    const bool on_devices = devices_asked > 1;
    if (on_devices && w.size > 1)
      throw input_error("--device with " + std::to_string(devices_asked) +
                        " devices under mpirun: one device per rank");
    options.slabs = a.split != "views";
    options.slab_march = a.split == "segments" ? SlabMarch::segments : SlabMarch::states;
    if (w.size > 1) {
      options.worker = w.rank, options.workers = w.size;
      options.sum = [](std::vector<double>& v) { sum_all(v); };
      if (options.slabs) options.all_gather = domain_part().all_gather;
    }
    const bool own_checkpoint = writer || options.slabs;
    const std::string saved =
        options.slabs && w.size > 1 ? a.prefix + "_rank" + std::to_string(w.rank) : a.prefix;
    check_output_folder(a.prefix);
    // (Several devices: each its own files, PREFIX_deviceI_checkpoint*.)
    const std::string checkpoint = saved + (on_devices ? "_device0" : "") + "_checkpoint.json";
    const auto remove_checkpoint = [&] {
      if (on_devices)
        MultiDeviceReconstruction::remove_checkpoint(saved, devices_asked);
      else
        Reconstruction::remove_checkpoint(saved);
    };
    if (a.resume && !fs::exists(checkpoint))
      throw input_error("--resume: no checkpoint '" + checkpoint + "' to continue from");
    // (the devices first: under mpirun over slabs their speeds size the ranks' slabs, read next)
    const std::vector<std::unique_ptr<Device>> opened = open_devices(a.device);
    const std::vector<Device*> devices = pointers(opened);
    Device& device = *devices[0];
    weigh_rank_slabs(options.shares, devices, a.split);
    const Scene scene = load_scene_for(a.scene, a.split);
    const Image targets = load_images(a.targets, "--targets", scene);
    Volume truth;
    if (!a.truth.empty()) {
      VolumeSource source;
      source.path = a.truth;
      truth = load_volume(source);
      if (truth.nx != scene.volume.nx || truth.ny != scene.volume.ny || truth.nz != scene.volume.nz)
        throw input_error("--truth '" + a.truth + "' has " + std::to_string(truth.nx) + "x" +
                          std::to_string(truth.ny) + "x" + std::to_string(truth.nz) +
                          " voxels but the scene's grid is " + std::to_string(scene.volume.nx) +
                          "x" + std::to_string(scene.volume.ny) + "x" +
                          std::to_string(scene.volume.nz));
    }
    Scene held_out;  // the scene with the held-out cameras; the result's volume and TF go in
    Image held_out_targets;
    if (!a.held_out.empty()) {
      held_out = scene;
      held_out.cameras = load_scene(a.held_out).cameras;
      held_out_targets = load_images(a.held_out_targets, "--held-out-targets", held_out);
    }

    const int views = image_extent(scene).views;  // (each device's share of every batch)
    const std::vector<std::size_t> shares = checked_shares(
        options.shares, devices, std::size_t(options.batch > 0 ? std::min(options.batch, views) : views),
        a.split);
    if (w.size > 1)  // (the ranks': their views' counts, or their slabs' weights)
      options.shares = options.slabs ? world().slab_shares : worker_weights(shares);
    // Signals from here on: construction compiles kernels, which may take a while.
    const InterruptGuard interrupt;
    // The run, the same for one device (or rank) and for several devices.
    const auto run = [&](auto& r) -> int {
      // The start at the full grid (the first level's coarse copy would blur it).
      Scene start = scene;
      if (options.density && options.init != Init::scene)
        std::fill(start.volume.data.begin(), start.volume.data.end(),
                  options.init == Init::zeros ? 0.f : float(options.init_value));
      const Image before = render_view0(devices, start, options);
      int resumed_from = -1;
      if (a.resume) {
        r.resume(saved);
        resumed_from = r.iteration();
      }

      const ReconstructOptions& used = r.options();
      const int total = used.iterations;
      Progress progress(total, r.iteration());
      const auto stop_code = [&] {
        return interrupt.signal() == SIGINT ? 130 : interrupt.signal() == SIGTERM ? 143 : 0;
    };
    // A signal to any rank stops every rank after the same iteration.
    const auto interrupted = [&] {
      std::vector<double> signal{double(interrupt.signal() != 0)};
      if (w.size > 1) sum_all(signal);
      return signal[0] > 0;
    };
    while (!r.done()) {
      if (interrupted()) break;
      const IterationRecord& rec = r.step();
      if (writer) progress.update(rec);
      if (own_checkpoint && a.checkpoint_every > 0 && rec.iteration % a.checkpoint_every == 0 &&
          !r.done())
        r.save_checkpoint(saved);
    }
    const double seconds = progress.seconds(), rate = progress.rate(r.iteration());
    progress.finish();
    if (!r.done()) {
      // Interrupted: the state to continue from, then 128 + the signal, as a shell reports it.
      if (!own_checkpoint) return stop_code() ? stop_code() : 130;
      r.save_checkpoint(saved);
      if (!writer) return stop_code() ? stop_code() : 130;
      std::cerr << "interrupted after iteration " << r.iteration() << " of " << total
                << "; continue with --resume\n";
      return stop_code() ? stop_code() : 130;
    }
    // Everything is computed before the first file is written (over slabs the renders by every
    // rank, the slabs gathered on rank 0).
    Scene result = r.result();
    const Image after = render_view0(devices, result, options);
    Image held_out_image;
    if (!a.held_out.empty()) {
      held_out.volume = result.volume;
      held_out.tf = result.tf;
      held_out_image = render_with(devices, held_out, options);
    }
    if (options.slabs && !on_devices) {  // (several devices' result is whole already)
      const std::vector<double> mine(result.volume.data.begin(), result.volume.data.end());
      const std::vector<std::vector<double>> slabs = gather_parts(mine);
      if (writer) {
        const Volume& v = result.volume;
        const std::vector<double> whole = domain_assemble(v.nx, v.ny, v.nz, slabs);
        result.volume.data.assign(whole.begin(), whole.end());
      }
    }
    if (!writer) {
      if (options.slabs) Reconstruction::remove_checkpoint(saved);
      return 0;
    }
    double volume_error = NAN, held_out_psnr = NAN;
    if (!a.truth.empty()) volume_error = relative_volume_error(result.volume, truth);
    if (!a.held_out.empty()) held_out_psnr = psnr(held_out_image, held_out_targets);
    const std::vector<IterationRecord>& history = r.history();

    std::vector<std::string> outputs;
    const std::string& p = a.prefix;
    if (used.density) {
      const Volume& v = result.volume;
      save_npy(p + "_density.npy", {std::size_t(v.nz), std::size_t(v.ny), std::size_t(v.nx)},
               v.data.data());
      save_nrrd(p + "_density.nrrd", v);
      outputs.insert(outputs.end(), {p + "_density.npy", p + "_density.nrrd"});
    }
    if (used.tf) {
      const std::vector<double> values = tf_parameters(result.tf);
      const std::vector<float> rows(values.begin(), values.end());
      save_npy(p + "_tf.npy", tf_gradient_shape(result.tf), rows.data());
      write_text_atomically(p + "_tf.json", tf_json(result.tf) + "\n");
      outputs.insert(outputs.end(), {p + "_tf.npy", p + "_tf.json"});
    }
    write_text_atomically(p + "_loss.csv", csv_text(history));
    write_text_atomically(p + "_loss.svg", loss_svg(loss_curve(r, used)));
    outputs.insert(outputs.end(), {p + "_loss.csv", p + "_loss.svg"});
    if (!scene.has_ray_list()) {  // pictures of view 0 (a ray list has no picture to show)
      save_image_file(p + "_before.png", before);
      save_image_file(p + "_after.png", after);
      save_image_file(p + "_target.png", targets, 0);
      outputs.insert(outputs.end(), {p + "_before.png", p + "_after.png", p + "_target.png"});
    }
    remove_checkpoint();

    const double loss_first = history.empty() ? NAN : history.front().loss;
    const double loss_final = history.empty() ? NAN : history.back().loss;
    std::vector<std::vector<int>> levels;
    for (int l = 0; l < r.levels(); ++l) levels.push_back(r.level_dims(l));
    if (a.json) {
      nlohmann::json j = {
          {"iterations", r.iteration()},   {"seconds", seconds},
          {"iterations_per_second", rate}, {"loss_first", loss_first},
          {"loss_final", loss_final},      {"optimizer", optimizer_name(used.optimizer.kind)},
          {"lr", used.optimizer.lr},       {"levels", levels},
          {"device", device.info().name}, {"bricks", 1},  {"ranks", w.size}, {"split", a.split},
          {"devices", devices_of(r)},     {"shares", shares},
          {"slabs", device_slabs(devices, scene.volume.nz, a.options.shares, a.split)},
          {"outputs", outputs}};
      if (!a.truth.empty()) j["volume_error"] = volume_error;
      if (!a.held_out.empty()) j["held_out_psnr"] = held_out_psnr;  // null where +infinity
      if (resumed_from >= 0) j["resumed_from"] = resumed_from;
      std::cout << j.dump() << "\n";
    } else {
      std::ostringstream s;
      s << "reconstructed "
        << (used.density && used.tf ? "density and TF"
            : used.density          ? "density"
                                    : "TF")
        << " in " << r.iteration() << " iteration(s)"
        << (resumed_from >= 0 ? " (resumed from " + std::to_string(resumed_from) + ")" : "")
        << " on " << device.info().name << ": " << std::setprecision(3) << seconds << " s, " << rate
        << " it/s, " << optimizer_name(used.optimizer.kind) << " lr " << used.optimizer.lr << "\n";
      s << "loss " << std::scientific << loss_first << " -> " << loss_final << std::defaultfloat
        << ", levels";
      for (const std::vector<int>& d : levels) s << " " << d[0] << "x" << d[1] << "x" << d[2];
      s << "\n";
      if (!a.truth.empty()) s << "volume error " << volume_error << " against " << a.truth << "\n";
      if (!a.held_out.empty())
        s << "held-out PSNR " << held_out_psnr << " dB over " << held_out.cameras.size()
          << " view(s)\n";
      for (const std::string& o : outputs) s << "-> " << o << "\n";
      std::cout << s.str();
    }
    // A signal during the last iteration: the run is complete, so it is not an interruption.
    return 0;
    };
    if (on_devices) {
      MultiDeviceReconstruction r(devices, scene, targets, options);
      return run(r);
    }
    Reconstruction r(device, scene, targets, options);
    return run(r);
  };
}

}  // namespace ivr::cli
