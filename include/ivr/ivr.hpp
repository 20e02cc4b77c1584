// ivr/ivr.hpp — the C++ API: a header-only RAII layer over the C API (ivr/ivr.h), so only C types
// cross the library boundary. Errors throw ivr::api::Exception with the status and the message.
// Its namespace is ivr::api so that it never meets the core C++ types of ivr/core.hpp.
#pragma once
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "ivr/ivr.h"

namespace ivr::api {

// A failed call: the C status, the message (file, OpenCL call, build log) and the OpenCL code
// behind an IVR_ERROR_OPENCL (else 0).
class Exception : public std::runtime_error {
 public:
  Exception(ivr_status status, const std::string& message, int opencl_code = 0)
      : std::runtime_error(message), status_(status), opencl_code_(opencl_code) {}
  ivr_status status() const noexcept { return status_; }
  int opencl_code() const noexcept { return opencl_code_; }

 private:
  ivr_status status_;
  int opencl_code_;
};

namespace detail {
inline void check(ivr_status status) {
  if (status == IVR_OK) return;
  throw Exception(status, std::string(ivr_status_string(status)) + ": " + ivr_last_error(),
                  ivr_last_opencl_error());
}

// Shared ownership of one C handle through the C API's own reference count.
template <typename T, ivr_status (*Retain)(T*), ivr_status (*Release)(T*)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(T* adopted) noexcept : handle_(adopted) {}
  Handle(const Handle& other) : handle_(other.handle_) {
    if (handle_) check(Retain(handle_));
  }
  Handle(Handle&& other) noexcept : handle_(std::exchange(other.handle_, nullptr)) {}
  Handle& operator=(Handle other) noexcept {
    std::swap(handle_, other.handle_);
    return *this;
  }
  ~Handle() {
    if (handle_) Release(handle_);
  }
  T* get() const noexcept { return handle_; }
  explicit operator bool() const noexcept { return handle_ != nullptr; }

 protected:
  T* handle_ = nullptr;
};

inline size_t product(const std::vector<int64_t>& shape) {
  size_t n = 1;
  for (int64_t d : shape) n *= size_t(d);
  return n;
}
}  // namespace detail

enum class Precision { f32 = IVR_PRECISION_F32, f64 = IVR_PRECISION_F64 };
enum class Mode {
  automatic = IVR_MODE_AUTO,
  forward = IVR_MODE_FORWARD,
  adjoint = IVR_MODE_ADJOINT
};
enum class Loss { mse = IVR_LOSS_MSE, l1 = IVR_LOSS_L1, dot = IVR_LOSS_DOT };

inline int version() {
  return ivr_version();
}

// A dense float array with its shape (C order).
template <typename T>
struct Array {
  std::vector<int64_t> shape;
  std::vector<T> values;
  size_t size() const { return values.size(); }
};

// One named array of a gradient or Jacobian (e.g. "density", "tf", "jacobian").
struct NamedArray {
  std::string name;
  Array<double> array;
};

// A gradient or Jacobian: the loss, the mode that ran, kernel seconds and the arrays by name.
class Result : public detail::Handle<ivr_result, ivr_result_retain, ivr_result_release> {
 public:
  using Handle::Handle;
  double loss() const { return info().loss; }
  Mode mode() const { return info().mode; }
  double seconds() const { return info().seconds; }
  std::vector<NamedArray> arrays() const {
    size_t count = 0;
    detail::check(ivr_result_array_count(get(), &count));
    std::vector<NamedArray> out;
    for (size_t i = 0; i < count; ++i) out.push_back(array_at(i));
    return out;
  }
  // The array called `name`; throws ivr::api::Exception (IVR_ERROR_INVALID_ARGUMENT) if none is.
  Array<double> array(const std::string& name) const {
    for (NamedArray& a : arrays())
      if (a.name == name) return std::move(a.array);
    throw Exception(IVR_ERROR_INVALID_ARGUMENT, "the result has no array named '" + name + "'");
  }

