// project.cpp — the projector pair N / Nᵀ (kernels/project.cl): scene geometry packed for the
// device, one work-item per ray, host-vector and device-buffer entry points.
#include <algorithm>
#include <cmath>

#include "device_params.hpp"
#include "device_scene.hpp"
#include "ivr/error.hpp"
#include "kernel_sources.hpp"
#include "projector.hpp"
#include "real_args.hpp"
#include "scene_checks.hpp"

namespace ivr {

namespace {

// The grid, box and cameras must make sense; the model, TF, integrator and values do not matter.
void check_geometry(const Scene& scene) {
  validate_geometry(scene);
  if (double(scene.volume.nx) * scene.volume.ny * scene.volume.nz > 2147483647.0)
    throw Error(Status::invalid_argument, "projector: the volume holds more than 2^31 voxels");
}

}  // namespace

Projector::Impl::Impl(Device::Impl& device, const Scene& scene, Precision prec)
    : dev(device), precision(prec), real_size(prec == Precision::f64 ? 8 : 4) {
  check_geometry(scene);
  if (precision == Precision::f64 && !dev.info.fp64)
    throw Error(Status::unsupported,
                "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
  nx = scene.volume.nx, ny = scene.volume.ny, nz = scene.volume.nz;
  views = int(scene.cameras.size());
  width = scene.cameras.front().width;
  height = scene.cameras.front().height;
  voxels = std::size_t(nx) * ny * nz;
  rays = std::size_t(views) * width * height;
  if (double(rays) > 2147483647.0)
    throw Error(Status::invalid_argument, "projector: the cameras have more than 2^31 rays");

  const bool f64 = precision == Precision::f64;
  if (f64) {
    const std::vector<double> cams = pack_cameras<double>(scene.cameras);
    cameras = dev.buffer(CL_MEM_READ_ONLY, cams.size() * 8, cams.data(), "the cameras");
  } else {
    const std::vector<float> cams = pack_cameras<float>(scene.cameras);
    cameras = dev.buffer(CL_MEM_READ_ONLY, cams.size() * 4, cams.data(), "the cameras");
  }
  const bool native_atomics = use_float_atomics(dev.info, f64);
  std::string preamble =
      std::string("#define IVR_MODEL 0\n#define IVR_TF 0\n#define IVR_SCHEME 2\n") +
      "#define IVR_F64 " + (f64 ? "1" : "0") + "\n";
  std::string options = extra_build_options();
  if (native_atomics) {
    preamble += "#define IVR_FLOAT_ATOMICS 1\n";
    options = "-cl-std=" + dev.info.atomics_std + " " + options;
  }
  const std::string tag =
      std::string(f64 ? "f64" : "f32") + (native_atomics ? " float_atomics" : "");
  const cl::Program program =
      dev.programs.get(dev.context, dev.device, dev.info, preamble + assemble_kernel("project.cl"),
                       options, "project.cl [" + tag + "]");
  linalg_program = dev.programs.get(
      dev.context, dev.device, dev.info,
      std::string("#define IVR_F64 ") + (f64 ? "1" : "0") + "\n" + assemble_kernel("linalg.cl"),
      extra_build_options(), std::string("linalg.cl [") + (f64 ? "f64" : "f32") + "]");

  const glm::dvec3 h = scene.voxel_size();
  cl_call("setting up the projector kernels", [&] {
    project_kernel = cl::Kernel(program, "project");
    backproject_kernel = cl::Kernel(program, "backproject");
    for (cl::Kernel* k : {&project_kernel, &backproject_kernel}) {
      k->setArg(1, cl_int4{{nx, ny, nz, 0}});
      set_real4(*k, 2, f64, scene.box_min.x, scene.box_min.y, scene.box_min.z);
      set_real4(*k, 3, f64, scene.box_max.x, scene.box_max.y, scene.box_max.z);
      set_real4(*k, 4, f64, 1 / h.x, 1 / h.y, 1 / h.z);
      k->setArg(5, cameras);
      k->setArg(6, cl_int(width));
      k->setArg(7, cl_int(height));
    }
  });
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

void Projector::Impl::run_rays(cl::Kernel& kernel, const char* what) {
  cl::Event done;
  cl_call(std::string("running the ") + what + " on " + dev.info.name, [&] {
    const LaunchParams launch = launch_params(dev.info, "project");
    if (launch.local_x > 0) {  // global size rounded up; the kernels skip the padding
      const int lx = launch.local_x, ly = launch.local_y;
      dev.queue.enqueueNDRangeKernel(
          kernel, cl::NullRange,
          cl::NDRange((width + lx - 1) / lx * lx, (height + ly - 1) / ly * ly, views),
          cl::NDRange(lx, ly, 1), nullptr, &done);
    } else {
      dev.queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(width, height, views),
                                     cl::NullRange, nullptr, &done);
    }
    done.wait();
  });
  last_seconds = event_seconds(done);
}

void Projector::Impl::project(const cl::Buffer& volume, const cl::Buffer& lines) {
  project_kernel.setArg(0, volume);
  project_kernel.setArg(8, lines);
  run_rays(project_kernel, "projector");
}

void Projector::Impl::backproject(const cl::Buffer& lines, const cl::Buffer& volume) {
  cl::Event done;
  cl_call("running the back-projector on " + dev.info.name, [&] {
    const double zero = 0;  // all-zero bits in either precision
    dev.queue.enqueueFillBuffer(volume, cl_uchar(zero), 0, voxels * real_size);
    backproject_kernel.setArg(0, lines);
    backproject_kernel.setArg(8, volume);
    dev.queue.enqueueNDRangeKernel(backproject_kernel, cl::NullRange,
                                   cl::NDRange(width, height, views), cl::NullRange, nullptr,
                                   &done);
    done.wait();
  });
  last_seconds = event_seconds(done);
}

Projector::Projector(Device& device, const Scene& scene, Precision precision)
    : impl_(std::make_unique<Impl>(device.impl(), scene, precision)) {}
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
double Projector::last_kernel_seconds() const {
  return impl_->last_seconds;
}

std::vector<double> Projector::project(const std::vector<double>& volume) const {
  if (volume.size() != impl_->voxels)
    throw Error(Status::invalid_argument, "project: the volume has " +
                                              std::to_string(volume.size()) + " values, the grid " +
                                              std::to_string(impl_->voxels));
  const cl::Buffer v = impl_->upload(volume, "the volume");
  const cl::Buffer lines = impl_->vector(impl_->rays, "the line integrals");
  impl_->project(v, lines);
  return impl_->download(lines, impl_->rays);
}

std::vector<double> Projector::backproject(const std::vector<double>& lines) const {
  if (lines.size() != impl_->rays)
    throw Error(Status::invalid_argument, "backproject: " + std::to_string(lines.size()) +
                                              " values for " + std::to_string(impl_->rays) +
                                              " rays (views × height × width)");
  const cl::Buffer p = impl_->upload(lines, "the projections");
  const cl::Buffer v = impl_->vector(impl_->voxels, "the back-projection");
  impl_->backproject(p, v);
  return impl_->download(v, impl_->voxels);
}

}  // namespace ivr
