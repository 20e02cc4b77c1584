// lbfgs.cpp — projected L-BFGS (two-loop recursion, Nocedal & Wright alg. 7.4) with a
// backtracking Armijo search along the projected path.
#include "reconstruct/lbfgs.hpp"

#include <algorithm>
#include <cmath>

#include "ivr/error.hpp"

namespace ivr {

namespace {

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.size(); ++i) sum += a[i] * b[i];
  return sum;
}

double max_abs(const std::vector<double>& a) {
  double m = 0;
  for (double v : a) m = std::max(m, std::abs(v));
  return m;
}

}  // namespace

Lbfgs::Lbfgs(std::vector<double> lower, std::vector<double> upper, int history, double initial_step)
    : lower_(std::move(lower)),
      upper_(std::move(upper)),
      history_(history),
      initial_step_(initial_step) {
  if (lower_.size() != upper_.size() || history < 1 || !(initial_step > 0))
    throw Error(Status::invalid_argument,
                "lbfgs: bounds of different sizes, history < 1 or a "
                "non-positive initial step");
}

double Lbfgs::step(std::vector<double>& x, const Objective& f) {
  State& st = state_;
  const std::size_t n = x.size();
  if (n != lower_.size())
    throw Error(Status::invalid_argument, "lbfgs: " + std::to_string(n) +
                                              " parameters for bounds of " +
                                              std::to_string(lower_.size()));
  if (!st.evaluated) {
    st.g.assign(n, 0.0);
    st.f = f(x, st.g);
    ++evaluations_;
    st.evaluated = true;
  }
  // d = −H g by the two-loop recursion; H₀ = γI with γ = sᵀy / yᵀy of the newest pair.
  std::vector<double> d(st.g);
  const std::size_t m = st.s.size();
  std::vector<double> alpha(m);
  for (std::size_t k = m; k-- > 0;) {
    alpha[k] = dot(st.s[k], d) / dot(st.y[k], st.s[k]);
    for (std::size_t i = 0; i < n; ++i) d[i] -= alpha[k] * st.y[k][i];
  }
  const double gmax = max_abs(st.g);
  const double gamma = m > 0 ? dot(st.s.back(), st.y.back()) / dot(st.y.back(), st.y.back())
                             : (gmax > 0 ? initial_step_ / gmax : 0.0);
  for (double& v : d) v *= gamma;
  for (std::size_t k = 0; k < m; ++k) {
    const double beta = dot(st.y[k], d) / dot(st.y[k], st.s[k]);
    for (std::size_t i = 0; i < n; ++i) d[i] += st.s[k][i] * (alpha[k] - beta);
  }
  for (double& v : d) v = -v;
  if (!(dot(st.g, d) < 0)) {  // not a descent direction (or a zero gradient): steepest descent
    st.s.clear();
    st.y.clear();
    for (std::size_t i = 0; i < n; ++i) d[i] = gmax > 0 ? -initial_step_ / gmax * st.g[i] : 0.0;
  }
  std::vector<double> trial(n), trial_g(n), dx(n);
  double t = 1;
  for (int attempt = 0; attempt < 40; ++attempt, t *= 0.5) {
    for (std::size_t i = 0; i < n; ++i) {
      trial[i] = std::clamp(x[i] + t * d[i], lower_[i], upper_[i]);
      dx[i] = trial[i] - x[i];
    }
    if (max_abs(dx) == 0) break;  // the projected path does not move: a stationary point
    const double ft = f(trial, trial_g);
    ++evaluations_;
    if (std::isfinite(ft) && ft <= st.f + 1e-4 * dot(st.g, dx)) {
      std::vector<double> dg(n);
      for (std::size_t i = 0; i < n; ++i) dg[i] = trial_g[i] - st.g[i];
      const double sy = dot(dx, dg);
      if (sy > 1e-12 * std::sqrt(dot(dx, dx) * dot(dg, dg))) {  // keeps H positive definite
        st.s.push_back(dx);
        st.y.push_back(dg);
        if (int(st.s.size()) > history_) {
          st.s.erase(st.s.begin());
          st.y.erase(st.y.begin());
        }
      }
      x = trial;
      st.f = ft;
      st.g = trial_g;
      ++st.iterations;
      return ft;
    }
  }
  st.s.clear();  // no decrease along d: start again from steepest descent next time
  st.y.clear();
  ++st.iterations;
  return st.f;
}

}  // namespace ivr
