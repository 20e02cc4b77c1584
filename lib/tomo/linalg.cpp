// linalg.cpp — the tomography solvers' vector operations (kernels/linalg.cl) on device vectors of
// the projector's precision; reductions end in partial sums that the host adds in double.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "tomo/linalg.hpp"
#include "runtime/real_args.hpp"

namespace ivr {

namespace {
constexpr std::size_t kPartials = 4096;  // work-items of a reduction (each a strided partial sum)
}

DeviceVectors::DeviceVectors(Projector::Impl& p) : p_(p), partial_host_(kPartials) {
  cl_call("setting up the vector kernels", [&] {
    const cl::Program& prog = p.linalg_program;
    axpy_ = cl::Kernel(prog, "axpy");
    xpby_ = cl::Kernel(prog, "xpby");
    scale_ = cl::Kernel(prog, "scale_copy");
    multiply_ = cl::Kernel(prog, "multiply");
    reciprocal_ = cl::Kernel(prog, "safe_reciprocal");
    clamp_ = cl::Kernel(prog, "clamp_nonneg");
    dot_ = cl::Kernel(prog, "dot_partial");
    tv_forward_ = cl::Kernel(prog, "tv_forward");
    tv_adjoint_ = cl::Kernel(prog, "tv_adjoint");
    tv_weights_ = cl::Kernel(prog, "tv_weights");
    tv_diagonal_ = cl::Kernel(prog, "tv_diagonal");
  });
  partial_ = p.vector(kPartials, "the partial sums");
}

void DeviceVectors::run(cl::Kernel& k, std::size_t n, const char* what) {
  cl_call(std::string("running ") + what + " on " + p_.dev.info.name, [&] {
    p_.dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(std::max<std::size_t>(n, 1)),
                                      cl::NullRange);
  });
}

double DeviceVectors::sum_partials() {
  const std::vector<double> partial = p_.download(partial_, kPartials);
  return std::accumulate(partial.begin(), partial.end(), 0.0);
}

void DeviceVectors::fill(const cl::Buffer& x, std::size_t n, double value) {
  cl_call("filling a device vector", [&] {
    if (p_.precision == Precision::f64)
      p_.dev.queue.enqueueFillBuffer(x, cl_double(value), 0, n * 8);
    else
      p_.dev.queue.enqueueFillBuffer(x, cl_float(value), 0, n * 4);
  });
}

void DeviceVectors::copy(const cl::Buffer& from, const cl::Buffer& to, std::size_t n) {
  cl_call("copying a device vector",
          [&] { p_.dev.queue.enqueueCopyBuffer(from, to, 0, 0, n * p_.real_size); });
}

void DeviceVectors::axpy(std::size_t n, double a, const cl::Buffer& x, const cl::Buffer& y) {
  axpy_.setArg(0, cl_int(n));
  set_real(axpy_, 1, p_.real_size == 8, a);
  axpy_.setArg(2, x);
  axpy_.setArg(3, y);
  run(axpy_, n, "axpy");
}

void DeviceVectors::xpby(std::size_t n, const cl::Buffer& x, double b, const cl::Buffer& y) {
  xpby_.setArg(0, cl_int(n));
  xpby_.setArg(1, x);
  set_real(xpby_, 2, p_.real_size == 8, b);
  xpby_.setArg(3, y);
  run(xpby_, n, "xpby");
}

void DeviceVectors::scale(std::size_t n, double a, const cl::Buffer& x, const cl::Buffer& y) {
  scale_.setArg(0, cl_int(n));
  set_real(scale_, 1, p_.real_size == 8, a);
  scale_.setArg(2, x);
  scale_.setArg(3, y);
  run(scale_, n, "scale_copy");
}

void DeviceVectors::multiply(std::size_t n, const cl::Buffer& x, const cl::Buffer& y) {
  multiply_.setArg(0, cl_int(n));
  multiply_.setArg(1, x);
  multiply_.setArg(2, y);
  run(multiply_, n, "multiply");
}

void DeviceVectors::safe_reciprocal(std::size_t n, const cl::Buffer& x) {
  reciprocal_.setArg(0, cl_int(n));
  reciprocal_.setArg(1, x);
  run(reciprocal_, n, "safe_reciprocal");
}

double DeviceVectors::dot(std::size_t n, const cl::Buffer& x, const cl::Buffer& y) {
  dot_.setArg(0, cl_int(n));
  dot_.setArg(1, x);
  dot_.setArg(2, y);
  dot_.setArg(3, partial_);
  run(dot_, kPartials, "dot_partial");
  return sum_partials();
}

double DeviceVectors::norm(std::size_t n, const cl::Buffer& x) {
  return std::sqrt(std::max(0.0, dot(n, x, x)));
}

double DeviceVectors::clamp_nonneg(std::size_t n, const cl::Buffer& x) {
  clamp_.setArg(0, cl_int(n));
  clamp_.setArg(1, x);
  clamp_.setArg(2, partial_);
  run(clamp_, kPartials, "clamp_nonneg");
  return sum_partials();
}

void DeviceVectors::tv_forward(const cl::Buffer& x, const cl::Buffer& sw, const cl::Buffer& out) {
  tv_forward_.setArg(0, cl_int4{{p_.nx, p_.ny, p_.nz, 0}});
  tv_forward_.setArg(1, x);
  tv_forward_.setArg(2, sw);
  tv_forward_.setArg(3, out);
  run(tv_forward_, p_.voxels, "tv_forward");
}

void DeviceVectors::tv_adjoint(double a, const cl::Buffer& g, const cl::Buffer& sw,
                               const cl::Buffer& out) {
  tv_adjoint_.setArg(0, cl_int4{{p_.nx, p_.ny, p_.nz, 0}});
  set_real(tv_adjoint_, 1, p_.real_size == 8, a);
  tv_adjoint_.setArg(2, g);
  tv_adjoint_.setArg(3, sw);
  tv_adjoint_.setArg(4, out);
  run(tv_adjoint_, p_.voxels, "tv_adjoint");
}

void DeviceVectors::tv_weights(double epsilon, double lambda, const cl::Buffer& x,
                               const cl::Buffer& sw) {
  tv_weights_.setArg(0, cl_int4{{p_.nx, p_.ny, p_.nz, 0}});
  set_real(tv_weights_, 1, p_.real_size == 8, epsilon);
  set_real(tv_weights_, 2, p_.real_size == 8, std::sqrt(lambda));
  tv_weights_.setArg(3, x);
  tv_weights_.setArg(4, sw);
  run(tv_weights_, p_.voxels, "tv_weights");
}

void DeviceVectors::tv_diagonal(const cl::Buffer& sw, const cl::Buffer& base,
                                const cl::Buffer& out) {
  tv_diagonal_.setArg(0, cl_int4{{p_.nx, p_.ny, p_.nz, 0}});
  tv_diagonal_.setArg(1, sw);
  tv_diagonal_.setArg(2, base);
  tv_diagonal_.setArg(3, out);
  run(tv_diagonal_, p_.voxels, "tv_diagonal");
}

}  // namespace ivr
