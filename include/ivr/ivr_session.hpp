// ivr/ivr_session.hpp — the C++ RAII layer over the C API's sessions, device arrays and density
// optimisers (ivr/ivr.h, "Device-resident sessions"); included by ivr/ivr.hpp.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "ivr/ivr.hpp"

namespace ivr::api {

enum class DType { f32 = IVR_FLOAT32, f64 = IVR_FLOAT64 };

// An array in device memory (shape, dtype). Copies share the array; results of a session's
// operations keep their values until the last copy goes.
class DeviceArray : public detail::Handle<ivr_array, ivr_array_retain, ivr_array_release> {
 public:
  using Handle::Handle;
  // A zero-filled array on the context's device.
  DeviceArray(const Context& context, const std::vector<int64_t>& shape,
              DType dtype = DType::f32);
  std::vector<int64_t> shape() const {
    int rank = 0;
    int64_t s[8] = {};
    detail::check(ivr_array_info(get(), &rank, s, nullptr));
    return std::vector<int64_t>(s, s + rank);
  }
  DType dtype() const {
    ivr_dtype d = IVR_FLOAT32;
    detail::check(ivr_array_info(get(), nullptr, nullptr, &d));
    return DType(d);
  }
  size_t size() const { return detail::product(shape()); }
  void upload(const std::vector<float>& values) {
    detail::check(ivr_array_upload(get(), values.data(), IVR_FLOAT32, values.size()));
  }
  void upload(const std::vector<double>& values) {
    detail::check(ivr_array_upload(get(), values.data(), IVR_FLOAT64, values.size()));
  }
  // Waits for what writes it, then reads it back.
  Array<float> download() const {
    Array<float> a{shape(), {}};
    a.values.resize(detail::product(a.shape));
    detail::check(ivr_array_download(get(), a.values.data(), IVR_FLOAT32, a.size()));
    return a;
  }
  Array<double> download_f64() const {
    Array<double> a{shape(), {}};
    a.values.resize(detail::product(a.shape));
    detail::check(ivr_array_download(get(), a.values.data(), IVR_FLOAT64, a.size()));
    return a;
  }
  // The first value (a loss).
  double item() const { return download_f64().values.at(0); }
  // The group of a gradient's array ("density", "tf", …), else "".
  std::string name() const {
    const char* n = nullptr;
    detail::check(ivr_array_name(get(), &n));
    return n;
  }
  void wait() const { detail::check(ivr_array_wait(get())); }
};

inline DeviceArray::DeviceArray(const Context& context, const std::vector<int64_t>& shape,
                                DType dtype) {
  detail::check(ivr_array_create(context.get(), int(shape.size()), shape.data(), ivr_dtype(dtype),
                                 &handle_));
}

// ivr_session_options (documented in ivr_session.h) with the library's defaults.
struct SessionOptions : ivr_session_options {
  SessionOptions() : ivr_session_options() { detail::check(ivr_session_options_init(this)); }
};

// A gradient left on the device: the loss (shape {1}) and one array per group, in `wrt` order.
struct SessionGradient {
  DeviceArray loss;
  std::vector<std::pair<std::string, DeviceArray>> groups;
  Mode mode = Mode::adjoint;  // what ran
  const DeviceArray& operator[](const std::string& name) const {
    for (const auto& g : groups)
      if (g.first == name) return g.second;
    throw Exception(IVR_ERROR_INVALID_ARGUMENT, "the gradient has no group '" + name + "'");
  }
};

class Session;

// Adam or SGD moments for a session's densities (kept >= 0).
class DensityOptimizer
    : public detail::Handle<ivr_density_optimizer, ivr_density_optimizer_retain,
                            ivr_density_optimizer_release> {
 public:
  using Handle::Handle;
  DensityOptimizer(Session& session, ivr_optimizer kind, double lr);
};

// A scene resident on the device (ivr/session.hpp): setters upload only their part; operations
// enqueue and return device arrays.
class Session : public detail::Handle<ivr_session, ivr_session_retain, ivr_session_release> {
 public:
  using Handle::Handle;
  Session(const Context& context, const Scene& scene, const SessionOptions& options = {}) {
    const ivr_session_options& o = options;
    detail::check(ivr_session_create(context.get(), scene.get(), &o, &handle_));
  }
  // Densities {nz, ny, nx}, x fastest.
  void set_volume(const std::vector<float>& data, const std::vector<int64_t>& shape) {
    if (shape.size() != 3 || data.size() != detail::product(shape))
      throw Exception(IVR_ERROR_INVALID_ARGUMENT,
                      "set_volume: " + std::to_string(data.size()) +
                          " values do not fill a volume of the given 3-d shape");
    detail::check(ivr_session_set_volume(get(), data.data(), IVR_FLOAT32, shape.data()));
  }
  void set_volume(const DeviceArray& densities) {
    detail::check(ivr_session_set_volume_array(get(), densities.get()));
  }
  void set_tf(const TransferFunction& tf) { detail::check(ivr_session_set_tf(get(), tf.get())); }
  void set_cameras_json(const std::string& json) {
    detail::check(ivr_session_set_cameras_json(get(), json.c_str()));
  }
  // rows × columns doubles (8 or 6 columns, as ivr_session_set_rays).
  void set_rays(const double* values, size_t rows, int columns) {
    detail::check(ivr_session_set_rays(get(), values, rows, columns));
  }
  void set_cameras(const std::vector<ivr_camera>& cameras) {
    detail::check(ivr_session_set_cameras(get(), cameras.data(), cameras.size()));
  }
  void set_integrator_json(const std::string& json) {
    detail::check(ivr_session_set_integrator_json(get(), json.c_str()));
  }
  void set_background(double r, double g, double b) {
    const double bg[3] = {r, g, b};
    detail::check(ivr_session_set_background(get(), bg));
  }
  void set_target(const std::vector<float>& target) {
    detail::check(ivr_session_set_target(get(), target.data(), target.size()));
  }
  void set_target(const DeviceArray& target) {
    detail::check(ivr_session_set_target_array(get(), target.get()));
  }
  std::vector<int64_t> image_shape() const {
    std::vector<int64_t> s(4);
    detail::check(ivr_session_image_shape(get(), s.data()));
    return s;
  }
  std::vector<int64_t> volume_shape() const {
    std::vector<int64_t> s(3);
    detail::check(ivr_session_volume_shape(get(), s.data()));
    return s;
  }
  DeviceArray volume() {
    ivr_array* a = nullptr;
    detail::check(ivr_session_volume(get(), &a));
    return DeviceArray(a);
  }
  DeviceArray render() {
    ivr_array* a = nullptr;
    detail::check(ivr_session_render(get(), &a));
    return DeviceArray(a);
  }
  // Against the session's target, or `target` where given (not null).
  SessionGradient gradient(const std::string& wrt = "density", Mode mode = Mode::automatic,
                           Loss loss = Loss::mse, bool deterministic = false,
                           const DeviceArray* target = nullptr) {
    std::vector<ivr_array*> groups(64, nullptr);
    size_t count = 0;
    ivr_array* value = nullptr;
    ivr_mode ran = IVR_MODE_AUTO;
    detail::check(ivr_session_gradient(get(), target ? target->get() : nullptr, wrt.c_str(),
                                       ivr_mode(mode), ivr_loss(loss), deterministic ? 1 : 0,
                                       &value, groups.data(), groups.size(), &count, &ran));
    SessionGradient g{DeviceArray(value), {}, Mode(ran)};
    for (size_t i = 0; i < count; ++i) {
      DeviceArray a(groups[i]);
      const char* name = nullptr;
      detail::check(ivr_array_name(a.get(), &name));
      g.groups.emplace_back(name, std::move(a));
    }
    return g;
  }
  DeviceArray jacobian(const std::string& wrt) {
    ivr_array* a = nullptr;
    detail::check(ivr_session_jacobian(get(), wrt.c_str(), &a));
    return DeviceArray(a);
  }
  DeviceArray project(const DeviceArray* volume = nullptr) {
    ivr_array* a = nullptr;
    detail::check(ivr_session_project(get(), volume ? volume->get() : nullptr, &a));
    return DeviceArray(a);
  }
  DeviceArray backproject(const DeviceArray& lines) {
    ivr_array* a = nullptr;
    detail::check(ivr_session_backproject(get(), lines.get(), &a));
    return DeviceArray(a);
  }
  DeviceArray loss(const DeviceArray& image, const DeviceArray& target, Loss kind = Loss::mse) {
    ivr_array* a = nullptr;
    detail::check(ivr_session_loss(get(), image.get(), target.get(), ivr_loss(kind), &a));
    return DeviceArray(a);
  }
  void step(DensityOptimizer& optimizer, const DeviceArray& gradient) {
    detail::check(ivr_session_step(get(), optimizer.get(), gradient.get()));
  }
  ivr_operation_stats last_stats() {
    ivr_operation_stats s{};
    detail::check(ivr_session_last_stats(get(), &s));
    return s;
  }
  void finish() { detail::check(ivr_session_finish(get())); }
};

inline DensityOptimizer::DensityOptimizer(Session& session, ivr_optimizer kind, double lr) {
  detail::check(ivr_density_optimizer_create(session.get(), kind, lr, &handle_));
}

}  // namespace ivr::api
