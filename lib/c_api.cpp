// c_api.cpp — the C API (include/ivr/ivr.h) over the C++ core: handles checked against a registry
// of live objects, every entry point inside one try/catch (IVR_C_BEGIN / IVR_C_END) that turns
// exceptions into a status and a message (per thread and per context).
#include <atomic>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <nlohmann/json.hpp>
#include <string>
#include <unordered_map>
#include <vector>

#include "ivr/ivr.h"
#include "ivr/core.hpp"

// The handle types: each holds its reference count; scenes and results know their context.
struct ivr_context {
  std::atomic<int> references{1};
  ivr::Device device;
  std::string last_error;
  explicit ivr_context(const std::string& selector) : device(selector) {}
};

struct ivr_scene {
  std::atomic<int> references{1};
  ivr_context* context;
  ivr::Scene scene;
  bool explicit_box = false;  // the JSON gave a box: kept when the volume is replaced
  bool has_volume = true;     // false until ivr_scene_set_volume for JSON without "volume"
};

struct ivr_result {
  std::atomic<int> references{1};
  ivr_context* context;
  double loss = 0, seconds = 0;
  ivr_mode mode = IVR_MODE_ADJOINT;
  struct Array {
    std::string name;
    std::vector<int64_t> shape;
    std::vector<double> values;
  };
  std::vector<Array> arrays;
};

namespace {

enum class Kind { context, scene, result };

// Live handles and their types: a released or foreign pointer is found out before use.
std::mutex registry_mutex;
std::unordered_map<const void*, Kind>& registry() {
  static std::unordered_map<const void*, Kind> live;
  return live;
}

void track(const void* p, Kind k) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry()[p] = k;
}
void untrack(const void* p) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry().erase(p);
}
bool is_live(const void* p, Kind k) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  const auto it = registry().find(p);
  return it != registry().end() && it->second == k;
}

thread_local std::string thread_error;
thread_local int thread_opencl_error = 0;

// An error of the C layer itself (bad handle, null pointer, …).
struct CError {
  ivr_status status;
  std::string message;
};

const char* kind_name(Kind k) {
  return k == Kind::context ? "context" : k == Kind::scene ? "scene" : "result";
}

template <class T>
T* checked(T* p, Kind k, const char* what) {
  if (!p) throw CError{IVR_ERROR_NULL_POINTER, std::string(what) + " is NULL"};
  if (!is_live(p, k))
    throw CError{IVR_ERROR_INVALID_HANDLE,
                 std::string(what) + " is not a live ivr_" + kind_name(k) + " (released?)"};
  return p;
}

template <class T>
T* not_null(T* p, const char* what) {
  if (!p) throw CError{IVR_ERROR_NULL_POINTER, std::string(what) + " is NULL"};
  return p;
}

void same_context(const ivr_context* a, const ivr_context* b, const char* what) {
  if (a != b)
    throw CError{IVR_ERROR_WRONG_CONTEXT, std::string(what) + " belongs to another context"};
}

ivr_status status_of(ivr::Status s) {
  return static_cast<ivr_status>(static_cast<int>(s));  // the same numbers 0..7
}

// Records an error for this thread and, when known, for the context.
ivr_status fail(ivr_context* context, ivr_status status, const std::string& message,
                int opencl = 0) {
  thread_error = message;
  thread_opencl_error = opencl;
  if (context && is_live(context, Kind::context)) context->last_error = message;
  return status;
}

template <class F>
ivr_status guarded(ivr_context* context, const char* function, F&& body) {
  try {
    thread_error.clear();
    thread_opencl_error = 0;
    body();
    return IVR_OK;
  } catch (const CError& e) {
    return fail(context, e.status, std::string(function) + ": " + e.message);
  } catch (const ivr::Error& e) {
    return fail(context, status_of(e.status()), std::string(function) + ": " + e.what(),
                e.opencl_code());
  } catch (const std::bad_alloc&) {
    return fail(context, IVR_ERROR_OUT_OF_MEMORY, std::string(function) + ": out of host memory");
  } catch (const std::exception& e) {
    return fail(context, IVR_ERROR_INTERNAL, std::string(function) + ": " + e.what());
  } catch (...) {
    return fail(context, IVR_ERROR_INTERNAL, std::string(function) + ": unknown exception");
  }
}

