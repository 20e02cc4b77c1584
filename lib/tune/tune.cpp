// tune.cpp — the work-group tuner: each kernel's candidate shapes timed on the benchmark scene
// through the launch layer's probe (lib/runtime/launch.hpp), their outputs compared, a winner
// picked.
#include "ivr/tune.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>

#include "ivr/calibrate.hpp"
#include "ivr/core.hpp"
#include "ivr/error.hpp"
#include "ivr/session.hpp"
#include "runtime/device_params.hpp"
#include "runtime/launch.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

namespace {

[[noreturn]] void bad(const std::string& what) {
  throw Error(Status::invalid_argument, "tune: " + what);
}

std::string shape_name(int x, int y) {
  return std::to_string(x) + "x" + std::to_string(y);
}

// One output of an operation: exact ones must match bit for bit across shapes, scattered sums
// (float atomics add in an order the shape changes) to 1e-4 of their largest magnitude.
struct Output {
  const char* name;
  DeviceArray array;
  bool exact;
};
struct Values {
  std::string name;
  std::vector<double> values;
  bool exact;
};

// What launches a tuning name: an operation on the session (the tuner's representative scene).
struct Operation {
  const char* kernel;
  const char* description;
  bool packet;  // false: renders keep off the CPU packet kernel
  const char* check;
  std::function<std::vector<Output>(Session&)> run;
};

// The scene rendered in 8 bricks (lib/brick/): the out-of-core sweeps' kernels. The image is the
// host's, wrapped for the comparison (kept until the next call).
std::vector<Output> render_in_bricks(Session& s, const Scene& scene, double step) {
  static thread_local std::vector<float> pixels;
  RenderOptions o;
  o.step = step;
  o.volume_brick = std::max({scene.volume.nx, scene.volume.ny, scene.volume.nz, 2}) / 2;
  Image image = render(s.device(), scene, o);
  pixels = std::move(image.pixels);
  const DeviceArray a =
      DeviceArray::wrap(s.device(), pixels.data(),
                        {image.views, image.height, image.width, image.channels}, DType::f32);
  return {{"image", a, true}};
}

std::vector<Operation> operations(const DeviceArray& lines, const Scene& scene, double step) {
  GradientRequest adjoint;
  adjoint.mode = Mode::adjoint;
  const auto render = [](Session& s) { return std::vector<Output>{{"image", s.render(), true}}; };
  const auto gradient = [adjoint](Session& s) {
    const SessionGradient g = s.gradient(adjoint);
    return std::vector<Output>{{"loss", g.loss, true}, {"density gradient", g["density"], false}};
  };
  const char* gradient_check =
      "loss bit-identical, density gradient within 1e-4 of its largest value";
  return {
      {"render", "render (one ray per work-item)", false, "image bit-identical", render},
      {"render_packet", "render (CPU packet kernel, 16 rays per work-item)", true,
       "image bit-identical", render},
      {"adjoint", "gradient (adjoint mode, d mse / d density, one ray per work-item)", false,
       gradient_check, gradient},
      {"adjoint_packet", "gradient (adjoint mode, CPU packet kernel, 16 rays per work-item)", true,
       gradient_check, gradient},
      {"jacobian", "jacobian (forward mode, every TF parameter, one ray per work-item)", false,
       "jacobian bit-identical",
       [](Session& s) {
         return std::vector<Output>{{"jacobian", s.jacobian({"tf"}), true}};
       }},
      {"jacobian_packet", "jacobian (forward mode, every TF parameter, CPU packet kernel)", true,
       "jacobian bit-identical",
       [](Session& s) {
         return std::vector<Output>{{"jacobian", s.jacobian({"tf"}), true}};
       }},
      {"project", "project (line integrals of the densities)", true, "lines bit-identical",
       [](Session& s) {
         return std::vector<Output>{{"lines", s.project(), true}};
       }},
      {"backproject", "backproject (the lines onto the grid)", true,
       "volume within 1e-4 of its largest value",
       [lines](Session& s) {
         return std::vector<Output>{{"volume", s.backproject(lines), false}};
       }},
      {"bricked", "render in 8 bricks (out of core, one ray per work-item)", false,
       "image bit-identical",
       [&scene, step](Session& s) { return render_in_bricks(s, scene, step); }},
      {"bricked_packet", "render in 8 bricks (out of core, CPU packet kernel)", true,
       "image bit-identical",
       [&scene, step](Session& s) { return render_in_bricks(s, scene, step); }},
  };
}

std::vector<Values> read(const std::vector<Output>& outputs) {
  std::vector<Values> out;
  for (const Output& o : outputs) out.push_back({o.name, o.array.to_doubles(), o.exact});
  return out;
}

// Enough digits to tell two doubles apart.
std::string exact_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

// Throws when `got` (from shape `shape`) is not the reference's output (from `ref_shape`).
void compare(const std::string& kernel, const std::vector<Values>& ref,
             const std::string& ref_shape, const std::vector<Values>& got,
             const std::string& shape) {
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const std::vector<double>& a = ref[i].values;
    const std::vector<double>& b = got[i].values;
    const std::string what =
        "tune: " + kernel + "'s " + ref[i].name + " differs between " + ref_shape + " and " + shape;
    if (a.size() != b.size()) throw Error(Status::opencl, what + " in size");
    std::size_t at = a.size();
    if (ref[i].exact) {
      for (std::size_t k = 0; k < a.size() && at == a.size(); ++k)
        if (std::memcmp(&a[k], &b[k], sizeof(double)) != 0) at = k;
    } else {
      double largest = 0, worst = 0;
      std::size_t worst_at = 0;
      for (std::size_t k = 0; k < a.size(); ++k) {
        largest = std::max(largest, std::abs(a[k]));
        if (std::abs(a[k] - b[k]) > worst) {
          worst = std::abs(a[k] - b[k]);
          worst_at = k;
        }
      }
      if (!(worst <= 1e-4 * largest)) at = worst_at;
    }
    if (at == a.size()) continue;
    throw Error(Status::opencl,
                what + " (element " + std::to_string(at) + ": " + exact_text(a[at]) + " against " +
                    exact_text(b[at]) +
                    (ref[i].exact ? ", bit-identical expected" : ", beyond 1e-4 of the largest") +
                    "): the output depends on the work-group shape");
  }
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

Scene tuning_scene(const TuneOptions& o) {
  Scene scene = calibration_scene(o.volume, o.image);
  const Camera first = scene.cameras.front();
  for (int k = 1; k < o.views; ++k) {  // the others around z at the first one's height
    const double a = 2 * M_PI * k / o.views;
    Camera c = first;
    c.eye = {first.eye.x * std::cos(a) - first.eye.y * std::sin(a),
             first.eye.x * std::sin(a) + first.eye.y * std::cos(a), first.eye.z};
    scene.cameras.push_back(c);
  }
  return scene;
}

void validate(const TuneOptions& o) {
  if (o.volume < 8 || o.volume > 1024) bad("the volume edge must be in 8..1024");
  if (o.image < 8 || o.image > 8192) bad("the image edge must be in 8..8192");
  if (o.views < 1 || o.views > 360) bad("the views must be in 1..360");
  if (!(o.step > 0) || o.step > 16) bad("the step must be in (0, 16] voxels");
  if (o.repeats < 1 || o.repeats > 1000) bad("the repeats must be in 1..1000");
  if (!(o.tie >= 0) || o.tie >= 1) bad("the tie fraction must be in [0, 1)");
  const std::vector<std::string> known = tune_kernels();
  for (const std::string& k : o.kernels)
    if (std::find(known.begin(), known.end(), k) == known.end()) {
      std::string names;
      for (const std::string& n : known) names += (names.empty() ? "" : ", ") + n;
      bad("unknown kernel '" + k + "' (known: " + names + ")");
    }
  for (const auto& [x, y] : o.candidates)
    if (x < 0 || y < 0 || (x == 0) != (y == 0) || double(x) * y > 65536)
      bad("the candidate " + shape_name(x, y) +
          " is no work-group shape (0x0 or positive sizes, at most 65536 work-items)");
  if (const char* env = std::getenv("IVR_LOCAL_SIZE"); env && *env)
    bad("unset IVR_LOCAL_SIZE: it overrides the database the tuner measures against");
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

// Device time of the launches of `kernel` the probe recorded (waits for each).
double kernel_seconds(const TuningProbe& probe, const std::string& kernel) {
  double total = 0;
  for (const TuningProbe::Launch& l : probe.launches)
    if (l.shape.tuning == kernel) {
      l.event.wait();
      total += event_seconds(l.event);
    }
  return total;
}

// Why `shape` cannot run here, or "".
std::string limit_of(const KernelTuning& k, const std::vector<std::size_t>& item_sizes,
                     std::size_t device_max, int x, int y) {
  if (x == 0) return k.needs_group ? "the kernel needs an explicit work-group" : "";
  const std::size_t items = std::size_t(x) * std::size_t(y);
  if (items > k.kernel_max_group)
    return "beyond the kernel's limit of " + std::to_string(k.kernel_max_group) + " work-items";
  if (items > device_max)
    return "beyond the device's limit of " + std::to_string(device_max) + " work-items";
  if (item_sizes.size() >= 2 && (std::size_t(x) > item_sizes[0] || std::size_t(y) > item_sizes[1]))
    return "beyond the device's work-item sizes " + std::to_string(item_sizes[0]) + "x" +
           std::to_string(item_sizes[1]);
  return "";
}

void tune_kernel(Session& session, const Operation& op, const TuneOptions& o,
                 const std::vector<std::size_t>& item_sizes, std::size_t device_max,
                 KernelTuning& k) {
  TuningProbe probe;
  probe.packet = op.packet;
  ScopedTuningProbe scope(probe);
  // What the database launches now, and whether the operation launches this kernel at all.
  op.run(session);
  session.finish();
  const auto launched =
      std::find_if(probe.launches.begin(), probe.launches.end(),
                   [&](const TuningProbe::Launch& l) { return l.shape.tuning == op.kernel; });
  if (launched == probe.launches.end()) {
    k.skipped = std::string("not launched on this device (") + session.device().info().type +
                "): " + op.description + " takes another kernel";
    return;
  }
  k.needs_group = launched->shape.needs_group;
  k.kernel_max_group = launched->shape.kernel_max_group;
  k.current_x = launched->shape.group_x;
  k.current_y = launched->shape.group_y;
  k.current_source = launch_params(session.device().info(), op.kernel).source;

  std::vector<std::pair<int, int>> shapes = o.candidates.empty() ? tune_candidates() : o.candidates;
  if (std::find(shapes.begin(), shapes.end(), std::pair(k.current_x, k.current_y)) == shapes.end())
    shapes.push_back({k.current_x, k.current_y});
  std::string first_error;
  // A launch the driver refuses (resources, say) makes the candidate a skipped one; a difference
  // in the outputs stops the tuner.
  const auto attempt = [&](TuneCandidate& c, const std::function<void()>& f) {
    probe.kernel = op.kernel;
    probe.local_x = c.local_x;
    probe.local_y = c.local_y;
    try {
      f();
    } catch (const Error& e) {
      if (e.status() != Status::opencl && e.status() != Status::out_of_memory) throw;
      c.seconds.clear();
      c.skipped = std::string("failed: ") + e.what();
      if (first_error.empty()) first_error = e.what();
    }
  };
  // Warm-up runs: each compiles what its shape needs (PoCL builds a work-group function per local
  // size) and gives the outputs to compare.
  std::vector<Values> reference;
  std::string reference_shape;
  for (const auto& [x, y] : shapes) {
    TuneCandidate c;
    c.local_x = x;
    c.local_y = y;
    c.skipped = limit_of(k, item_sizes, device_max, x, y);
    std::vector<Values> out;
    if (c.skipped.empty()) attempt(c, [&] { out = read(op.run(session)); });
    if (c.skipped.empty() && reference_shape.empty()) {
      reference = out;
      reference_shape = shape_name(x, y);
    } else if (c.skipped.empty()) {
      compare(op.kernel, reference, reference_shape, out, shape_name(x, y));
    }
    k.candidates.push_back(c);
  }
  // Timed rounds, every candidate once in each, so that a load that comes and goes on a shared
  // machine falls on all of them alike.
  for (int r = 0; r < o.repeats; ++r)
    for (TuneCandidate& c : k.candidates)
      if (c.skipped.empty())
        attempt(c, [&] {
          probe.launches.clear();
          op.run(session);
          session.finish();
          c.seconds.push_back(kernel_seconds(probe, op.kernel));
        });
  for (TuneCandidate& c : k.candidates) {
    if (c.skipped.empty()) {
      c.median_seconds = median(c.seconds);
      c.min_seconds = *std::min_element(c.seconds.begin(), c.seconds.end());
      c.score_seconds = o.statistic == TuneStatistic::minimum ? c.min_seconds : c.median_seconds;
    }
    if (o.progress) o.progress(k.kernel, c);
  }
  int current = -1;
  for (std::size_t i = 0; i < k.candidates.size(); ++i) {
    const TuneCandidate& c = k.candidates[i];
    if (!c.skipped.empty()) continue;
    if (k.fastest < 0 || c.score_seconds < k.candidates[std::size_t(k.fastest)].score_seconds)
      k.fastest = int(i);
    if (c.local_x == k.current_x && c.local_y == k.current_y) current = int(i);
  }
  if (k.fastest < 0) {
    k.failed = true;
    k.skipped = "no candidate ran" + (first_error.empty() ? "" : ": " + first_error);
    return;
  }
  const double best = k.candidates[std::size_t(k.fastest)].score_seconds;
  k.winner = current >= 0 && k.candidates[std::size_t(current)].score_seconds <= best * (1 + o.tie)
                 ? current
                 : k.fastest;
}

}  // namespace

std::vector<std::pair<int, int>> tune_candidates() {
  // The small shapes are for the packet kernels, whose work-items are tiles of 16 pixels.
  return {{0, 0},  {1, 1},  {2, 2},  {4, 4},  {8, 8},   {16, 8}, {16, 16},
          {32, 4}, {32, 8}, {64, 1}, {64, 4}, {128, 1}, {256, 1}};
}

std::vector<std::string> tune_kernels() {
  return {"render",          "render_packet", "adjoint",     "adjoint_packet", "jacobian",
          "jacobian_packet", "project",       "backproject", "bricked",        "bricked_packet"};
}

TuneResult tune(Device& device, const TuneOptions& options) {
  validate(options);
  TuneResult result;
  result.device = device.info();
  result.options = options;
  result.date = utc_now();
  const Scene scene = tuning_scene(options);
  SessionOptions so;
  so.step = options.step;
  so.empty_space = EmptySpace::off;  // the kernels' plain variants: what the database shapes
  Session session(device, scene, so);
  const std::vector<std::int64_t> shape = session.image_shape();
  Image target{int(shape[0]), int(shape[1]), int(shape[2]), int(shape[3]), {}};
  target.pixels.assign(std::size_t(shape[0] * shape[1] * shape[2] * shape[3]), 0.25f);
  session.set_target(target);  // not the render itself, so that the gradient is not zero
  const DeviceArray lines = session.project();
  lines.wait();

  Device::Impl& dev = device.impl();
  const auto item_sizes = cl_call("querying the device's work-item sizes", [&] {
    return dev.device.getInfo<CL_DEVICE_MAX_WORK_ITEM_SIZES>();
  });
  const std::size_t device_max = cl_call("querying the device's work-group limit", [&] {
    return dev.device.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>();
  });
  for (const Operation& op : operations(lines, scene, options.step)) {
    if (!options.kernels.empty() && std::find(options.kernels.begin(), options.kernels.end(),
                                              op.kernel) == options.kernels.end())
      continue;
    KernelTuning k;
    k.kernel = op.kernel;
    k.operation = op.description;
    k.check = op.check;
    tune_kernel(session, op, options, item_sizes, device_max, k);
    result.kernels.push_back(std::move(k));
  }
  return result;
}

}  // namespace ivr
