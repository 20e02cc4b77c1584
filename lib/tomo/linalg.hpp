// linalg.hpp — internal: the solvers' vector operations (kernels/linalg.cl) on the device vectors
// of a projector, in its precision.
#pragma once
#include <vector>

#include "tomo/project.hpp"

namespace ivr {

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
  // out = base + 2·diag(LᵀL) of the TV rows with weights sw (kernels/linalg.cl).
  void tv_diagonal(const cl::Buffer& sw, const cl::Buffer& base, const cl::Buffer& out);

 private:
  Projector::Impl& p_;
  cl::Kernel axpy_, xpby_, scale_, multiply_, reciprocal_, clamp_, dot_, tv_forward_, tv_adjoint_,
      tv_weights_, tv_diagonal_;
  cl::Buffer partial_;
  std::vector<double> partial_host_;
  void run(cl::Kernel& k, std::size_t n, const char* what);
  double sum_partials();
};

}  // namespace ivr
