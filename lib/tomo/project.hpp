// projector.hpp — the projector pair on the device (kernels/project.cl) and the solvers' vector
// operations (kernels/linalg.cl), on device buffers of the chosen precision.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "ivr/session.hpp"
#include "ivr/tomo.hpp"
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

// The session's projector kernels on buffers of its precision: lines = N volume; volume = Nᵀ
// lines (zeroed first; both commands' events appended). Enqueued, not waited for.
cl::Event enqueue_project(Session::Impl& s, const cl::Buffer& volume, const cl::Buffer& lines);
cl::Event enqueue_backproject(Session::Impl& s, const cl::Buffer& lines, const cl::Buffer& volume,
                              std::vector<cl::Event>& events);

// The vector operations of kernels/linalg.cl on device vectors of one precision.
class DeviceVectors {
 public:
  explicit DeviceVectors(Projector::Impl& p);
  void fill(const cl::Buffer& x, std::size_t n, double value);
  void copy(const cl::Buffer& from, const cl::Buffer& to, std::size_t n);
  void axpy(std::size_t n, double a, const cl::Buffer& x, const cl::Buffer& y);   // y += a·x
  void xpby(std::size_t n, const cl::Buffer& x, double b, const cl::Buffer& y);   // y = x + b·y
  void scale(std::size_t n, double a, const cl::Buffer& x, const cl::Buffer& y);  // y = a·x
  void multiply(std::size_t n, const cl::Buffer& x, const cl::Buffer& y);         // y = x ⊙ y
  void safe_reciprocal(std::size_t n, const cl::Buffer& x);  // x = 1/x where x > 0, else 0
  double dot(std::size_t n, const cl::Buffer& x, const cl::Buffer& y);
  double norm(std::size_t n, const cl::Buffer& x);
  double clamp_nonneg(std::size_t n, const cl::Buffer& x);  // returns the total removed
  // TV's weighted forward differences (3 per voxel), their transpose (out += a·Dᵀ(sw ⊙ g)), and
  // the lagged-diffusivity weights of x scaled by sqrt(λ).
  void tv_forward(const cl::Buffer& x, const cl::Buffer& sw, const cl::Buffer& out);
  void tv_adjoint(double a, const cl::Buffer& g, const cl::Buffer& sw, const cl::Buffer& out);
  void tv_weights(double epsilon, double lambda, const cl::Buffer& x, const cl::Buffer& sw);

 private:
  Projector::Impl& p_;
  cl::Kernel axpy_, xpby_, scale_, multiply_, reciprocal_, clamp_, dot_, tv_forward_, tv_adjoint_,
      tv_weights_;
  cl::Buffer partial_;
  std::vector<double> partial_host_;
  void run(cl::Kernel& k, std::size_t n, const char* what);
  double sum_partials();
};

}  // namespace ivr