// The context of a handle, for error reporting, without trusting the handle.
ivr_context* context_of(const ivr_scene* s) {
  return s && is_live(s, Kind::scene) ? s->context : nullptr;
}
ivr_context* context_of(const ivr_result* r) {
  return r && is_live(r, Kind::result) ? r->context : nullptr;
}
ivr_context* context_of(const ivr_context* c) {  // the error record is not the context's state
  return c && is_live(c, Kind::context) ? const_cast<ivr_context*>(c) : nullptr;
}

ivr::Precision precision_of(ivr_precision p) {
  if (p != IVR_PRECISION_F32 && p != IVR_PRECISION_F64)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown precision " + std::to_string(int(p))};
  return p == IVR_PRECISION_F64 ? ivr::Precision::f64 : ivr::Precision::f32;
}

template <class Handle>
ivr_status release(Handle* h, Kind k, const char* function) {
  return guarded(nullptr, function, [&] {
    checked(h, k, "the handle");
    if (h->references.fetch_sub(1) == 1) {
      untrack(h);
      if constexpr (!std::is_same_v<Handle, ivr_context>) ivr_context_release(h->context);
      delete h;
    }
  });
}

template <class Handle>
ivr_status retain(Handle* h, Kind k, const char* function) {
  return guarded(nullptr, function, [&] { checked(h, k, "the handle")->references.fetch_add(1); });
}

// A copy of caller memory as densities: floats as they are, integers mapped to [0, 1].
ivr::Volume volume_from_memory(const void* data, ivr_dtype dtype, const int64_t shape[3]) {
  ivr::Volume v;
  v.nz = int(shape[0]);
  v.ny = int(shape[1]);
  v.nx = int(shape[2]);
  const size_t n = v.voxel_count();
  v.data.resize(n);
  switch (dtype) {
    case IVR_FLOAT32:
      std::memcpy(v.data.data(), data, n * sizeof(float));
      break;
    case IVR_FLOAT64:
      for (size_t i = 0; i < n; ++i) v.data[i] = float(static_cast<const double*>(data)[i]);
      break;
    case IVR_UINT8:
      for (size_t i = 0; i < n; ++i)
        v.data[i] = float(static_cast<const uint8_t*>(data)[i] / 255.0);
      break;
    case IVR_UINT16:
      for (size_t i = 0; i < n; ++i)
        v.data[i] = float(static_cast<const uint16_t*>(data)[i] / 65535.0);
      break;
    default:
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown dtype " + std::to_string(int(dtype)) +
                                                   " (IVR_FLOAT32, IVR_FLOAT64, IVR_UINT8, "
                                                   "IVR_UINT16)"};
  }
  return v;
}

// The scene must have its volume before any march.
const ivr_scene* with_volume(const ivr_scene* s) {
  if (!s->has_volume)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "the scene has no volume: its JSON has none and ivr_scene_set_volume was not "
                 "called"};
  return s;
}

ivr_result* new_result(ivr_context* context) {
  auto* r = new ivr_result();
  r->context = context;
  context->references.fetch_add(1);
  track(r, Kind::result);
  return r;
}

}  // namespace

