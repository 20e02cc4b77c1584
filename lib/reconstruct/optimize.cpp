// optimize.cpp — Adam and SGD with momentum on the device (kernels/optimize.cl): options and
// schedules, the moments' buffers, one step per call, and the state for checkpoints.
#include "reconstruct/optimize.hpp"

#include <cmath>

#include "ivr/error.hpp"
#include "runtime/launch.hpp"
#include "runtime/real_args.hpp"
#include "scene/scene.hpp"

namespace ivr {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

}  // namespace

const char* optimizer_name(OptimizerKind kind) {
  switch (kind) {
    case OptimizerKind::adam:
      return "adam";
    case OptimizerKind::sgd:
      return "sgd";
    case OptimizerKind::lbfgs:
      return "lbfgs";
  }
  return "?";
}

const char* schedule_name(Schedule schedule) {
  switch (schedule) {
    case Schedule::constant:
      return "constant";
    case Schedule::step:
      return "step";
    case Schedule::cosine:
      return "cosine";
  }
  return "?";
}

OptimizerKind parse_optimizer(const std::string& name, const std::string& where) {
  for (OptimizerKind k : {OptimizerKind::adam, OptimizerKind::sgd, OptimizerKind::lbfgs})
    if (name == optimizer_name(k)) return k;
  fail(where + ": unknown optimizer '" + name + "' (known: adam, sgd, lbfgs)");
}

Schedule parse_schedule(const std::string& name, const std::string& where) {
  for (Schedule s : {Schedule::constant, Schedule::step, Schedule::cosine})
    if (name == schedule_name(s)) return s;
  fail(where + ": unknown schedule '" + name + "' (known: constant, step, cosine)");
}

void validate_optimizer(const OptimizerOptions& o) {
  if (!(o.lr > 0) || !std::isfinite(o.lr))
    fail("lr must be > 0 and finite, got " + number_text(o.lr));
  if (!(o.beta1 >= 0 && o.beta1 < 1)) fail("beta1 must be in [0, 1), got " + number_text(o.beta1));
  if (!(o.beta2 >= 0 && o.beta2 < 1)) fail("beta2 must be in [0, 1), got " + number_text(o.beta2));
  if (!(o.epsilon > 0) || !std::isfinite(o.epsilon))
    fail("epsilon must be > 0, got " + number_text(o.epsilon));
  if (!(o.momentum >= 0 && o.momentum < 1))
    fail("momentum must be in [0, 1), got " + number_text(o.momentum));
  if (o.history < 1) fail("history must be >= 1, got " + std::to_string(o.history));
  if (std::isnan(o.lower) || std::isnan(o.upper) || !(o.lower <= o.upper))
    fail("the bounds need lower <= upper, got [" + number_text(o.lower) + ", " +
         number_text(o.upper) + "]");
  if (o.schedule == Schedule::step) {
    if (o.step_every < 1) fail("step_every must be >= 1, got " + std::to_string(o.step_every));
    if (!(o.step_gamma > 0 && o.step_gamma <= 1))
      fail("step_gamma must be in (0, 1], got " + number_text(o.step_gamma));
  }
  if (o.schedule == Schedule::cosine) {
    if (o.total_iterations < 1)
      fail("the cosine schedule needs total_iterations >= 1, got " +
           std::to_string(o.total_iterations));
    if (!(o.min_lr >= 0 && o.min_lr <= o.lr))
      fail("min_lr must be in [0, lr], got " + number_text(o.min_lr));
  }
}

double learning_rate(const OptimizerOptions& o, int k) {
  switch (o.schedule) {
    case Schedule::constant:
      return o.lr;
    case Schedule::step:
      return o.lr * std::pow(o.step_gamma, double(k / o.step_every));
    case Schedule::cosine: {
      if (k >= o.total_iterations) return o.min_lr;
      const double pi = 3.14159265358979323846;
      return o.min_lr + (o.lr - o.min_lr) * 0.5 * (1 + std::cos(pi * k / o.total_iterations));
    }
  }
  return o.lr;
}

