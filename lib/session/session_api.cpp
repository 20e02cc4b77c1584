// session_api.cpp — ivr::Session's public face: construction, the setters, the accessors and the
// operations, each under the session's lock and each leaving the session as it was when it throws.
#include <algorithm>
#include <cmath>

#include "reconstruct/optimize.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"
#include "render/render.hpp"
#include "jacobian/jacobian.hpp"
#include "gradient/gradient.hpp"

namespace ivr {

namespace {

[[noreturn]] void bad(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

Volume dims_of(std::int64_t nz, std::int64_t ny, std::int64_t nx, const char* what) {
  const std::int64_t most = std::int64_t(1) << 20;
  if (nz < 1 || ny < 1 || nx < 1 || nz > most || ny > most || nx > most)
    bad(std::string(what) + ": shape (" + std::to_string(nz) + ", " + std::to_string(ny) + ", " +
        std::to_string(nx) + ") (each dimension 1 .. 2^20)");
  if (double(nz) * double(ny) * double(nx) > 2147483647.0)
    bad(std::string(what) + ": more than 2^31 voxels");
  Volume v;
  v.nz = int(nz), v.ny = int(ny), v.nx = int(nx);
  return v;
}

}  // namespace

Session::Session(Device& device, const Scene& scene, const SessionOptions& options)
    : impl_(std::make_unique<Impl>(device, scene, options, false)) {}
Session::Session(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
// Waits for the session's commands: operations enqueue and return, and a process that ended with
// a launch still pending could exit while PoCL's worker threads compile that kernel's work-group
// function (LLVM's pass registry is torn down under them: a crash at exit). Buffers themselves
// would be safe (OpenCL keeps them until their commands complete).
Session::~Session() {
  if (!impl_) return;
  try {
    impl_->dev.queue.finish();
  } catch (...) {  // nothing to report to from a destructor; the device's own error shows later
  }
}
Session::Session(Session&&) noexcept = default;
Session& Session::operator=(Session&&) noexcept = default;

// --- setters ---------------------------------------------------------------------------------------

void Session::set_volume(const Volume& volume) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const Volume dims = dims_of(volume.nz, volume.ny, volume.nx, "set_volume");
  if (volume.data.size() != dims.voxel_count())
    bad("set_volume: " + std::to_string(volume.data.size()) + " values for a volume of shape (" +
        std::to_string(volume.nz) + ", " + std::to_string(volume.ny) + ", " +
        std::to_string(volume.nx) + ")");
  impl_->upload_volume(volume.data.data(), nullptr, dims);
}

void Session::set_volume(const float* densities, std::int64_t nz, std::int64_t ny,
                         std::int64_t nx) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (!densities) bad("set_volume: densities is null");
  impl_->upload_volume(densities, nullptr, dims_of(nz, ny, nx, "set_volume"));
}

void Session::set_volume(const double* densities, std::int64_t nz, std::int64_t ny,
                         std::int64_t nx) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (!densities) bad("set_volume: densities is null");
  impl_->upload_volume(nullptr, densities, dims_of(nz, ny, nx, "set_volume"));
}

void Session::set_volume(const DeviceArray& densities) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->copy_volume(densities);
}

void Session::set_tf(const TransferFunction& tf) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->upload_tf(tf);
}

void Session::set_cameras(const std::vector<Camera>& cameras) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->upload_cameras(cameras);
}

void Session::set_rays(const RayList& rays) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->upload_rays(rays);
}

void Session::set_integrator(const Integrator& integrator) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  Scene next = s.scene;
  next.integrator = integrator;
  Integrator checked = integrator;
  if (s.options.step > 0) checked.step = s.options.step;
  validate_description(next, checked);
  s.scene.integrator = integrator;
  s.resolved.reset();
}

void Session::set_background(const glm::dvec3& background) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (!std::isfinite(background.x) || !std::isfinite(background.y) ||
      !std::isfinite(background.z))
    bad("set_background: background must be finite");
  impl_->scene.background = background;
  if (impl_->scene.integrator.tolerance > 0) impl_->resolved.reset();
}

void Session::set_box(const glm::dvec3& box_min, const glm::dvec3& box_max) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  Scene next = s.scene;
  next.box_min = box_min;
  next.box_max = box_max;
  validate_description(next, s.declared_integrator());
  s.scene.box_min = box_min;
  s.scene.box_max = box_max;
  if (s.scene.integrator.tolerance > 0) s.resolved.reset();
}