extern "C" {

const char* ivr_status_string(ivr_status s) {
  switch (s) {
    case IVR_OK:
      return "IVR_OK";
    case IVR_ERROR_INVALID_ARGUMENT:
      return "IVR_ERROR_INVALID_ARGUMENT";
    case IVR_ERROR_IO:
      return "IVR_ERROR_IO";
    case IVR_ERROR_NO_DEVICE:
      return "IVR_ERROR_NO_DEVICE";
    case IVR_ERROR_OPENCL:
      return "IVR_ERROR_OPENCL";
    case IVR_ERROR_BUILD:
      return "IVR_ERROR_BUILD";
    case IVR_ERROR_OUT_OF_MEMORY:
      return "IVR_ERROR_OUT_OF_MEMORY";
    case IVR_ERROR_UNSUPPORTED:
      return "IVR_ERROR_UNSUPPORTED";
    case IVR_ERROR_NULL_POINTER:
      return "IVR_ERROR_NULL_POINTER";
    case IVR_ERROR_INVALID_HANDLE:
      return "IVR_ERROR_INVALID_HANDLE";
    case IVR_ERROR_WRONG_CONTEXT:
      return "IVR_ERROR_WRONG_CONTEXT";
    case IVR_ERROR_BUFFER_TOO_SMALL:
      return "IVR_ERROR_BUFFER_TOO_SMALL";
    case IVR_ERROR_INTERNAL:
      return "IVR_ERROR_INTERNAL";
    case IVR_STATUS_MAX_ENUM:
      break;
  }
  return "IVR_ERROR_UNKNOWN_STATUS";
}

int ivr_version(void) {
  return IVR_VERSION;
}
const char* ivr_last_error(void) {
  return thread_error.c_str();
}
int ivr_last_opencl_error(void) {
  return thread_opencl_error;
}

ivr_status ivr_devices_json(char* buffer, size_t capacity, size_t* needed) {
  return guarded(nullptr, "ivr_devices_json", [&] {
    const std::string text = ivr::devices_json();
    if (needed) *needed = text.size() + 1;
    if (!buffer && capacity == 0) return;
    not_null(buffer, "buffer");
    if (capacity < text.size() + 1)
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "buffer of " + std::to_string(capacity) +
                                                   " bytes; the text needs " +
                                                   std::to_string(text.size() + 1)};
    std::memcpy(buffer, text.c_str(), text.size() + 1);
  });
}

ivr_status ivr_context_create(const char* selector, ivr_context** out) {
  return guarded(nullptr, "ivr_context_create", [&] {
    not_null(out, "context");
    *out = nullptr;
    auto* c = new ivr_context(selector ? selector : "");
    track(c, Kind::context);
    *out = c;
  });
}

ivr_status ivr_context_retain(ivr_context* c) {
  return retain(c, Kind::context, "ivr_context_retain");
}
ivr_status ivr_context_release(ivr_context* c) {
  return release(c, Kind::context, "ivr_context_release");
}

const char* ivr_context_last_error(const ivr_context* c) {
  if (!c || !is_live(c, Kind::context)) return "ivr_context_last_error: not a live ivr_context";
  return c->last_error.c_str();
}

ivr_status ivr_context_device_name(const ivr_context* c, const char** name) {
  return guarded(context_of(c), "ivr_context_device_name", [&] {
    checked(c, Kind::context, "context");
    *not_null(name, "name") = c->device.info().name.c_str();
  });
}

ivr_status ivr_scene_from_json(ivr_context* c, const char* json, const char* base_dir,
                               ivr_scene** out) {
  return guarded(c, "ivr_scene_from_json", [&] {
    checked(c, Kind::context, "context");
    not_null(json, "json");
    not_null(out, "scene");
    *out = nullptr;
    auto s = std::make_unique<ivr_scene>();
    s->context = c;
    // Without "volume" the scene parses with a placeholder until ivr_scene_set_volume.
    nlohmann::json j = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
    std::string text = json;
    if (j.is_object()) {
      s->explicit_box = j.contains("box");
      if (!j.contains("volume")) {
        s->has_volume = false;
        j["volume"] = {{"synthetic", "sphere"}, {"dims", {2, 2, 2}}};
        text = j.dump();
      }
    }
    s->scene = ivr::parse_scene(text, base_dir ? base_dir : ".");
    c->references.fetch_add(1);
    track(s.get(), Kind::scene);
    *out = s.release();
  });
}

ivr_status ivr_scene_load(ivr_context* c, const char* path, ivr_scene** out) {
  return guarded(c, "ivr_scene_load", [&] {
    checked(c, Kind::context, "context");
    not_null(path, "path");
    not_null(out, "scene");
    *out = nullptr;
    auto s = std::make_unique<ivr_scene>();
    s->context = c;
    s->scene = ivr::load_scene(path);
    s->explicit_box = true;
    c->references.fetch_add(1);
    track(s.get(), Kind::scene);
    *out = s.release();
  });
}

ivr_status ivr_scene_retain(ivr_scene* s) {
  return retain(s, Kind::scene, "ivr_scene_retain");
}
ivr_status ivr_scene_release(ivr_scene* s) {
  return release(s, Kind::scene, "ivr_scene_release");
}

