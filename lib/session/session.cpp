// session.cpp — a scene resident on the device: its construction, the setters (each checks, then
// uploads only its part and marks what depends on it stale), and what the operations share — the
// resolved integrator, the leading kernel arguments, the skipping plan, pooled outputs.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "runtime/real_args.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"
#include "render/tolerance.hpp"

namespace ivr {

namespace {

[[noreturn]] void bad(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

}  // namespace

Scene description_of(const Scene& scene) {
  Scene d;
  d.volume.nx = scene.volume.nx;
  d.volume.ny = scene.volume.ny;
  d.volume.nz = scene.volume.nz;
  d.volume.spacing = scene.volume.spacing;
  d.box_min = scene.box_min;
  d.box_max = scene.box_max;
  d.model = scene.model;
  d.tf = scene.tf;
  d.background = scene.background;
  d.cameras = scene.cameras;
  d.rays = scene.rays;
  d.integrator = scene.integrator;
  return d;
}

namespace {

void check_options(const SessionOptions& o) {
  if (!(o.step >= 0) || !std::isfinite(o.step))
    bad("session options: step must be >= 0 and finite (0: the scene's), got " +
        number_text(o.step));
  if (!(o.min_empty_fraction >= 0 && o.min_empty_fraction <= 1))
    bad("session options: min_empty_fraction must be in [0, 1], got " +
        number_text(o.min_empty_fraction));
  if (o.brick_size < 0 || o.brick_size > 64)
    bad("session options: brick_size must be in 0 .. 64 (0: automatic), got " +
        std::to_string(o.brick_size));
}

}  // namespace

Session::Impl::Impl(Device& d, const Scene& s, const SessionOptions& o, bool host_data)
    : device(d),
      dev(d.impl()),
      options(o),
      f64(o.precision == Precision::f64),
      real_size(o.precision == Precision::f64 ? 8 : 4),
      scene(description_of(s)),
      kernels(d.impl()),
      arrays(d.impl(), kernels, o.precision == Precision::f64) {
  check_options(o);
  if (f64 && !dev.info.fp64)
    throw Error(Status::unsupported,
                "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
  validate_description(scene, declared_integrator());
  const std::size_t voxels = s.volume.voxel_count();
  if (!s.volume.data.empty() && s.volume.data.size() != voxels)
    bad("volume: holds " + std::to_string(s.volume.data.size()) + " values but dims need " +
        std::to_string(voxels));
  const std::uint8_t none = 0;
  no_occupancy = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, 1, &none, "the occupancy grid");
  if (scene.has_ray_list())
    upload_rays(scene.rays);
  else
    upload_cameras(scene.cameras);
  upload_tf(scene.tf);
  if (!s.volume.data.empty()) {
    upload_volume(s.volume.data.data(), nullptr, s.volume);
    if (host_data) host_volume = &s.volume.data;
  }
}

// --- state ---------------------------------------------------------------------------------------

void Session::Impl::check_array(const DeviceArray& a, const char* what) const {
  if (!a.valid()) bad(std::string(what) + ": the device array is empty");
  if (!a.on(device))
    throw Error(Status::invalid_argument,
                std::string(what) + ": the device array belongs to another device or context");
}

void Session::Impl::upload_volume(const float* data, const double* data64, const Volume& dims,
                                  const glm::dvec3* box) {
  const std::size_t n = dims.voxel_count();
  DeviceArray fresh = output("volume", {dims.nz, dims.ny, dims.nx}, real_dtype(f64), "the volume");
  if (data)
    fresh.upload(data, n);
  else
    fresh.upload(data64, n);
  adopt_volume(fresh, dims, box);
}

void Session::Impl::copy_volume(const DeviceArray& densities, const glm::dvec3* box) {
  check_array(densities, "set_volume");
  const std::vector<std::int64_t>& shape = densities.shape();
  if (shape.size() != 3)
    bad("set_volume: the array has shape " + shape_text(shape) + "; densities are (nz, ny, nx)");
  for (std::int64_t d : shape)
    if (d < 1 || d > (std::int64_t(1) << 20))
      bad("set_volume: shape " + shape_text(shape) + " (each dimension 1 .. 2^20)");
  Volume dims;
  dims.nz = int(shape[0]), dims.ny = int(shape[1]), dims.nx = int(shape[2]);
  DeviceArray fresh = output("volume", shape, real_dtype(f64), "the volume");
  cl_call("copying the densities on " + dev.info.name, [&] {
    mark_written(fresh, arrays.convert(buffer_of(densities), densities.dtype(), buffer_of(fresh),
                                       real_dtype(f64), dims.voxel_count()));
  });
  adopt_volume(fresh, dims, box);
}

void Session::Impl::adopt_volume(DeviceArray fresh, const Volume& dims, const glm::dvec3* box) {
  Scene next = scene;
  next.volume.nx = dims.nx, next.volume.ny = dims.ny, next.volume.nz = dims.nz;
  if (box) next.box_min = box[0], next.box_max = box[1];
  validate_description(next, declared_integrator());
  double lo = 0, hi = 0;
  std::vector<cl::Event> events;
  const std::uint64_t n = dims.voxel_count();
  const std::uint64_t first = arrays.check_values(buffer_of(fresh), n, false, &lo, &hi, events);
  if (first < n) {
    double value = 0;
    cl_call("reading a bad density back", [&] {
      if (f64)
        dev.queue.enqueueReadBuffer(buffer_of(fresh), CL_TRUE, first * 8, 8, &value);
      else {
        float v = 0;
        dev.queue.enqueueReadBuffer(buffer_of(fresh), CL_TRUE, first * 4, 4, &v);
        value = v;
      }
    });
    throw bad_density(dims, std::size_t(first), value);
  }
  scene.volume.nx = dims.nx, scene.volume.ny = dims.ny, scene.volume.nz = dims.nz;
  if (box) scene.box_min = box[0], scene.box_max = box[1];
  volume = std::move(fresh);
  has_volume = true;
  volume_min = lo;
  volume_max = hi;
  volume_range_exact = true;
  volume_changed();
}

void Session::Impl::volume_changed() {
  host_volume = nullptr;
  grid.size = 0;
  grid.ranges.clear();
  grid.occupancy_fresh = false;
  if (scene.integrator.tolerance > 0) resolved.reset();
}

void Session::Impl::tf_changed() {
  grid.occupancy_fresh = false;
  if (scene.integrator.tolerance > 0) resolved.reset();
}

void Session::Impl::upload_cameras(const std::vector<Camera>& cams) {
  Scene next = scene;
  next.cameras = cams;
  next.rays = RayList{};
  validate_description(next, declared_integrator());
  cl::Buffer packed, params;
  if (f64) {
    const std::vector<double> a = pack_cameras<double>(cams), b = pack_camera_params<double>(cams);
    packed = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, a.size() * 8, a.data(), "the cameras");
    params = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, b.size() * 8, b.data(),
                        "the camera parameters");
  } else {
    const std::vector<float> a = pack_cameras<float>(cams), b = pack_camera_params<float>(cams);
    packed = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, a.size() * 4, a.data(), "the cameras");
    params = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, b.size() * 4, b.data(),
                        "the camera parameters");
  }
  geometry_changed(std::move(next), packed, params);
}

