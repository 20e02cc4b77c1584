// ivr/optimize.hpp — first-order optimisers on the device (Adam, SGD with momentum) with
// learning-rate schedules and box constraints: the update step of ivr's reconstructions.
#pragma once
#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/render.hpp"

namespace ivr {

// lbfgs: limited-memory BFGS with projected backtracking line searches on the host, for small
// parameter sets (transfer functions, viewpoints) and full batches (see ivr/reconstruct.hpp);
// ivr::Optimizer runs adam and sgd.
enum class OptimizerKind { adam, sgd, lbfgs };
// constant: lr; step: lr·γ^⌊k / step_every⌋; cosine: min_lr + (lr − min_lr)·(1 + cos(π k / K))/2
// over K = total_iterations (then min_lr), k the 0-based iteration.
enum class Schedule { constant, step, cosine };

struct OptimizerOptions {
  OptimizerKind kind = OptimizerKind::adam;
  double lr = 1e-2;
  Schedule schedule = Schedule::constant;
  int step_every = 100;                               // step schedule
  double step_gamma = 0.5;                            // step schedule, in (0, 1]
  int total_iterations = 0;                           // cosine schedule (K >= 1)
  double min_lr = 0;                                  // cosine schedule, in [0, lr]
  double beta1 = 0.9, beta2 = 0.999, epsilon = 1e-8;  // Adam
  double momentum = 0.9;                              // SGD, in [0, 1)
  int history = 10;                                   // L-BFGS: curvature pairs kept (>= 1)
  // Every parameter is projected onto [lower, upper] after each step (lower = 0: densities).
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
};

IVR_API const char* optimizer_name(OptimizerKind kind);
IVR_API const char* schedule_name(Schedule schedule);
// By name ("adam", "sgd", "lbfgs"; "constant", "step", "cosine"); ivr::Error(invalid_argument)
// naming `where` and the known ones.
IVR_API OptimizerKind parse_optimizer(const std::string& name,
                                      const std::string& where = "optimizer");
IVR_API Schedule parse_schedule(const std::string& name, const std::string& where = "schedule");
// Throws ivr::Error(invalid_argument) naming the first bad option (lr ≤ 0, β outside [0, 1), …).
IVR_API void validate_optimizer(const OptimizerOptions& options);
// The learning rate of 0-based iteration k under the schedule.
IVR_API double learning_rate(const OptimizerOptions& options, int k);

// The optimiser's moments for `count` parameters on the device, in the given precision.
class IVR_API Optimizer {
 public:
  Optimizer(Device& device, std::size_t count, const OptimizerOptions& options,
            Precision precision = Precision::f32);
  ~Optimizer();
  Optimizer(Optimizer&&) noexcept;
  Optimizer& operator=(Optimizer&&) noexcept;

  // One step with the next iteration's learning rate: params ← project(params − update(grad)).
  // Host arrays of `count` values (uploaded and read back: for small parameter sets and tests;
  // reconstructions step device buffers through impl()).
  void step(std::vector<double>& params, const std::vector<double>& grad);
  int iterations() const;  // steps taken

  // Everything a checkpoint needs: restoring it continues bit-for-bit.
  struct State {
    int iterations = 0;
    std::vector<double> first, second;  // Adam: m and v; SGD: the velocity and (empty)
  };
  State state() const;
  void restore(const State& state);

  struct Impl;
  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ivr