ivr_status ivr_scene_set_volume(ivr_scene* s, const void* data, ivr_dtype dtype,
                                const int64_t shape[3]) {
  return guarded(context_of(s), "ivr_scene_set_volume", [&] {
    checked(s, Kind::scene, "scene");
    not_null(data, "data");
    not_null(shape, "shape");
    for (int i = 0; i < 3; ++i)
      if (shape[i] < 1 || shape[i] > (int64_t(1) << 20))
        throw CError{IVR_ERROR_INVALID_ARGUMENT, "shape[" + std::to_string(i) +
                                                     "] = " + std::to_string(shape[i]) +
                                                     " (each dimension 1 .. 2^20)"};
    ivr::Volume v = volume_from_memory(data, dtype, shape);
    v.spacing = s->scene.volume.spacing;
    s->scene.volume = std::move(v);
    s->has_volume = true;
    if (!s->explicit_box) ivr::set_default_box(s->scene);
  });
}

ivr_status ivr_scene_image_shape(const ivr_scene* s, int64_t shape[4]) {
  return guarded(context_of(s), "ivr_scene_image_shape", [&] {
    checked(s, Kind::scene, "scene");
    not_null(shape, "shape");
    const ivr::Camera& c = s->scene.cameras.front();
    shape[0] = int64_t(s->scene.cameras.size());
    shape[1] = c.height;
    shape[2] = c.width;
    shape[3] = s->scene.channels();
  });
}

ivr_status ivr_scene_volume_shape(const ivr_scene* s, int64_t shape[3]) {
  return guarded(context_of(s), "ivr_scene_volume_shape", [&] {
    checked(s, Kind::scene, "scene");
    not_null(shape, "shape");
    shape[0] = s->scene.volume.nz;
    shape[1] = s->scene.volume.ny;
    shape[2] = s->scene.volume.nx;
  });
}

ivr_status ivr_render(ivr_context* c, const ivr_scene* s, ivr_precision precision, double step,
                      float* image, size_t capacity) {
  return guarded(c, "ivr_render", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(image, "image");
    const ivr::Precision p = precision_of(precision);
    const ivr::Image out = ivr::render(c->device, s->scene, ivr::RenderOptions{p, step});
    if (capacity < out.pixels.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "image holds " + std::to_string(capacity) +
                                                   " floats; the render has " +
                                                   std::to_string(out.pixels.size())};
    std::memcpy(image, out.pixels.data(), out.pixels.size() * sizeof(float));
  });
}

ivr_status ivr_gradient(ivr_context* c, const ivr_scene* s, const float* target, size_t count,
                        const char* wrt, ivr_mode mode, ivr_loss loss, ivr_precision precision,
                        double step, ivr_result** out) {
  return guarded(c, "ivr_gradient", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(target, "target");
    not_null(wrt, "wrt");
    not_null(out, "result");
    *out = nullptr;
    if (mode != IVR_MODE_AUTO && mode != IVR_MODE_FORWARD && mode != IVR_MODE_ADJOINT)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown mode " + std::to_string(int(mode))};
    if (loss != IVR_LOSS_MSE && loss != IVR_LOSS_L1)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown loss " + std::to_string(int(loss))};
    const ivr::Camera& cam = s->scene.cameras.front();
    ivr::Image t{int(s->scene.cameras.size()), cam.height, cam.width, s->scene.channels(), {}};
    const size_t want = size_t(t.views) * t.height * t.width * t.channels;
    if (count != want)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "target has " + std::to_string(count) +
                                                   " floats; the scene renders " +
                                                   std::to_string(want)};
    t.pixels.assign(target, target + count);
    ivr::DifferentiateOptions o;
    o.mode = mode == IVR_MODE_FORWARD   ? ivr::Mode::forward
             : mode == IVR_MODE_ADJOINT ? ivr::Mode::adjoint
                                        : ivr::Mode::automatic;
    o.loss = loss == IVR_LOSS_L1 ? ivr::Loss::l1 : ivr::Loss::mse;
    o.precision = precision_of(precision);
    o.step = step;
    const ivr::Differentiation d =
        ivr::differentiate(c->device, s->scene, t, ivr::parse_groups(wrt), o);
    ivr_result* r = new_result(c);
    r->loss = d.loss;
    r->seconds = d.kernel_seconds;
    r->mode = d.plan.mode == ivr::Mode::forward ? IVR_MODE_FORWARD : IVR_MODE_ADJOINT;
    for (const ivr::GroupGradient& g : d.groups)
      r->arrays.push_back({g.name, std::vector<int64_t>(g.shape.begin(), g.shape.end()), g.values});
    *out = r;
  });
}