 private:
  struct Info {
    double loss;
    Mode mode;
    double seconds;
  };
  Info info() const {
    Info i{};
    ivr_mode mode = IVR_MODE_AUTO;
    detail::check(ivr_result_info(get(), &i.loss, &mode, &i.seconds));
    i.mode = Mode(mode);
    return i;
  }
  NamedArray array_at(size_t index) const {
    const char* name = nullptr;
    int rank = 0;
    int64_t shape[5] = {};
    detail::check(ivr_result_array_shape(get(), index, &name, &rank, shape));
    NamedArray a{name, {std::vector<int64_t>(shape, shape + rank), {}}};
    a.array.values.resize(detail::product(a.array.shape));
    detail::check(ivr_result_array_data(get(), index, a.array.values.data(), a.array.size()));
    return a;
  }
};

// Densities (nz, ny, nx) with their spacing; set on scenes of its context by copy.
class Volume : public detail::Handle<ivr_volume, ivr_volume_retain, ivr_volume_release> {
 public:
  using Handle::Handle;
  std::vector<int64_t> shape() const {
    std::vector<int64_t> shape(3);
    detail::check(ivr_volume_shape(get(), shape.data()));
    return shape;
  }
  // The densities as float32, x fastest.
  Array<float> data() const {
    Array<float> a{shape(), {}};
    a.values.resize(detail::product(a.shape));
    detail::check(ivr_volume_data(get(), a.values.data(), a.size()));
    return a;
  }
};

// A transfer function (docs/design.md's "tf" object); set on scenes of its context by copy.
class TransferFunction
    : public detail::Handle<ivr_transfer_function, ivr_tf_retain, ivr_tf_release> {
 public:
  using Handle::Handle;
};

// A scene (docs/design.md's JSON) with its volume; belongs to the context that made it.
class Scene : public detail::Handle<ivr_scene, ivr_scene_retain, ivr_scene_release> {
 public:
  using Handle::Handle;
  // Replaces the volume by a copy of `data`, shape {nz, ny, nx}, x fastest.
  void set_volume(const float* data, const std::vector<int64_t>& shape) {
    set_volume(data, IVR_FLOAT32, shape);
  }
  void set_volume(const std::vector<float>& data, const std::vector<int64_t>& shape) {
    if (shape.size() != 3 || data.size() != detail::product(shape))
      throw Exception(IVR_ERROR_INVALID_ARGUMENT,
                      "set_volume: " + std::to_string(data.size()) +
                          " values do not fill a volume of the given 3-d shape");
    set_volume(data.data(), IVR_FLOAT32, shape);
  }
  void set_volume(const void* data, ivr_dtype dtype, const std::vector<int64_t>& shape) {
    if (shape.size() != 3)
      throw Exception(IVR_ERROR_INVALID_ARGUMENT, "set_volume: shape has " +
                                                      std::to_string(shape.size()) +
                                                      " dimensions (nz, ny, nx expected)");
    detail::check(ivr_scene_set_volume(get(), data, dtype, shape.data()));
  }
  // Copies a volume or transfer function of the same context into the scene.
  void set_volume(const Volume& volume) {
    detail::check(ivr_scene_set_volume_handle(get(), volume.get()));
  }
  void set_tf(const TransferFunction& tf) { detail::check(ivr_scene_set_tf(get(), tf.get())); }
  // (views, height, width, channels)
  std::vector<int64_t> image_shape() const {
    std::vector<int64_t> shape(4);
    detail::check(ivr_scene_image_shape(get(), shape.data()));
    return shape;
  }
  // (nz, ny, nx)
  std::vector<int64_t> volume_shape() const {
    std::vector<int64_t> shape(3);
    detail::check(ivr_scene_volume_shape(get(), shape.data()));
    return shape;
  }
};

// What render, gradient and jacobian accept beyond the scene.
struct Options {
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step (voxel units)
};
struct GradientOptions : Options {
  std::string wrt = "density";  // comma-separated groups, as `ivr gradient --wrt`
  Mode mode = Mode::automatic;
  Loss loss = Loss::mse;
  // The density gradient in fixed point (ivr_gradient_shared, ivr_gradient_split_deterministic).
  bool deterministic = false;
};