void Session::set_target(const Image& target) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  ivr::check_target(s.scene, target);
  DeviceArray fresh = make_array(s.device, s.dev, s.image_shape(), real_dtype(s.f64), "the target");
  fresh.upload(target.pixels.data(), target.pixels.size());
  double largest = 0;  // for the deterministic gradient's bound (lib/adjoint/adjoint.cpp)
  for (float v : target.pixels) largest = std::max(largest, std::abs(double(v)));
  s.target = fresh;
  s.target_abs_max = largest;
}

void Session::set_target(const DeviceArray& target) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.check_target(target);
  DeviceArray fresh = make_array(s.device, s.dev, s.image_shape(), real_dtype(s.f64), "the target");
  cl_call("copying the target on " + s.dev.info.name, [&] {
    mark_written(fresh, s.arrays.convert(buffer_of(target), target.dtype(), buffer_of(fresh),
                                         real_dtype(s.f64), fresh.size()));
  });
  double lo = 0, hi = 0;
  std::vector<cl::Event> events;
  const std::uint64_t first =
      s.arrays.check_values(buffer_of(fresh), fresh.size(), true, &lo, &hi, events);
  if (first < fresh.size())
    bad("target element " + std::to_string(first) + " is not finite");
  s.target = fresh;
  s.target_abs_max = std::max(std::abs(lo), std::abs(hi));
}

// --- accessors -------------------------------------------------------------------------------------

const Scene& Session::scene() const {
  return impl_->scene;
}
const SessionOptions& Session::options() const {
  return impl_->options;
}
Device& Session::device() const {
  return impl_->device;
}
std::vector<std::int64_t> Session::image_shape() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->image_shape();
}
std::vector<std::int64_t> Session::volume_shape() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->volume_shape();
}
bool Session::has_volume() const {
  return impl_->has_volume;
}
DeviceArray Session::volume() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->require_volume("volume");
  return impl_->volume;
}
DeviceArray Session::target() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->target;
}
Integrator Session::integrator() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->integrator();
}

// --- operations ------------------------------------------------------------------------------------

DeviceArray Session::render() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->require_volume("render");
  return enqueue_render(*impl_, impl_->begin("render"));
}

SessionGradient Session::gradient(const GradientRequest& request) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (!impl_->target.valid())
    bad("gradient: the session has no target (set_target, or pass one)");
  impl_->require_volume("gradient");
  return session_gradient(*impl_, impl_->target, request);
}

SessionGradient Session::gradient(const DeviceArray& target, const GradientRequest& request) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->check_target(target);
  impl_->require_volume("gradient");
  // A target given per call is checked per call (a device pass: set_target checks it once).
  double lo = 0, hi = 0;
  std::vector<cl::Event> events;
  const std::uint64_t first =
      impl_->arrays.check_values(buffer_of(target), target.size(), true, &lo, &hi, events);
  if (first < target.size()) bad("target element " + std::to_string(first) + " is not finite");
  DeviceArray t = target;
  if (target.dtype() != real_dtype(impl_->f64)) {  // the kernels read reals
    t = impl_->output("target", target.shape(), real_dtype(impl_->f64), "the target");
    cl_call("converting the target", [&] {
      mark_written(t, impl_->arrays.convert(buffer_of(target), target.dtype(), buffer_of(t),
                                            real_dtype(impl_->f64), t.size()));
    });
  }
  return session_gradient(*impl_, t, request);
}

DeviceArray Session::jacobian(const std::vector<std::string>& wrt) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.require_volume("jacobian");
  if (wrt.empty()) bad("jacobian: no parameter group asked for");
  std::vector<Parameter> params;
  for (const std::string& g : wrt)
    for (const Parameter& p : parameters_of(s.scene, g)) params.push_back(p);
  OperationRecord& op = s.begin("jacobian");
  return enqueue_jacobian(s, lanes_of(s.scene, params), nullptr, true, Loss::mse, op).jacobian;
}

