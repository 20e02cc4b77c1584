// ivr/session.hpp — device-resident sessions: one scene's volume, transfer function, cameras,
// target and empty-space grid live on the device; a setter uploads only its part and marks what
// depends on it stale; operations enqueue their kernels and leave their results in device arrays,
// read back only when asked. Every render, gradient, projection and optimiser step of ivr —
// the one-shot functions, the CLI, the C API, reconstructions — runs through a session.
#pragma once
#include <cstdint>
#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/adjoint.hpp"
#include "ivr/optimize.hpp"
#include "ivr/planner.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "ivr/jacobian.hpp"

namespace ivr {

enum class DType { f32, f64 };
IVR_API const char* dtype_name(DType dtype);  // "float32", "float64"

// A dense array in device memory: shape (C order), element type, and the buffer. Copies share
// the buffer (a view); an operation's result keeps its values until the holder lets it go.
// Commands on it run on its device's in-order queue, so a download sees every operation enqueued
// before it. Throws ivr::Error: invalid_argument for a count or shape that does not fit.
class IVR_API DeviceArray {
 public:
  DeviceArray() = default;  // no array: valid() is false
  // A new zero-filled array on `device`.
  DeviceArray(Device& device, std::vector<std::int64_t> shape, DType dtype);

  bool valid() const { return impl_ != nullptr; }
  const std::vector<std::int64_t>& shape() const;
  DType dtype() const;
  std::size_t size() const;   // elements
  std::size_t bytes() const;  // of device memory

  // Host → device: exactly size() values, converted to dtype(); the host memory may be reused
  // once the call returns.
  void upload(const float* values, std::size_t count);
  void upload(const double* values, std::size_t count);
  // Device → host: waits for what writes the array, then copies size() values (count must be at
  // least that), converted.
  void download(float* values, std::size_t count) const;
  void download(double* values, std::size_t count) const;
  std::vector<float> to_floats() const;
  std::vector<double> to_doubles() const;
  // Waits until every command enqueued so far that writes the array has finished.
  void wait() const;
  // Whether the array lives on `device` (arrays of another device or context are refused).
  bool on(const Device& device) const;

  // An array over the caller's `host` memory (shape in C order, dtype). Where the device's memory
  // is the host's (DeviceInfo::host_unified_memory: CPUs through PoCL) kernels read and write that
  // memory itself, with no copy: the caller keeps it alive, and does not touch it while an
  // operation that uses the array runs, until the array is released (the release waits for those
  // operations). Elsewhere the values are copied in once. borrowed() tells which.
  static DeviceArray wrap(Device& device, void* host, std::vector<std::int64_t> shape,
                          DType dtype);
  bool borrowed() const;
  // The array's values in host memory: waits for what writes it and maps it — no copy where the
  // device's memory is the host's, one elsewhere (written back at unmap). Every map() needs an
  // unmap(); maps nest and share one pointer, valid until the last unmap or the array's release.
  // A mapped array must not be written by uploads (refused) or operations.
  void* map() const;
  void unmap() const;

  struct Impl;
  const std::shared_ptr<Impl>& impl() const { return impl_; }
  explicit DeviceArray(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}