// What Context::tomo solves: ivr_tomo_options (its fields are documented in ivr.h) filled with
// the library's defaults.
struct TomoOptions : ivr_tomo_options {
  TomoOptions() : ivr_tomo_options() { detail::check(ivr_tomo_options_init(this)); }
};
// Called after every iteration (number, relative residual, seconds); return false to stop.
using TomoProgress = std::function<bool(const ivr_tomo_iteration&)>;
struct TomoResult {
  Array<float> volume;                      // the last iterate, (nz, ny, nx)
  std::vector<ivr_tomo_iteration> history;  // one entry per completed iteration
  std::string stop_reason;  // "iterations", "tolerance", "converged" or "interrupted"
  double residual = 0, seconds = 0, setup_seconds = 0;
};

namespace detail {
// Carries a C++ progress function through the C callback; an exception it throws stops the
// solver and is rethrown once ivr_tomo has returned (none may cross the C boundary).
struct Progress {
  const TomoProgress* function;
  std::exception_ptr error;
  static int call(const ivr_tomo_iteration* it, void* user) {
    auto* self = static_cast<Progress*>(user);
    try {
      return (*self->function)(*it) ? 1 : 0;
    } catch (...) {
      self->error = std::current_exception();
      return 0;
    }
  }
};
// Carries a C++ sum over the workers through ivr_sum_fn; an exception it throws fails the call
// and is rethrown once the library has returned.
struct Sum {
  const std::function<void(double*, size_t)>* function;
  std::exception_ptr error;
  static int call(double* values, size_t count, void* user) {
    auto* self = static_cast<Sum*>(user);
    try {
      (*self->function)(values, count);
      return 1;
    } catch (...) {
      self->error = std::current_exception();
      return 0;
    }
  }
};
}  // namespace detail

// This process's part of a split operation (docs/scaling.md): worker `rank` of `ranks`, sharing
// the views or the slabs of the volume; `sum` replaces `count` doubles by their sum over the
// workers (an MPI_Allreduce), every worker calling it together.
struct Workers {
  ivr_split split = IVR_SPLIT_VIEWS;
  int rank = 0, ranks = 1;
  std::function<void(double* values, size_t count)> sum;
  // Each worker's weight (`ranks` of them, each > 0, the same on every worker; a device's speed,
  // Context::samples_per_second): over views its share of the views in proportion
  // (ivr_view_shares), over slabs its share of the planes (ivr_domain_slab_weighted); empty:
  // equal shares.
  std::vector<double> shares{};
  const double* shares_or_null() const { return shares.empty() ? nullptr : shares.data(); }
};