SessionGradient Session::forward(const std::vector<Parameter>& parameters, Loss kind) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.require_volume("forward");
  if (!s.target.valid()) bad("forward: the session has no target (set_target first)");
  const std::vector<cl_int4> lanes = lanes_of(s.scene, parameters);
  OperationRecord& op = s.begin("forward");
  const JacobianResult t = enqueue_jacobian(s, lanes, &s.target, false, kind, op);
  SessionGradient g;
  g.loss = t.loss;
  g.groups.emplace_back("parameters", t.gradient);
  g.plan.mode = Mode::forward;
  return g;
}

static_assert(int(Loss::mse) == 0 && int(Loss::l1) == 1 && int(Loss::dot) == 2,
              "kernels/array_ops.cl loss_partial numbers the losses in this order");

DeviceArray Session::loss(const DeviceArray& image, const DeviceArray& target, Loss kind) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.check_array(image, "loss: image");
  s.check_array(target, "loss: target");
  if (image.size() != target.size() || image.size() == 0)
    bad("loss: image " + shape_text(image.shape()) + " and target " + shape_text(target.shape()) +
        " differ in size (or are empty)");
  OperationRecord& op = s.begin("loss");
  return cl_call("computing the loss on " + s.dev.info.name, [&] {
    // The kernel reads images and targets of the session's precision.
    const cl::Buffer img = s.buffer_as(image, real_dtype(s.f64), "the loss's image", op);
    const cl::Buffer tgt = s.buffer_as(target, real_dtype(s.f64), "the loss's target", op);
    DeviceArray out = s.output("loss", {1}, s.arrays.acc_dtype(), "the loss");
    mark_written(out, s.arrays.loss(img, tgt, image.size(), int(kind), buffer_of(out),
                                    op.events));
    return out;
  });
}

void Session::step(Optimizer& optimizer, const DeviceArray& gradient) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.require_volume("step");
  s.check_array(gradient, "step: gradient");
  Optimizer::Impl& o = optimizer.impl();
  if (&o.dev != &s.dev) bad("step: the optimizer belongs to another device or context");
  if (o.count != s.volume.size())
    bad("step: the optimizer has " + std::to_string(o.count) + " parameters; the densities " +
        std::to_string(s.volume.size()));
  if (o.f64 != s.f64) bad("step: the optimizer's precision differs from the session's");
  if (!(o.options.lower >= 0))
    bad("step: the optimizer's lower bound must be >= 0 (densities stay >= 0), got " +
        number_text(o.options.lower));
  if (gradient.shape() != s.volume.shape())
    bad("step: the gradient has shape " + shape_text(gradient.shape()) + "; the densities " +
        shape_text(s.volume.shape()));
  OperationRecord& op = s.begin("step");
  cl_call("the optimiser step on " + s.dev.info.name, [&] {
    // Forward mode's float64 sums, for one, step a float32 session's densities converted.
    const cl::Buffer g = s.buffer_as(gradient, real_dtype(s.f64), "the step's gradient", op);
    op.events.push_back(o.step(buffer_of(s.volume), g));
    mark_written(s.volume, op.events.back());
  });
  // The values moved within the optimiser's bounds: the grid and a tolerance's step are stale.
  s.volume_changed();
  s.volume_min = o.options.lower;
  s.volume_max = o.options.upper;
  s.volume_range_exact = false;
}

OperationStats Session::last_stats() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  OperationRecord& op = impl_->last;
  if (!op.resolved) {
    cl_call("timing the last operation", [&] {
      op.stats.kernel_seconds = events_seconds(op.events);
      if (op.sample_count) {
        std::vector<cl_uint> samples(op.sample_count);
        impl_->dev.queue.enqueueReadBuffer(op.samples, CL_TRUE, 0, samples.size() * 4,
                                           samples.data());
        std::uint64_t total = 0;
        for (cl_uint v : samples) total += v;
        op.stats.samples = total;
      }
    });
    op.resolved = true;
  }
  return op.stats;
}

double Session::last_kernel_seconds() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  OperationRecord& op = impl_->last;
  if (op.resolved) return op.stats.kernel_seconds;
  return cl_call("timing the last operation", [&] { return events_seconds(op.events); });
}

void Session::finish() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  cl_call("waiting for the session's commands", [&] { impl_->dev.queue.finish(); });
}

const DeviceArray& SessionGradient::operator[](const std::string& name) const {
  for (const auto& [group, array] : groups)
    if (group == name) return array;
  bad("the gradient has no group '" + name + "'");
}

}  // namespace ivr