void Session::Impl::upload_rays(const RayList& rays) {
  Scene next = scene;
  next.cameras.clear();
  next.rays = rays;
  validate_description(next, declared_integrator());
  // The list in the kernels' precision, in the cameras' place (kernels/geometry.cl, IVR_RAY_LIST);
  // no camera parameters (nothing differentiates a ray list's geometry): one value, as buffers
  // cannot be empty.
  cl::Buffer packed, params;
  if (f64) {
    packed = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, rays.values.size() * 8,
                        const_cast<double*>(rays.values.data()), "the rays");
  } else {
    std::vector<float> a(rays.values.begin(), rays.values.end());
    packed = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, a.size() * 4, a.data(), "the rays");
  }
  const double none = 0;
  params = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, 8, const_cast<double*>(&none),
                      "the camera parameters");
  geometry_changed(std::move(next), packed, params);
}

void Session::Impl::geometry_changed(Scene next, const cl::Buffer& packed,
                                     const cl::Buffer& params) {
  cameras = packed;
  camera_params = params;
  scene.cameras = std::move(next.cameras);
  scene.rays = std::move(next.rays);
  if (target.valid() && target.shape() != image_shape()) {
    target = DeviceArray();
    target_abs_max = -1;
  }
  if (scene.integrator.tolerance > 0) resolved.reset();
}

