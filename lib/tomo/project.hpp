// project.hpp — internal: the projector pair on the device (kernels/project.cl), on device buffers
// of the chosen precision (the solvers' vector operations: tomo/linalg.hpp).
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "ivr/session.hpp"
#include "brick/brick_layout.hpp"
#include "ivr/tomo.hpp"
#include "runtime/kernel_config.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

// A session of the scene's geometry alone (grid, box, cameras: no densities) runs the kernels.
struct Projector::Impl {
  std::unique_ptr<Session> session;
  Session::Impl& s;
  Device::Impl& dev;
  Precision precision;
  std::size_t real_size;  // 4 or 8 bytes
  int nx, ny, nz, views, width, height;
  std::size_t voxels, rays;
  cl::Program linalg_program;
  double last_seconds = 0;  // device time of the last projector kernel
  BrickLayout bricks;       // out of core (edge > 0): N and Nᵀ brick by brick (lib/brick/)

  Impl(Device& device, const Scene& scene, Precision precision);

  // A device vector of n reals (uninitialised), or of the given values.
  cl::Buffer vector(std::size_t n, const char* what) const;
  cl::Buffer upload(const std::vector<double>& values, const char* what) const;
  std::vector<double> download(const cl::Buffer& buffer, std::size_t n) const;

  // lines = N volume; volume = Nᵀ lines (overwritten). Both wait for the kernel and set
  // last_seconds.
  void project(const cl::Buffer& volume, const cl::Buffer& lines);
  void backproject(const cl::Buffer& lines, const cl::Buffer& volume);
};

// The configuration of the projector program's kernel `entry` (kernels/project.cl: project,
// backproject, and the bricks' project_brick, backproject_brick) for the session's device.
KernelConfig projector_config(Session::Impl& s, const char* entry);

// The session's projector kernels on buffers of its precision: lines = N volume; volume = Nᵀ
// lines (zeroed first; both commands' events appended). Enqueued, not waited for.
cl::Event enqueue_project(Session::Impl& s, const cl::Buffer& volume, const cl::Buffer& lines);
cl::Event enqueue_backproject(Session::Impl& s, const cl::Buffer& lines, const cl::Buffer& volume,
                              std::vector<cl::Event>& events);

}  // namespace ivr