ivr_status ivr_image_loss(const float* image, const float* target, size_t count, ivr_loss loss,
                          double* value) {
  return guarded(nullptr, "ivr_image_loss", [&] {
    not_null(image, "image");
    not_null(target, "target");
    not_null(value, "value");
    if (count == 0) throw CError{IVR_ERROR_INVALID_ARGUMENT, "count is 0 (no pixels to compare)"};
    if (loss != IVR_LOSS_MSE && loss != IVR_LOSS_L1)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown loss " + std::to_string(int(loss))};
    ivr::Image a{1, 1, int(count), 1, std::vector<float>(image, image + count)};
    ivr::Image b{1, 1, int(count), 1, std::vector<float>(target, target + count)};
    *value = ivr::image_loss(a, b, loss == IVR_LOSS_L1 ? ivr::Loss::l1 : ivr::Loss::mse);
  });
}

ivr_status ivr_jacobian(ivr_context* c, const ivr_scene* s, const char* wrt,
                        ivr_precision precision, double step, ivr_result** out) {
  return guarded(c, "ivr_jacobian", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(wrt, "wrt");
    not_null(out, "result");
    *out = nullptr;
    std::vector<ivr::Parameter> params;
    for (const std::string& g : ivr::parse_groups(wrt))
      for (const ivr::Parameter& p : ivr::parameters_of(s->scene, g)) params.push_back(p);
    ivr::TangentOptions o;
    o.precision = precision_of(precision);
    o.step = step;
    o.jacobian = true;
    const ivr::Tangents t = ivr::tangents(c->device, s->scene, params, nullptr, o);
    ivr_result* r = new_result(c);
    r->seconds = t.kernel_seconds;
    r->mode = IVR_MODE_FORWARD;
    const ivr::Image& im = t.image;
    r->arrays.push_back({"jacobian",
                         {im.views, im.height, im.width, im.channels, int64_t(params.size())},
                         std::vector<double>(t.jacobian.begin(), t.jacobian.end())});
    *out = r;
  });
}

ivr_status ivr_result_retain(ivr_result* r) {
  return retain(r, Kind::result, "ivr_result_retain");
}
ivr_status ivr_result_release(ivr_result* r) {
  return release(r, Kind::result, "ivr_result_release");
}

ivr_status ivr_result_info(const ivr_result* r, double* loss, ivr_mode* mode, double* seconds) {
  return guarded(context_of(r), "ivr_result_info", [&] {
    checked(r, Kind::result, "result");
    if (loss) *loss = r->loss;
    if (mode) *mode = r->mode;
    if (seconds) *seconds = r->seconds;
  });
}

ivr_status ivr_result_array_count(const ivr_result* r, size_t* count) {
  return guarded(context_of(r), "ivr_result_array_count", [&] {
    checked(r, Kind::result, "result");
    *not_null(count, "count") = r->arrays.size();
  });
}

namespace {
const ivr_result::Array& array_at(const ivr_result* r, size_t i) {
  checked(r, Kind::result, "result");
  if (i >= r->arrays.size())
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "array " + std::to_string(i) + " of " + std::to_string(r->arrays.size())};
  return r->arrays[i];
}
}  // namespace

ivr_status ivr_result_array_shape(const ivr_result* r, size_t i, const char** name, int* rank,
                                  int64_t shape[5]) {
  return guarded(context_of(r), "ivr_result_array_shape", [&] {
    const ivr_result::Array& a = array_at(r, i);
    if (name) *name = a.name.c_str();
    if (rank) *rank = int(a.shape.size());
    not_null(shape, "shape");
    for (size_t k = 0; k < 5; ++k) shape[k] = k < a.shape.size() ? a.shape[k] : 1;
  });
}

ivr_status ivr_result_array_data(const ivr_result* r, size_t i, double* values, size_t capacity) {
  return guarded(context_of(r), "ivr_result_array_data", [&] {
    const ivr_result::Array& a = array_at(r, i);
    not_null(values, "values");
    if (capacity < a.values.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "values hold " + std::to_string(capacity) +
                                                   "; array '" + a.name + "' has " +
                                                   std::to_string(a.values.size())};
    std::memcpy(values, a.values.data(), a.values.size() * sizeof(double));
  });
}

}  // extern "C"