void Session::Impl::upload_tf(const TransferFunction& t) {
  Scene next = scene;
  next.tf = t;
  validate_description(next, declared_integrator());
  int count = 0;
  double scalars[2] = {0, 0};
  cl::Buffer packed;
  if (f64) {
    const std::vector<double> v = pack_tf<double>(t, &count, scalars);
    packed = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, v.size() * 8, v.data(),
                        "the transfer function");
  } else {
    const std::vector<float> v = pack_tf<float>(t, &count, scalars);
    packed = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, v.size() * 4, v.data(),
                        "the transfer function");
  }
  tf = packed;
  tf_count = count;
  tf_scalars[0] = scalars[0];
  tf_scalars[1] = scalars[1];
  scene.tf = t;
  tf_changed();
}

void Session::Impl::check_target(const DeviceArray& t) const {
  check_array(t, "target");
  if (t.shape() != image_shape())
    bad("target has shape " + shape_text(t.shape()) + " but the scene renders " +
        shape_text(image_shape()));
}

void Session::Impl::require_volume(const char* operation) const {
  if (!has_volume)
    bad(std::string(operation) +
        ": the session has no densities (its scene had none: set_volume first)");
}

// --- what operations share ------------------------------------------------------------------------

Integrator Session::Impl::declared_integrator() const {
  Integrator it = scene.integrator;
  if (options.step > 0) it.step = options.step;
  return it;
}

const Integrator& Session::Impl::integrator() {
  if (resolved) return *resolved;
  Integrator it = scene.integrator;
  choice = StepChoice{};
  if (options.step > 0) {
    it.step = options.step;
  } else if (it.tolerance > 0) {
    require_volume("choosing the step for integrator.tolerance");
    choice = choose_session_step(*this, it.tolerance);
    it.step = choice.step;
  }
  choice.step = it.step;
  resolved = it;
  return *resolved;
}

RenderVariant Session::Impl::variant_of(const Integrator& it) const {
  return RenderVariant::of(scene, it, options.precision);
}

int Session::Impl::set_scene_args(cl::Kernel& k, const Integrator& it) const {
  const glm::dvec3 h = scene.voxel_size();
  const double step = it.step * std::min(h.x, std::min(h.y, h.z));
  const glm::dvec3 bg = scene.effective_background();
  const ImageExtent extent = image_extent(scene);
  int a = 0;
  // (A session without densities — the out-of-core render's, lib/brick/ — sets its bricks itself.)
  if (has_volume) k.setArg(a, buffer_of(volume));
  ++a;
  k.setArg(a++, cl_int4{{scene.volume.nx, scene.volume.ny, scene.volume.nz, 0}});
  set_real4(k, a++, f64, scene.box_min.x, scene.box_min.y, scene.box_min.z);
  set_real4(k, a++, f64, scene.box_max.x, scene.box_max.y, scene.box_max.z);
  set_real4(k, a++, f64, 1 / h.x, 1 / h.y, 1 / h.z);
  k.setArg(a++, cameras);
  k.setArg(a++, cl_int(extent.width));
  k.setArg(a++, cl_int(extent.height));
  k.setArg(a++, tf);
  k.setArg(a++, cl_int(tf_count));
  set_real4(k, a++, f64, tf_scalars[0], tf_scalars[1], 0);
  set_real4(k, a++, f64, bg.x, bg.y, bg.z);
  set_real(k, a++, f64, step);
  set_real(k, a++, f64, it.min_transmittance);
  return a;
}