// A device with its queue and kernel cache. One context serves one thread at a time; separate
// contexts work concurrently on separate threads.
class Context : public detail::Handle<ivr_context, ivr_context_retain, ivr_context_release> {
 public:
  // selector as for `ivr --device` ("" : $IVR_DEVICE, else the first GPU, else the first device)
  explicit Context(const std::string& selector = "") {
    detail::check(ivr_context_create(selector.c_str(), &handle_));
  }
  // Every OpenCL device as JSON ({"devices": [...]}, the fields of `ivr devices --json`).
  static std::string devices_json() {
    size_t needed = 0;
    detail::check(ivr_devices_json(nullptr, 0, &needed));
    std::string text(needed, '\0');
    detail::check(ivr_devices_json(&text[0], text.size(), &needed));
    text.resize(needed - 1);
    return text;
  }
  std::string device_name() const {
    const char* name = nullptr;
    detail::check(ivr_context_device_name(get(), &name));
    return name;
  }
  // A scene from JSON text (relative paths against base_dir) or from a JSON file.
  Scene scene_from_json(const std::string& json, const std::string& base_dir = "") {
    ivr_scene* s = nullptr;
    detail::check(ivr_scene_from_json(get(), json.c_str(),
                                      base_dir.empty() ? nullptr : base_dir.c_str(), &s));
    return Scene(s);
  }
  Scene load_scene(const std::string& path) {
    ivr_scene* s = nullptr;
    detail::check(ivr_scene_load(get(), path.c_str(), &s));
    return Scene(s);
  }
  // A volume from memory (copied, shape {nz, ny, nx}) or from docs/design.md's "volume" object.
  Volume volume(const std::vector<float>& data, const std::vector<int64_t>& shape) {
    if (shape.size() != 3 || data.size() != detail::product(shape))
      throw Exception(IVR_ERROR_INVALID_ARGUMENT,
                      "volume: " + std::to_string(data.size()) +
                          " values do not fill a volume of the given 3-d shape");
    ivr_volume* v = nullptr;
    detail::check(ivr_volume_create(get(), data.data(), IVR_FLOAT32, shape.data(), &v));
    return Volume(v);
  }
  Volume volume_from_json(const std::string& json, const std::string& base_dir = "") {
    ivr_volume* v = nullptr;
    detail::check(ivr_volume_from_json(get(), json.c_str(),
                                       base_dir.empty() ? nullptr : base_dir.c_str(), &v));
    return Volume(v);
  }
  TransferFunction tf_from_json(const std::string& json) {
    ivr_transfer_function* t = nullptr;
    detail::check(ivr_tf_from_json(get(), json.c_str(), &t));
    return TransferFunction(t);
  }
  // The step (voxel units) a render of the scene uses: its own, or the one chosen for its
  // integrator's tolerance; *estimated_error (optional): that step's estimated relative RMS error.
  double step(const Scene& scene, Precision precision = Precision::f32,
              double* estimated_error = nullptr) {
    double s = 0;
    detail::check(
        ivr_scene_step(get(), scene.get(), ivr_precision(precision), &s, estimated_error));
    return s;
  }
  // Every view, shape (views, height, width, channels).
  Array<float> render(const Scene& scene, const Options& options = {}) {
    Array<float> image{scene.image_shape(), {}};
    image.values.resize(detail::product(image.shape));
    detail::check(ivr_render(get(), scene.get(), ivr_precision(options.precision), options.step,
                             image.values.data(), image.size()));
    return image;
  }
  // The loss of the render against `target` (the image shape) and its gradient by group.
  Result gradient(const Scene& scene, const float* target, size_t count,
                  const GradientOptions& options = {}) {
    if (options.deterministic) return gradient_shared(scene, target, count, options, Workers{});
    ivr_result* r = nullptr;
    detail::check(ivr_gradient(get(), scene.get(), target, count, options.wrt.c_str(),
                               ivr_mode(options.mode), ivr_loss(options.loss),
                               ivr_precision(options.precision), options.step, &r));
    return Result(r);
  }
  // Data-parallel over views (ivr_gradient_shared_weighted; `views.split` is not read): worker
  // views.rank of views.ranks differentiates its share of the whole scene's views, every worker
  // calling together; every worker gets the whole loss and gradient (with options.deterministic
  // the density gradient is one process's bit for bit).
  Result gradient_shared(const Scene& scene, const float* target, size_t count,
                         const GradientOptions& options, const Workers& views) {
    ivr_result* r = nullptr;
    detail::Sum sum{&views.sum, nullptr};
    const ivr_status status = ivr_gradient_shared_weighted(
        get(), scene.get(), target, count, options.wrt.c_str(), ivr_mode(options.mode),
        ivr_loss(options.loss), ivr_precision(options.precision), options.step,
        options.deterministic ? 1 : 0, views.rank, views.ranks,
        views.shares.empty() ? nullptr : views.shares.data(),
        views.sum ? &detail::Sum::call : nullptr, &sum, &r);
    if (sum.error) std::rethrow_exception(sum.error);
    detail::check(status);
    return Result(r);
  }
  Result gradient(const Scene& scene, const std::vector<float>& target,
                  const GradientOptions& options = {}) {
    return gradient(scene, target.data(), target.size(), options);
  }
  // Over slabs (ivr_render_split, ivr_gradient_split): worker slabs.rank of slabs.ranks marches
  // only its slab of the scene's volume (cut by slabs.shares), every worker calling together; the
  // image is the whole render, the gradient (density, tf) this worker's parts. slabs.split
  // IVR_SPLIT_SEGMENTS marches each ray's segments independently; any other value passes the
  // rays' march states. options.deterministic: the density in fixed point
  // (ivr_gradient_split_deterministic: over states the parts add up to one process's bits).
  Array<float> render(const Scene& scene, const Options& options, const Workers& slabs) {
    Array<float> image{scene.image_shape(), {}};
    image.values.resize(detail::product(image.shape));
    detail::Sum sum{&slabs.sum, nullptr};
    const ivr_status status = ivr_render_split_weighted(
        get(), scene.get(), ivr_precision(options.precision), options.step, slab_march(slabs),
        slabs.rank, slabs.ranks, slabs.shares_or_null(), slabs.sum ? &detail::Sum::call : nullptr,
        &sum, image.values.data(), image.size());
    if (sum.error) std::rethrow_exception(sum.error);
    detail::check(status);
    return image;
  }
  Result gradient(const Scene& scene, const std::vector<float>& target,
                  const GradientOptions& options, const Workers& slabs) {
    ivr_result* r = nullptr;
    detail::Sum sum{&slabs.sum, nullptr};
    const ivr_status status = ivr_gradient_split_deterministic(
        get(), scene.get(), target.data(), target.size(), options.wrt.c_str(),
        ivr_loss(options.loss), ivr_precision(options.precision), options.step, slab_march(slabs),
        options.deterministic ? 1 : 0, slabs.rank, slabs.ranks, slabs.shares_or_null(),
        slabs.sum ? &detail::Sum::call : nullptr, &sum, &r);
    if (sum.error) std::rethrow_exception(sum.error);
    detail::check(status);
    return Result(r);
  }
  // The Jacobian (views, H, W, C, P) of the render with respect to `wrt`, in result "jacobian".
  Result jacobian(const Scene& scene, const std::string& wrt, const Options& options = {}) {
    ivr_result* r = nullptr;
    detail::check(ivr_jacobian(get(), scene.get(), wrt.c_str(), ivr_precision(options.precision),
                               options.step, &r));
    return Result(r);
  }
  // Absorption tomography (ivr_project …): line integrals (views, H, W, 1) of the scene's
  // volume, or of `volume` (the grid's nz * ny * nx values), along every camera ray.
  Array<float> project(const Scene& scene, Precision precision = Precision::f32) {
    return project(scene, nullptr, 0, precision);
  }
  Array<float> project(const Scene& scene, const std::vector<float>& volume,
                       Precision precision = Precision::f32) {
    return project(scene, volume.data(), volume.size(), precision);
  }
  // N^T p onto the scene's grid, (nz, ny, nx); `lines` has views * H * W values.
  Array<float> backproject(const Scene& scene, const std::vector<float>& lines,
                           Precision precision = Precision::f32) {
    Array<float> volume{scene.volume_shape(), {}};
    volume.values.resize(detail::product(volume.shape));
    detail::check(ivr_backproject(get(), scene.get(), ivr_precision(precision), lines.data(),
                                  lines.size(), volume.values.data(), volume.size()));
    return volume;
  }
  // Reconstructs the scene's grid from line integrals (views * H * W values). With `workers`
  // (ivr_tomo_split_weighted): this worker's share of the views and their lines (the whole grid
  // out), or over slabs the whole scene's lines and this worker's planes (planes, ny, nx; cut by
  // workers->shares) out.
  TomoResult tomo(const Scene& scene, const std::vector<float>& lines,
                  const TomoOptions& options = {}, const TomoProgress& progress = {},
                  const Workers* workers = nullptr) {
    const ivr_tomo_options& o = options;
    TomoResult r;
    r.volume.shape = scene.volume_shape();
    const bool slabs = workers && workers->split == IVR_SPLIT_SLABS;
    if (slabs) {
      int first = 0, last = 0;
      detail::check(ivr_domain_slab_weighted(int(r.volume.shape[0]), workers->rank, workers->ranks,
                                             workers->shares_or_null(), &first, &last));
      r.volume.shape[0] = last - first + 1;
    }
    r.volume.values.resize(detail::product(r.volume.shape));
    r.history.resize(size_t(options.iterations > 0 ? options.iterations : 0));
    detail::Progress state{&progress, nullptr};
    ivr_tomo_summary summary{};
    ivr_tomo_iteration* history = r.history.empty() ? nullptr : r.history.data();
    ivr_tomo_progress call = progress ? &detail::Progress::call : nullptr;
    detail::Sum sum{workers ? &workers->sum : nullptr, nullptr};
    const ivr_status status =
        workers ? ivr_tomo_split_weighted(
                      get(), scene.get(), &o, workers->split, workers->rank, workers->ranks,
                      slabs ? workers->shares_or_null() : nullptr,
                      workers->sum ? &detail::Sum::call : nullptr, &sum, lines.data(),
                      lines.size(), r.volume.values.data(), r.volume.size(), call, &state,
                      history, r.history.size(), &summary)
                : ivr_tomo(get(), scene.get(), &o, lines.data(), lines.size(),
                           r.volume.values.data(), r.volume.size(), call, &state, history,
                           r.history.size(), &summary);
    if (state.error) std::rethrow_exception(state.error);
    if (sum.error) std::rethrow_exception(sum.error);
    detail::check(status);
    r.history.resize(size_t(summary.iterations));
    r.stop_reason = summary.stop_reason;
    r.residual = summary.residual;
    r.seconds = summary.seconds;
    r.setup_seconds = summary.setup_seconds;
    return r;
  }