 private:
  std::shared_ptr<Impl> impl_;
};

// Fixed for a session's life: the precision of its device copies and kernels, and how it skips
// empty space.
struct SessionOptions {
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step and tolerance (voxel units)
  EmptySpace empty_space = EmptySpace::automatic;
  double min_empty_fraction = 0.05;
  int brick_size = 0;  // cells per brick edge; 0: 4 up to 128 voxels across, else 8
};

// What a gradient differentiates and how: the parameter groups of ivr gradient --wrt (density, tf,
// tf_points, scales, background, camera, step, voxels:LIST), the mode (automatic: the planner's
// choice by the parameter count), the loss and, for the adjoint's density gradient, fixed-point
// sums that repeat bit for bit (AdjointOptions::deterministic).
struct GradientRequest {
  std::vector<std::string> wrt{"density"};
  Mode mode = Mode::automatic;
  Loss loss = Loss::mse;
  bool deterministic = false;
};

// A gradient left on the device: the loss (shape {1}) and one array per group, in the order asked
// for (density (nz, ny, nx); tf rows × columns; background (1) or (3); camera (views, 7); tf_points,
// scales, step, voxels (n)). Scatter sums (density, adjoint TF) have the session's precision;
// reduced values (the loss, background, camera, forward-mode gradients) are float64 where the
// device has it.
struct IVR_API SessionGradient {
  DeviceArray loss;
  std::vector<std::pair<std::string, DeviceArray>> groups;
  Plan plan;            // the mode that ran, and both modes' predicted seconds
  std::string atomics;  // adjoint: the scatter's ("cl_ext_float_atomics" or "compare-and-swap")
  // The group called `name`; throws ivr::Error(invalid_argument) if it was not asked for.
  const DeviceArray& operator[](const std::string& name) const;
};

// What the last operation did, with its kernels' device time (profiling events).
struct OperationStats {
  std::string operation;       // "render", "gradient", "jacobian", "project", "backproject", …
  double kernel_seconds = 0;   // every kernel it enqueued, from their profiling events
  double build_seconds = 0;    // finding or compiling its programs (0 once a session has them)
  std::uint64_t samples = 0;   // density samples over all rays (render, gradient, tangents)
  std::string variant;         // the compiled feature set, e.g. "render model=… f32 …"
  bool skipped_empty = false;  // empty-space skipping ran
  double empty_fraction = 0;   // of the bricks, when the grid was built
  double grid_seconds = 0;     // building the occupancy grid (0 while it is fresh)
  double step = 0;             // the integrator step used (voxel units)
  std::uint64_t device_bytes = 0;  // device memory of the operation's buffers and the scene's
  Mode mode = Mode::adjoint;       // gradient: what ran
  int passes = 0, lanes = 0;       // forward mode
  bool deterministic = false;      // the density gradient was summed in fixed point
  int fixed_exponent = 0;          // its scale 2^S, when it was
  int fixed_passes = 0;            // the adjoint passes that took (1; 2 where the bound failed)
  double fixed_bound = 0;          // the a-priori bound on one ray's Σ |contribution| that set S
  double fixed_largest_ray = 0;    // the largest ray's Σ |contribution| measured (≤ fixed_bound)
  double fixed_largest = 0;        // the largest single contribution (≥ 2^24·2^−S, or 2 passes)
  int bricks = 1;                  // out-of-core: the bricks the volume was split into (1: in core)
  int sweeps = 0;                  // out-of-core: passes over the bricks (1 in a front-to-back order)
};

// A scene on one device. Not copyable; one thread at a time (calls from several threads are
// serialised); sessions on one device may be used from different threads at once.
// Every setter checks its input first and leaves the session exactly as it was when it throws
// ivr::Error (invalid_argument naming what and where; out_of_memory; opencl).
class IVR_API Session {
 public:
  // Uploads the scene's volume (checked on the device: finite, >= 0), TF and cameras. A scene
  // whose volume has dims but no data gives a session without densities: set_volume must come
  // before any operation that marches them (projections of given volumes do not).
  Session(Device& device, const Scene& scene, const SessionOptions& options = {});
  ~Session();
  Session(Session&&) noexcept;
  Session& operator=(Session&&) noexcept;
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // --- setters: only this part is uploaded; what depends on it is rebuilt when next needed -----
  // Densities (nz, ny, nx), x fastest, any shape (the box is kept): a device pass checks them.
  void set_volume(const Volume& volume);
  void set_volume(const float* densities, std::int64_t nz, std::int64_t ny, std::int64_t nx);
  void set_volume(const double* densities, std::int64_t nz, std::int64_t ny, std::int64_t nx);
  // From a device array of shape (nz, ny, nx), float32 or float64: copied on the device.
  void set_volume(const DeviceArray& densities);
  void set_tf(const TransferFunction& tf);
  // Views may change in number and size (a target of the old shape is then dropped).
  void set_cameras(const std::vector<Camera>& cameras);
  // A ray list instead of cameras (ivr::make_ray_list; docs/design.md, "Ray lists"): images and
  // targets then have shape (rays, channels). set_cameras goes back to cameras.
  void set_rays(const RayList& rays);
  void set_integrator(const Integrator& integrator);
  void set_background(const glm::dvec3& background);  // absorption: x is I_in
  void set_box(const glm::dvec3& box_min, const glm::dvec3& box_max);
  // The loss target: the image shape (views, H, W, C) — (rays, C) for a ray list — finite.
  void set_target(const Image& target);
  void set_target(const DeviceArray& target);

  // --- what it holds -------------------------------------------------------------------------
  const Scene& scene() const;  // the description; volume.data is empty (the densities are on the device)
  const SessionOptions& options() const;
  Device& device() const;
  std::vector<std::int64_t> image_shape() const;   // (views, H, W, C); a ray list's (rays, C)
  std::vector<std::int64_t> volume_shape() const;  // (nz, ny, nx)
  bool has_volume() const;
  // The densities as a view of the session's own buffer (the session's precision): optimiser
  // steps show through it; a later set_volume gives the session a new buffer.
  DeviceArray volume() const;
  DeviceArray target() const;  // invalid until set
  // The integrator the next operation marches with (a tolerance's step chosen by pilot renders).
  Integrator integrator();

  // --- operations: enqueued; results stay on the device ---------------------------------------
  // Every view: (views, H, W, C), float32, or float64 in a session of precision f64.
  DeviceArray render();
  // The loss of the render against the target (set_target, or `target`) and its gradients.
  SessionGradient gradient(const GradientRequest& request = {});
  SessionGradient gradient(const DeviceArray& target, const GradientRequest& request = {});
  // d pixel / d parameter in forward mode: (views, H, W, C, P), P in `wrt` order; float32, or
  // float64 at f64.
  DeviceArray jacobian(const std::vector<std::string>& wrt);
  // Forward mode on any list of parameters (ivr/jacobian.hpp; repeats allowed) against the
  // target: the loss and one group, "parameters", of their derivatives in order.
  SessionGradient forward(const std::vector<Parameter>& parameters, Loss loss = Loss::mse);
  // Line integrals N v of the densities (or of `volume`, (nz, ny, nx)) along every pixel ray,
  // evaluated exactly whatever the integrator: (views, H, W, 1) in the session's precision.
  DeviceArray project();
  DeviceArray project(const DeviceArray& volume);
  // Nᵀ p, the exact transpose: `lines` (views, H, W, 1) onto the grid, (nz, ny, nx).
  DeviceArray backproject(const DeviceArray& lines);
  // The loss (shape {1}) of an image against a target of the same size.
  DeviceArray loss(const DeviceArray& image, const DeviceArray& target, Loss loss = Loss::mse);
  // One optimiser step on the densities in place: densities ← project(densities − update(grad)).
  // The optimiser must count the voxels, have the session's precision and bounds within
  // [0, ∞) (densities stay >= 0); `gradient` is the density gradient's shape.
  void step(Optimizer& optimizer, const DeviceArray& gradient);

  // Waits for the last operation; its statistics (the samples are read back and summed).
  OperationStats last_stats();
  // Waits for the last operation; the device time of its kernels alone (nothing read back).
  double last_kernel_seconds();
  // Waits for every command enqueued so far.
  void finish();

  struct Impl;
  Impl& impl() const { return *impl_; }
  explicit Session(std::unique_ptr<Impl> impl);

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ivr