const cl::Buffer& Session::Impl::plan_skipping(bool allowed, RenderVariant& variant,
                                               OperationStats& stats) {
  const EmptySpace mode = options.empty_space;
  variant.empty_space = allowed && (mode == EmptySpace::on ||
                                   (mode == EmptySpace::automatic && tf_has_empty_range(scene.tf)));
  variant.brick_size = RenderVariant().brick_size;
  if (!variant.empty_space) return no_occupancy;
  // Where σ > 0 over the densities' whole range no brick can be empty: the range from the
  // volume check settles what the grid would find.
  if (mode == EmptySpace::automatic && tf_absorbs_throughout(scene.tf, volume_min, volume_max)) {
    variant.empty_space = false;
    return no_occupancy;
  }
  const int size = options.brick_size > 0 ? options.brick_size : auto_brick_size(scene.volume);
  if (grid.size != size || !grid.occupancy_fresh) {
    const auto start = std::chrono::steady_clock::now();
    if (grid.size != size) {
      grid.ranges = host_volume && !grid_on_device(dev.info)
                        ? host_brick_ranges(Volume{scene.volume.nx, scene.volume.ny,
                                                   scene.volume.nz, *host_volume, {}},
                                            size)
                        : device_brick_ranges(dev, kernels, buffer_of(volume), scene.volume, size,
                                              f64);
      grid.size = size;
    }
    grid.grid = brick_layout(scene.volume, size);
    occupy_from_ranges(grid.grid, grid.ranges, scene.tf);
    grid.occupied = dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, grid.grid.occupied.size(),
                               grid.grid.occupied.data(), "the occupancy grid");
    grid.occupancy_fresh = true;
    stats.grid_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  stats.empty_fraction = grid.grid.empty_fraction;
  if (mode == EmptySpace::automatic && grid.grid.empty_fraction < options.min_empty_fraction) {
    variant.empty_space = false;
    return no_occupancy;
  }
  variant.brick_size = size;
  return grid.occupied;
}

cl_int4 Session::Impl::brick_counts() const {
  return cl_int4{{grid.grid.nx, grid.grid.ny, grid.grid.nz, 0}};
}

DeviceArray Session::Impl::output(const std::string& slot, const std::vector<std::int64_t>& shape,
                                  DType dtype, const char* what) {
  std::vector<DeviceArray>& arrays_of_slot = pool[slot];
  for (DeviceArray& a : arrays_of_slot)
    if (a.impl().use_count() == 1 && a.impl()->shape == shape && a.impl()->dtype == dtype)
      return a;
  // None free: drop those nobody holds (another shape), keep at most a few.
  arrays_of_slot.erase(std::remove_if(arrays_of_slot.begin(), arrays_of_slot.end(),
                                      [](const DeviceArray& a) { return a.impl().use_count() == 1; }),
                       arrays_of_slot.end());
  DeviceArray fresh = make_array(device, dev, shape, dtype, what);
  if (arrays_of_slot.size() < 3) arrays_of_slot.push_back(fresh);
  return fresh;
}

const cl::Buffer& Session::Impl::scratch(const std::string& slot, std::size_t bytes,
                                         const char* what) {
  auto& entry = scratch_buffers[slot];
  if (entry.second < bytes || !entry.first()) {
    entry.first = dev.buffer(CL_MEM_READ_WRITE, std::max<std::size_t>(bytes, 1), nullptr, what);
    entry.second = std::max<std::size_t>(bytes, 1);
  }
  return entry.first;
}

cl::Buffer Session::Impl::buffer_as(const DeviceArray& a, DType dtype, const char* slot,
                                   OperationRecord& op) {
  if (a.dtype() == dtype) return buffer_of(a);
  const cl::Buffer& out = scratch(slot, a.size() * dtype_size(dtype), slot);
  op.events.push_back(arrays.convert(buffer_of(a), a.dtype(), out, dtype, a.size()));
  return out;
}

OperationRecord& Session::Impl::begin(const std::string& operation) {
  last = OperationRecord{};
  last.stats.operation = operation;
  return last;
}

std::uint64_t Session::Impl::scene_bytes() const {
  const std::uint64_t voxels = has_volume ? scene.volume.voxel_count() : 0;
  const std::uint64_t geometry = 32 * scene.cameras.size() + RayList::kColumns * scene.rays.count();
  return (voxels + geometry + 6 * std::max(tf_count, 1)) * real_size;
}

std::size_t Session::Impl::pixels() const {
  return image_extent(scene).pixels();
}

std::vector<std::int64_t> Session::Impl::image_shape() const {
  if (scene.has_ray_list()) return {std::int64_t(scene.rays.count()), scene.channels()};
  const ImageExtent e = image_extent(scene);
  return {e.views, e.height, e.width, scene.channels()};
}

std::vector<std::int64_t> Session::Impl::volume_shape() const {
  return {scene.volume.nz, scene.volume.ny, scene.volume.nx};
}

}  // namespace ivr