 private:
  static ivr_split slab_march(const Workers& slabs) {
    return slabs.split == IVR_SPLIT_SEGMENTS ? IVR_SPLIT_SEGMENTS : IVR_SPLIT_SLABS;
  }
  Array<float> project(const Scene& scene, const float* volume, size_t count, Precision precision) {
    std::vector<int64_t> shape = scene.image_shape();
    shape[3] = 1;
    Array<float> lines{shape, std::vector<float>(detail::product(shape))};
    detail::check(ivr_project(get(), scene.get(), ivr_precision(precision), volume, count,
                              lines.values.data(), lines.size()));
    return lines;
  }
};

// Line integrals (views, H, W, 1) from intensities of the scene's image shape:
// p = -log(I / I_in) / a (ivr_lines_from_intensities); clamp in (0, 1) raises I to clamp * I_in.
inline Array<float> lines_from_intensities(const Scene& scene,
                                           const std::vector<float>& intensities,
                                           double clamp = 0) {
  std::vector<int64_t> shape = scene.image_shape();
  shape[3] = 1;
  Array<float> lines{shape, std::vector<float>(detail::product(shape))};
  detail::check(ivr_lines_from_intensities(scene.get(), intensities.data(), intensities.size(),
                                           clamp, lines.values.data(), lines.size()));
  return lines;
}

