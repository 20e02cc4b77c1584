// cli_support.cpp — helpers shared by the subcommands (see cli_support.hpp).
#include "cli_support.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "ivr/planner.hpp"
#include "mpi_world.hpp"

namespace fs = std::filesystem;

namespace ivr::cli {

Error input_error(const std::string& what) {
  return Error(Status::invalid_argument, what);
}

std::string shape_text(const std::vector<std::size_t>& shape) {
  std::string s = "(";
  for (std::size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

std::vector<std::size_t> image_file_shape(const Scene& scene) {
  const ImageExtent e = image_extent(scene);
  const std::size_t c = std::size_t(scene.channels());
  if (scene.has_ray_list()) return {std::size_t(e.width), c};
  return {std::size_t(e.views), std::size_t(e.height), std::size_t(e.width), c};
}

std::vector<std::vector<std::size_t>> ray_file_shapes(const Scene& scene) {
  const ImageExtent e = image_extent(scene);
  const std::size_t v = std::size_t(e.views), h = std::size_t(e.height), w = std::size_t(e.width);
  if (scene.has_ray_list()) return {{w, 1}, {w}};
  return {{v, h, w, 1}, {v, h, w}};
}

Image load_target(const std::string& path, const Scene& scene) {
  const NpyArray a = load_npy(path);
  const ImageExtent cam = image_extent(scene);
  const std::size_t v = std::size_t(cam.views), h = std::size_t(cam.height),
                    w = std::size_t(cam.width), c = std::size_t(scene.channels());
  const std::vector<std::size_t> full = image_file_shape(scene);
  std::vector<std::vector<std::size_t>> accepted{full};
  if (scene.has_ray_list()) {
    if (c == 1) accepted.push_back({w});
  } else {
    if (v == 1) accepted.push_back({h, w, c});
    if (c == 1) accepted.push_back({v, h, w});
    if (v == 1 && c == 1) accepted.push_back({h, w});
  }
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

void write_outputs(const std::vector<Output>& outputs) {
  std::vector<std::string> staged;
  try {
    for (const Output& o : outputs) {
      const fs::path p(o.path);
      staged.push_back(
          (p.parent_path() / ("." + p.filename().string() + ".tmp" + std::to_string(::getpid())))
              .string());
      if (o.float64) {
        save_npy(staged.back(), o.shape, o.data.data());
      } else {
        const std::vector<float> rounded(o.data.begin(), o.data.end());
        save_npy(staged.back(), o.shape, rounded.data());
      }
    }
    for (std::size_t i = 0; i < outputs.size(); ++i) fs::rename(staged[i], outputs[i].path);
  } catch (...) {
    std::error_code ec;
    for (const std::string& s : staged) fs::remove(s, ec);
    throw;
  }
}

void add_march_options(CLI::App* cmd, MarchOptions& o) {
  cmd->add_option("--precision", o.precision, "Arithmetic precision: f32 (default) or f64");
  o.step_option =
      cmd->add_option("--step", o.step,
                      "Integrator step in voxel units (overrides the scene's step and tolerance)");
  cmd->add_option("--scheme", o.scheme,
                  "Integrator: midpoint, trapezoid, exact (absorption) or preintegrated "
                  "(overrides the scene)");
  o.tolerance_option = cmd->add_option(
      "--tolerance", o.tolerance,
      "Choose the step for this relative RMS image error (overrides the scene's tolerance)");
  cmd->add_option("--device", o.device,
                  "Device: index, P:D, cpu, gpu or a name substring (default: $IVR_DEVICE); "
                  "render and gradient: several, comma-separated, share the views");
}

void add_split_option(CLI::App* cmd, std::string& split) {
  cmd->add_option("--split", split,
                  "Under mpirun: views (default: each rank its share of the views, the whole "
                  "volume on every rank), slabs (each rank one slab of z planes, the rays' "
                  "march states passed between ranks; one device per rank — without mpirun, each "
                  "--device one slab; docs/scaling.md) or "
                  "segments (slabs, each rank marching its segments of every ray at once, "
                  "composited after one exchange; with early termination on, within its "
                  "threshold of the one-process render)")
      ->check(CLI::IsMember({"views", "slabs", "segments"}));
}

std::vector<std::unique_ptr<Device>> open_devices(const std::string& selectors) {
  std::vector<std::unique_ptr<Device>> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = selectors.find(',', start);
    const std::string one = selectors.substr(start, comma == std::string::npos ? comma : comma - start);
    if (one.empty() && selectors.find(',') != std::string::npos)
      throw Error(Status::invalid_argument, "--device '" + selectors + "': an empty selector");
    out.push_back(std::make_unique<Device>(one));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

void add_shares_option(CLI::App* cmd, std::vector<double>& shares) {
  cmd->add_option("--shares", shares,
                  "Each device's weight, comma-separated, its share of the views in proportion, "
                  "or with --split slabs|segments of the volume's planes (several --device; "
                  "under mpirun one a rank, every rank giving the same). "
                  "Default: each device's speed, samples per second from `ivr calibrate` or "
                  "estimated from its size (`ivr devices` shows it); a rank's, its devices' summed")
      ->delimiter(',');
}

namespace {

// This rank's speed: its devices' samples per second summed (their cost models).
double rank_speed(const std::vector<Device*>& devices) {
  double total = 0;
  for (const Device* d : devices) total += samples_per_second(d->info());
  if (!(total > 0) || !std::isfinite(total))
    throw input_error("rank " + std::to_string(world().rank) + ": its devices' cost models give " +
                      std::to_string(total) + " samples per second; give --shares");
  return total;
}

// The ranks' weights under mpirun (a collective): --shares, one a rank (each checked), or else
// each rank's speed, gathered; every rank gets the same.
std::vector<double> rank_weights(const std::vector<double>& shares,
                                 const std::vector<Device*>& devices) {
  if (shares.empty()) return every_rank(rank_speed(devices));
  if (shares.size() != std::size_t(world().size))
    throw input_error("--shares: " + std::to_string(shares.size()) + " weights for " +
                      std::to_string(world().size) + " ranks (under mpirun, one a rank)");
  view_shares(0, shares);  // (each weight checked, by name)
  return shares;
}

}  // namespace

std::vector<std::size_t> checked_shares(const std::vector<double>& shares,
                                        const std::vector<Device*>& devices, std::size_t items,
                                        const std::string& split) {
  std::vector<std::size_t> counts;
  if (world().size > 1) {
    if (split != "views") return {};  // (the ranks' slabs: weigh_rank_slabs)
    // Every rank computes the same split from the same weights.
    for (const auto& part : view_shares_each(items, rank_weights(shares, devices)))
      counts.push_back(part.second);
    return counts;
  }
  if (devices.size() < 2 || split != "views") {
    if (!shares.empty()) share_weights(devices, shares);  // (one device: their count checked)
    return {};
  }
  for (const auto& part : view_shares(items, share_weights(devices, shares)))
    counts.push_back(part.second);
  return counts;
}

std::pair<std::size_t, std::size_t> rank_part(const std::vector<std::size_t>& counts,
                                              std::size_t items) {
  if (world().size == 1 || counts.empty()) return {0, items};
  std::size_t first = 0;
  for (int r = 0; r < world().rank; ++r) first += counts[std::size_t(r)];
  return {first, counts[std::size_t(world().rank)]};
}

void weigh_rank_slabs(const std::vector<double>& shares, const std::vector<Device*>& devices,
                      const std::string& split) {
  if (world().size == 1 || split == "views") return;
  set_slab_shares(rank_weights(shares, devices));  // (every rank the same, so the same slabs)
}

std::vector<std::array<int, 2>> device_slabs(const std::vector<Device*>& devices, int nz,
                                             const std::vector<double>& shares,
                                             const std::string& split) {
  if (split == "views" || (world().size == 1 && devices.size() < 2)) return {};
  const int n = world().size > 1 ? world().size : int(devices.size());
  const std::vector<double> weights =
      world().size > 1 ? world().slab_shares : share_weights(devices, shares);
  std::vector<std::array<int, 2>> out;
  for (int i = 0; i < n; ++i) {
    const Slab s = domain_slab(nz, i, n, weights);
    out.push_back({s.first, s.last});
  }
  return out;
}

std::vector<double> device_shares(const std::vector<double>& shares) {
  return world().size > 1 ? std::vector<double>{} : shares;
}

std::vector<double> worker_weights(const std::vector<std::size_t>& counts) {
  // A count of 0 only where there are fewer views than ranks: the first ones one each, which the
  // equal split (no weights) gives too.
  if (std::find(counts.begin(), counts.end(), std::size_t(0)) != counts.end()) return {};
  return std::vector<double>(counts.begin(), counts.end());
}

std::vector<Device*> pointers(const std::vector<std::unique_ptr<Device>>& devices) {
  std::vector<Device*> out;
  for (const auto& d : devices) out.push_back(d.get());
  return out;
}

Precision checked_precision(const MarchOptions& o) {
  if (o.precision != "f32" && o.precision != "f64")
    throw input_error("--precision: unknown precision '" + o.precision + "' (known: f32, f64)");
  if (o.step_option && o.step_option->count() > 0 && !(o.step > 0 && std::isfinite(o.step)))
    throw input_error("--step must be > 0, got " + std::to_string(o.step));
  if (o.tolerance_option && o.tolerance_option->count() > 0 &&
      !(o.tolerance > 0 && std::isfinite(o.tolerance)))
    throw input_error("--tolerance must be > 0, got " + std::to_string(o.tolerance));
  if (!o.scheme.empty()) parse_scheme(o.scheme, "--scheme");
  return o.precision == "f64" ? Precision::f64 : Precision::f32;
}

Scene with_integrator(Scene scene, const MarchOptions& o) {
  if (!o.scheme.empty()) scene.integrator.scheme = parse_scheme(o.scheme, "--scheme");
  if (o.tolerance_option && o.tolerance_option->count() > 0)
    scene.integrator.tolerance = o.tolerance;
  // A rank's slab (--split slabs, load_scene_for): checked as a volume of its planes.
  const int nz = scene.volume.nz;
  const std::size_t plane = std::size_t(scene.volume.nx) * std::size_t(scene.volume.ny);
  if (scene.volume.data.size() != scene.volume.voxel_count() && plane &&
      scene.volume.data.size() % plane == 0)
    scene.volume.nz = int(scene.volume.data.size() / plane);
  validate(scene);
  scene.volume.nz = nz;
  return scene;
}

void check_output_folder(const std::string& path_or_prefix) {
  if (path_or_prefix.empty()) throw input_error("-o: the output path is empty");
  const fs::path p(path_or_prefix);
  const fs::path folder = p.has_parent_path() ? p.parent_path() : ".";
  if (!fs::is_directory(folder))
    throw Error(Status::io, "output folder '" + folder.string() + "' does not exist");
}

void write_text_atomically(const std::string& path, const std::string& content) {
  const fs::path p(path);
  const fs::path tmp =
      p.parent_path() / ("." + p.filename().string() + ".tmp" + std::to_string(::getpid()));
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << content;
    out.close();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw Error(Status::io, "cannot write '" + path + "'");
    }
  }
  fs::rename(tmp, p);
}

namespace {
volatile std::sig_atomic_t g_signal = 0;
constexpr int kSignals[2] = {SIGINT, SIGTERM};
void on_signal(int signal) {
  g_signal = signal;
  std::signal(signal, SIG_DFL);
}
}  // namespace

InterruptGuard::InterruptGuard() {
  g_signal = 0;
  for (int i = 0; i < 2; ++i) {
    previous_[i] = std::signal(kSignals[i], on_signal);
    if (previous_[i] == SIG_IGN) std::signal(kSignals[i], SIG_IGN);
  }
}

InterruptGuard::~InterruptGuard() {
  for (int i = 0; i < 2; ++i)
    std::signal(kSignals[i], previous_[i] == SIG_ERR ? SIG_DFL : previous_[i]);
}

int InterruptGuard::signal() const {
  return g_signal;
}

}  // namespace ivr::cli
