// project.cpp — the projector pair N / Nᵀ (kernels/project.cl) on a session's geometry: one
// work-item per ray; the session's project / backproject on device arrays, and the Projector
// (host vectors and the tomography solvers' device buffers) over a session of its own.
#include <algorithm>
#include <cmath>

#include "ivr/error.hpp"
#include "tomo/project.hpp"

#include "brick/bricked_project.hpp"
#include "runtime/real_args.hpp"
#include "runtime/variants.hpp"
#include "adjoint/scatter_cache.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"

namespace ivr {

namespace {

[[noreturn]] void bad(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

// Whether the back-projector sums each work-group's adds in local memory first
// (lib/adjoint/scatter_cache.hpp); the table is its only local memory.
bool backproject_cache(Session::Impl& s) {
  return scatter_cache_for(s.dev, s.real_size, 0);
}

}  // namespace

// N and Nᵀ share one program: the scatter cache's define changes Nᵀ alone.
KernelConfig projector_config(Session::Impl& s, const char* entry) {
  // Absorption line integrals, evaluated exactly (the exact scheme's splitting): no TF.
  RenderVariant v;
  v.model = Model::absorption;
  v.tf = TfKind::identity;
  v.scheme = Scheme::exact;
  v.precision = s.f64 ? Precision::f64 : Precision::f32;
  v.ray_list = s.scene.has_ray_list();
  KernelConfig c = v.config("project.cl", entry);
  return with_scatter_cache(c.with_atomics(atomic_add_for(s.dev.info, s.f64)),
                            backproject_cache(s));
}

namespace {

// The grid and cameras of the ray kernels (arguments 1 … 7 of project and backproject).
void set_geometry(const Session::Impl& s, cl::Kernel& k) {
  const Scene& scene = s.scene;
  const glm::dvec3 h = scene.voxel_size();
  k.setArg(1, cl_int4{{scene.volume.nx, scene.volume.ny, scene.volume.nz, 0}});
  set_real4(k, 2, s.f64, scene.box_min.x, scene.box_min.y, scene.box_min.z);
  set_real4(k, 3, s.f64, scene.box_max.x, scene.box_max.y, scene.box_max.z);
  set_real4(k, 4, s.f64, 1 / h.x, 1 / h.y, 1 / h.z);
  k.setArg(5, s.cameras);
  const ImageExtent e = image_extent(scene);
  k.setArg(6, cl_int(e.width));
  k.setArg(7, cl_int(e.height));
}

void check_projector_size(const Scene& scene) {
  if (double(scene.volume.nx) * scene.volume.ny * scene.volume.nz > 2147483647.0)
    bad("projector: the volume holds more than 2^31 voxels");
  if (double(image_extent(scene).pixels()) > 2147483647.0)
    bad("projector: the cameras have more than 2^31 rays");
}

// The lines' shape: the image's with one channel ((views, H, W, 1); a ray list's (rays, 1)).
std::vector<std::int64_t> line_shape(const Session::Impl& s) {
  std::vector<std::int64_t> shape = s.image_shape();
  shape.back() = 1;
  return shape;
}

// Lines N v of `volume` (reals) into a new result array.
DeviceArray project_into_lines(Session::Impl& s, const cl::Buffer& volume, OperationRecord& op) {
  DeviceArray lines = s.output("lines", line_shape(s), real_dtype(s.f64), "the lines");
  op.events.push_back(enqueue_project(s, volume, buffer_of(lines)));
  mark_written(lines, op.events.back());
  return lines;
}

}  // namespace

cl::Event enqueue_project(Session::Impl& s, const cl::Buffer& volume, const cl::Buffer& lines) {
  check_projector_size(s.scene);
  return cl_call("running the projector on " + s.dev.info.name, [&] {
    cl::Kernel& k = s.kernels.get(projector_config(s, "project"));
    k.setArg(0, volume);
    set_geometry(s, k);
    k.setArg(8, lines);
    const ImageExtent c = image_extent(s.scene);
    return enqueue(s.dev, k, pixel_launch(s.dev, k, "project", c.width, c.height, c.views, false));
  });
}

cl::Event enqueue_backproject(Session::Impl& s, const cl::Buffer& lines, const cl::Buffer& volume,
                              std::vector<cl::Event>& events) {
  check_projector_size(s.scene);
  return cl_call("running the back-projector on " + s.dev.info.name, [&] {
    events.push_back(cl::Event());
    s.dev.queue.enqueueFillBuffer(volume, cl_uchar(0), 0,
                                  s.scene.volume.voxel_count() * s.real_size, nullptr,
                                  &events.back());
    const bool cache = backproject_cache(s);
    cl::Kernel& k = s.kernels.get(projector_config(s, "backproject"));
    k.setArg(0, lines);
    set_geometry(s, k);
    k.setArg(8, volume);
    const ImageExtent c = image_extent(s.scene);
    // The table is a work-group's: the groups are tiles of one view, with padding items.
    events.push_back(enqueue(s.dev, k,
                             pixel_launch(s.dev, k, "backproject", c.width, c.height, c.views,
                                          cache)));
    return events.back();
  });
}

DeviceArray Session::project() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.require_volume("project");
  return project_into_lines(s, buffer_of(s.volume), s.begin("project"));
}

DeviceArray Session::project(const DeviceArray& volume) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.check_array(volume, "project: volume");
  if (volume.shape() != s.volume_shape())
    bad("project: the volume has shape " + shape_text(volume.shape()) + "; the grid is " +
        shape_text(s.volume_shape()));
  OperationRecord& op = s.begin("project");
  return project_into_lines(s, s.buffer_as(volume, real_dtype(s.f64), "the projected volume", op),
                            op);
}

