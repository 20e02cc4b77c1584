// lbfgs.hpp — limited-memory BFGS on the host, projected onto a box, with a backtracking
// (Armijo) line search: the optimiser for small parameter sets (transfer functions, viewpoints).
#pragma once
#include <functional>
#include <vector>

namespace ivr {

class Lbfgs {
 public:
  // f(x, grad): the objective at x, its gradient written to grad (x.size() values).
  using Objective = std::function<double(const std::vector<double>& x, std::vector<double>& grad)>;

  // Bounds per parameter (±infinity where free); `history` curvature pairs; the first trial
  // step moves the largest parameter by `initial_step` (and after every reset of the memory).
  Lbfgs(std::vector<double> lower, std::vector<double> upper, int history, double initial_step);

  // One iteration: x moves to the accepted point of the line search and the objective there is
  // returned. Where no decrease is found (a minimum, to rounding) x stays and the memory resets.
  double step(std::vector<double>& x, const Objective& f);

  int evaluations() const { return evaluations_; }

  // Everything a checkpoint needs to continue bit-for-bit.
  struct State {
    int iterations = 0;
    bool evaluated = false;  // f and g hold the objective at the current x
    double f = 0;
    std::vector<double> g;
    std::vector<std::vector<double>> s, y;  // oldest first
  };
  const State& state() const { return state_; }
  void restore(const State& state) { state_ = state; }

 private:
  std::vector<double> lower_, upper_;
  int history_;
  double initial_step_;
  int evaluations_ = 0;
  State state_;
};

}  // namespace ivr
