// session.hpp — internal: a session's state (the scene's device copies, what is derived from
// them and whether it is fresh) and the pieces the operations share — the leading kernel
// arguments, the skipping plan, pooled outputs, the record of the last operation.
#pragma once
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "runtime/device_array.hpp"
#include "scene/device_scene.hpp"
#include "empty_space/empty_space.hpp"
#include "ivr/session.hpp"
#include "ivr/jacobian.hpp"
#include "ivr/tolerance.hpp"
#include "runtime/launch.hpp"
#include "runtime/runtime.hpp"
#include "runtime/variants.hpp"

namespace ivr {

// The last operation: its statistics, its kernels' events, and the per-pixel sample counts that
// its statistics sum (read back only when asked).
struct OperationRecord {
  OperationStats stats;
  std::vector<cl::Event> events;
  cl::Buffer samples;
  std::size_t sample_count = 0;
  bool resolved = false;
};

// The brick occupancy grid of the session's densities under its TF, rebuilt when either changed.
struct SessionGrid {
  int size = 0;                 // brick size of `ranges` (0: none taken)
  std::vector<float> ranges;    // per brick [min, max] of the densities, x fastest
  bool occupancy_fresh = false;  // `grid` and `occupied` match the ranges and the TF
  EmptySpaceGrid grid;
  cl::Buffer occupied;
};

struct Session::Impl {
  Device& device;
  Device::Impl& dev;
  SessionOptions options;
  bool f64;
  std::size_t real_size;
  std::mutex mutex;  // the public methods take it: one operation at a time

  Scene scene;  // the description; volume.data empty (dims and spacing kept)
  bool has_volume = false;
  DeviceArray volume;  // reals (nz, ny, nx)
  // The densities' range: exact where volume_range_exact (set by every upload, which checks
  // them), else only bounds (an optimiser step's [lower, upper]); the deterministic gradient's
  // bound measures it again then (lib/adjoint/adjoint.cpp).
  double volume_min = 0, volume_max = 0;
  bool volume_range_exact = false;
  // The caller's host copy of the densities, while it is known to be alive and current (the
  // one-shot functions: their scene outlives their session): where the grid may be built on the
  // host (CPU devices, $IVR_GRID=host). Dropped by every change of the densities.
  const std::vector<float>* host_volume = nullptr;
  cl::Buffer cameras, camera_params;  // pack_cameras / pack_camera_params
  cl::Buffer tf;
  int tf_count = 0;
  double tf_scalars[2] = {0, 0};
  DeviceArray target;  // reals, the image shape (invalid until set)
  // Its largest |element| (< 0: not known), set with it: the deterministic gradient's bound reads
  // it (lib/adjoint/adjoint.cpp), so the target changes only through set_target.
  double target_abs_max = -1;

  SessionGrid grid;
  std::optional<Integrator> resolved;  // the integrator with its step chosen (stale: none)
  StepChoice choice;
  std::optional<CostModel> cost;
  KernelSet kernels;
  ArrayKernels arrays;
  cl::Buffer no_occupancy;  // one byte: the kernels' occupancy argument when not skipping
  std::map<std::string, std::vector<DeviceArray>> pool;  // outputs by slot
  std::map<std::string, std::pair<cl::Buffer, std::size_t>> scratch_buffers;
  // The private copies of the adjoint's density gradient (kernels/private_sums.cl), their size
  // and how many of their leading bytes are known to be 0 (the sum of the copies leaves them so;
  // 0 while a launch may have left them otherwise).
  cl::Buffer private_copies;
  std::size_t private_copies_bytes = 0, private_copies_clean = 0;
  OperationRecord last;

  // `host_data`: the scene's densities stay alive and unchanged for the session's life (see
  // host_volume); otherwise they are only read here. A scene without data (dims only) gives a
  // session without densities.
  Impl(Device& device, const Scene& scene, const SessionOptions& options, bool host_data);

  // --- state ---
  // New densities (and, where `box` is given, a new box [box[0], box[1]] with them): checked on
  // the host and the device, then taken; nothing changes when either check fails.
  void upload_volume(const float* data, const double* data64, const Volume& dims,
                     const glm::dvec3* box = nullptr);
  void copy_volume(const DeviceArray& densities, const glm::dvec3* box = nullptr);
  void adopt_volume(DeviceArray densities, const Volume& dims, const glm::dvec3* box);
  void upload_cameras(const std::vector<Camera>& cameras);  // replaces a ray list too
  void upload_rays(const RayList& rays);                   // replaces the cameras too
  // The new cameras or rays (validated) and their device buffers taken.
  void geometry_changed(Scene next, const cl::Buffer& packed, const cl::Buffer& params);
  void upload_tf(const TransferFunction& tf);
  void check_target(const DeviceArray& target) const;
  void require_volume(const char* operation) const;
  void volume_changed();  // grid ranges, step choice
  void tf_changed();      // occupancy, step choice
  void check_array(const DeviceArray& a, const char* what) const;  // live, on this device

  // --- what operations share ---
  const Integrator& integrator();
  Integrator declared_integrator() const;  // the scene's, with options.step; no step chosen yet
  RenderVariant variant_of(const Integrator& integrator) const;
  // volume … min_transmittance, the leading arguments of every marching kernel; the next index.
  int set_scene_args(cl::Kernel& k, const Integrator& integrator) const;
  // Empty-space skipping for one launch, where `allowed` (a gradient that skipping keeps exact:
  // gradient_may_skip in lib/empty_space/empty_space.hpp) and the session's options ask for it — automatic:
  // where the TF is 0 on some density range and enough bricks are empty. The grid is rebuilt
  // only when stale; sets variant.empty_space / brick_size; the occupancy buffer to pass.
  const cl::Buffer& plan_skipping(bool allowed, RenderVariant& variant, OperationStats& stats);
  cl_int4 brick_counts() const;
  // A result array from the slot's pool: one that nobody else holds any more, else a new one.
  DeviceArray output(const std::string& slot, const std::vector<std::int64_t>& shape, DType dtype,
                     const char* what);
  // `a`'s buffer where it holds `dtype` already, else a copy converted into scratch slot `slot`
  // (the conversion's event joins `op`): what a kernel reading one type takes.
  cl::Buffer buffer_as(const DeviceArray& a, DType dtype, const char* slot, OperationRecord& op);
  // A buffer only operations of this session use (never handed out), at least `bytes` long.
  const cl::Buffer& scratch(const std::string& slot, std::size_t bytes, const char* what);
  OperationRecord& begin(const std::string& operation);
  std::uint64_t scene_bytes() const;
  std::size_t pixels() const;
  std::vector<std::int64_t> image_shape() const;
  std::vector<std::int64_t> volume_shape() const;
};

// The operations enqueue into the session's last-operation record and return device arrays:
// lib/render/render.hpp, lib/adjoint/adjoint.hpp, lib/jacobian/jacobian.hpp,
// lib/gradient/gradient.hpp, lib/tomo/project.hpp.

// The scene without its densities (they go to the device; a copy would double host memory).
Scene description_of(const Scene& scene);

}  // namespace ivr