DeviceArray Session::backproject(const DeviceArray& lines) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& s = *impl_;
  s.check_array(lines, "backproject: lines");
  const std::vector<std::int64_t> want = line_shape(s);
  if (lines.shape() != want)
    bad("backproject: the lines have shape " + shape_text(lines.shape()) +
        "; the cameras' rays are " + shape_text(want));
  OperationRecord& op = s.begin("backproject");
  DeviceArray out =
      s.output("backprojection", s.volume_shape(), real_dtype(s.f64), "the back-projection");
  const cl::Buffer p = s.buffer_as(lines, real_dtype(s.f64), "the back-projected lines", op);
  enqueue_backproject(s, p, buffer_of(out), op.events);
  mark_written(out, op.events.back());
  return out;
}

// --- the Projector: a session of the scene's geometry alone -------------------------------------

namespace {
// The grid, box and cameras; the model, TF, integrator and values do not matter to N.
Scene geometry_of(const Scene& scene) {
  Scene g = description_of(scene);
  g.model = Model::absorption;
  g.tf = TransferFunction();
  g.background.reset();
  g.integrator = Integrator();
  return g;
}

std::unique_ptr<Session> geometry_session(Device& device, const Scene& scene, Precision precision) {
  validate_geometry(scene);
  check_projector_size(scene);
  SessionOptions o;
  o.precision = precision;
  return std::make_unique<Session>(device, geometry_of(scene), o);
}
}  // namespace

Projector::Impl::Impl(Device& device, const Scene& scene, Precision prec)
    : session(geometry_session(device, scene, prec)),
      s(session->impl()),
      dev(device.impl()),
      precision(prec),
      real_size(prec == Precision::f64 ? 8 : 4) {
  nx = scene.volume.nx, ny = scene.volume.ny, nz = scene.volume.nz;
  const ImageExtent extent = image_extent(scene);
  views = extent.views;
  width = extent.width;
  height = extent.height;
  voxels = std::size_t(nx) * ny * nz;
  rays = std::size_t(views) * width * height;
  bricks = plan_projector(device, scene, prec);
  KernelConfig linalg("linalg.cl", "");
  linalg.set(Switch::f64, s.f64);
  linalg_program = program_for(dev, linalg);
}

cl::Buffer Projector::Impl::vector(std::size_t n, const char* what) const {
  return dev.buffer(CL_MEM_READ_WRITE, std::max<std::size_t>(n, 1) * real_size, nullptr, what);
}

cl::Buffer Projector::Impl::upload(const std::vector<double>& values, const char* what) const {
  return upload_reals(dev, precision == Precision::f64, values, what);
}

std::vector<double> Projector::Impl::download(const cl::Buffer& buffer, std::size_t n) const {
  return download_reals(dev, precision == Precision::f64, buffer, n);
}

void Projector::Impl::project(const cl::Buffer& volume, const cl::Buffer& lines) {
  const cl::Event done = enqueue_project(s, volume, lines);
  cl_call("waiting for the projector", [&] {
    done.wait();
    last_seconds = event_seconds(done);
  });
}

void Projector::Impl::backproject(const cl::Buffer& lines, const cl::Buffer& volume) {
  std::vector<cl::Event> events;
  const cl::Event done = enqueue_backproject(s, lines, volume, events);
  cl_call("waiting for the back-projector", [&] {
    done.wait();
    last_seconds = event_seconds(done);
  });
}

Projector::Projector(Device& device, const Scene& scene, Precision precision)
    : impl_(std::make_unique<Impl>(device, scene, precision)) {}
Projector::~Projector() = default;
Projector::Projector(Projector&&) noexcept = default;
Projector& Projector::operator=(Projector&&) noexcept = default;

std::size_t Projector::voxel_count() const {
  return impl_->voxels;
}
std::size_t Projector::ray_count() const {
  return impl_->rays;
}
int Projector::views() const {
  return impl_->views;
}
int Projector::height() const {
  return impl_->height;
}
int Projector::width() const {
  return impl_->width;
}
Precision Projector::precision() const {
  return impl_->precision;
}
int Projector::bricks() const {
  return impl_->bricks.edge ? impl_->bricks.total() : 1;
}
double Projector::last_kernel_seconds() const {
  return impl_->last_seconds;
}

std::vector<double> Projector::project(const std::vector<double>& volume) const {
  if (volume.size() != impl_->voxels)
    bad("project: the volume has " + std::to_string(volume.size()) + " values, the grid " +
        std::to_string(impl_->voxels));
  if (impl_->bricks.edge) return project_bricked(*impl_, impl_->bricks, volume.data());
  const cl::Buffer v = impl_->upload(volume, "the volume");
  const cl::Buffer lines = impl_->vector(impl_->rays, "the line integrals");
  impl_->project(v, lines);
  return impl_->download(lines, impl_->rays);
}

std::vector<double> Projector::backproject(const std::vector<double>& lines) const {
  if (lines.size() != impl_->rays)
    bad("backproject: " + std::to_string(lines.size()) + " values for " +
        std::to_string(impl_->rays) + " rays (views × height × width)");
  if (impl_->bricks.edge) {
    std::vector<double> volume(impl_->voxels);
    backproject_bricked(*impl_, impl_->bricks, lines, volume.data());
    return volume;
  }
  const cl::Buffer p = impl_->upload(lines, "the projections");
  const cl::Buffer v = impl_->vector(impl_->voxels, "the back-projection");
  impl_->backproject(p, v);
  return impl_->download(v, impl_->voxels);
}

}  // namespace ivr