Optimizer::Impl::Impl(Device::Impl& device, std::size_t n, const OptimizerOptions& o,
                      Precision precision)
    : dev(device), options(o), count(n), f64(precision == Precision::f64) {
  validate_optimizer(o);
  if (o.kind == OptimizerKind::lbfgs)
    fail(
        "lbfgs runs on the host with a line search (ivr::reconstruct, ivr::select_viewpoint); "
        "ivr::Optimizer runs adam and sgd");
  if (n == 0 || n > 2147483647u)
    fail("an optimizer needs 1 .. 2^31 - 1 parameters, got " + std::to_string(n));
  if (f64 && !dev.info.fp64)
    throw Error(Status::unsupported,
                "device " + dev.info.name + " has no float64 support (cl_khr_fp64)");
  KernelConfig config("optimize.cl", o.kind == OptimizerKind::adam ? "adam_step" : "sgd_step");
  config.set(Switch::f64, f64);
  const cl::Program program = program_for(dev, config);
  const std::vector<double> zeros(n, 0.0);
  first = upload_reals(dev, f64, zeros, "the optimizer's first moments");
  if (o.kind == OptimizerKind::adam)
    second = upload_reals(dev, f64, zeros, "the optimizer's second moments");
  cl_call("setting up the optimizer kernel", [&] {
    kernel = cl::Kernel(program, config.entry.c_str());
  });
}

cl::Event Optimizer::Impl::step(const cl::Buffer& x, const cl::Buffer& g) {
  const OptimizerOptions& o = options;
  const double lr = learning_rate(o, iterations);
  ++iterations;
  return cl_call("running the optimizer step on " + dev.info.name, [&] {
    cl_uint a = 0;
    kernel.setArg(a++, cl_int(count));
    set_real(kernel, a++, f64, lr);
    if (o.kind == OptimizerKind::adam) {
      set_real(kernel, a++, f64, o.beta1);
      set_real(kernel, a++, f64, o.beta2);
      set_real(kernel, a++, f64, o.epsilon);
      set_real(kernel, a++, f64, 1 - std::pow(o.beta1, iterations));
      set_real(kernel, a++, f64, 1 - std::pow(o.beta2, iterations));
    } else {
      set_real(kernel, a++, f64, o.momentum);
    }
    set_real(kernel, a++, f64, o.lower);
    set_real(kernel, a++, f64, o.upper);
    kernel.setArg(a++, x);
    kernel.setArg(a++, g);
    kernel.setArg(a++, first);
    if (o.kind == OptimizerKind::adam) kernel.setArg(a++, second);
    return enqueue_1d(dev, kernel, count);
  });
}

Optimizer::Optimizer(Device& device, std::size_t count, const OptimizerOptions& options,
                     Precision precision)
    : impl_(std::make_unique<Impl>(device.impl(), count, options, precision)) {}
Optimizer::~Optimizer() = default;
Optimizer::Optimizer(Optimizer&&) noexcept = default;
Optimizer& Optimizer::operator=(Optimizer&&) noexcept = default;

int Optimizer::iterations() const {
  return impl_->iterations;
}

void Optimizer::step(std::vector<double>& params, const std::vector<double>& grad) {
  Impl& p = *impl_;
  if (params.size() != p.count || grad.size() != p.count)
    fail("optimizer step: " + std::to_string(params.size()) + " parameters and " +
         std::to_string(grad.size()) + " gradient values for an optimizer of " +
         std::to_string(p.count));
  const cl::Buffer x = upload_reals(p.dev, p.f64, params, "the parameters");
  const cl::Buffer g = upload_reals(p.dev, p.f64, grad, "the gradient");
  p.step(x, g);
  params = download_reals(p.dev, p.f64, x, p.count);
}

Optimizer::State Optimizer::state() const {
  const Impl& p = *impl_;
  State s;
  s.iterations = p.iterations;
  s.first = download_reals(p.dev, p.f64, p.first, p.count);
  if (p.options.kind == OptimizerKind::adam)
    s.second = download_reals(p.dev, p.f64, p.second, p.count);
  return s;
}

void Optimizer::restore(const State& s) {
  Impl& p = *impl_;
  const bool adam = p.options.kind == OptimizerKind::adam;
  if (s.iterations < 0 || s.first.size() != p.count || s.second.size() != (adam ? p.count : 0))
    fail("optimizer state: it does not fit this optimizer (" + std::to_string(p.count) + " " +
         optimizer_name(p.options.kind) + " parameters)");
  p.first = upload_reals(p.dev, p.f64, s.first, "the optimizer's first moments");
  if (adam) p.second = upload_reals(p.dev, p.f64, s.second, "the optimizer's second moments");
  p.iterations = s.iterations;
}

}  // namespace ivr