// A tomography test volume (n, n, n): "shepp-logan" or "ellipsoids" (random, from `seed`);
// supersample s > 1: each voxel the mean of s³ sub-cell samples.
inline Array<float> phantom(const std::string& name, int n, uint64_t seed = 1,
                            int supersample = 1) {
  if (n < 1 || n > 1024)
    throw Exception(IVR_ERROR_INVALID_ARGUMENT,
                    "phantom: n = " + std::to_string(n) + " (1 .. 1024)");
  Array<float> volume{{n, n, n}, std::vector<float>(size_t(n) * size_t(n) * size_t(n))};
  detail::check(
      ivr_phantom(name.c_str(), n, seed, supersample, volume.values.data(), volume.size()));
  return volume;
}

// The loss (mean over every element) of `image` against `target`.
inline double image_loss(const std::vector<float>& image, const std::vector<float>& target,
                         Loss loss = Loss::mse) {
  if (image.size() != target.size())
    throw Exception(IVR_ERROR_INVALID_ARGUMENT,
                    "image_loss: image has " + std::to_string(image.size()) + " values, target " +
                        std::to_string(target.size()));
  double value = 0;
  detail::check(ivr_image_loss(image.data(), target.data(), image.size(), ivr_loss(loss), &value));
  return value;
}

}  // namespace ivr::api

// Reconstruction, viewpoint selection, entropy and PSNR: kept in their own header for size.
#include "ivr/ivr_reconstruct.hpp"
#include "ivr/ivr_session.hpp"
