// host_cgls.hpp — internal: the solvers' iteration bookkeeping (Monitor), and CGLS on host vectors
// over any split of the projector pair: bricks streamed through one device (lib/tomo/tomo.cpp),
// a worker's share of the views (tomo_shared) or its slab of the volume (tomo_domain,
// lib/brick/domain_tomo.cpp).
#pragma once
#include <chrono>
#include <cmath>
#include <functional>
#include <type_traits>
#include <vector>

#include "ivr/tomo.hpp"

namespace ivr {

// Every option's range (Error(invalid_argument) naming the first out of it).
void check_tomo_options(const TomoOptions& options);

// The iteration loop's bookkeeping: history, the stopping rules, the progress callback.
class Monitor {
 public:
  Monitor(const TomoOptions& o, const TomoProgress& progress, double p_norm, TomoResult& result)
      : o_(o),
        progress_(progress),
        p_norm_(p_norm),
        result_(result),
        start_(std::chrono::steady_clock::now()) {}
  // Records iteration k's residual norm; false when the loop must stop (reason set).
  bool next(int k, double residual_norm) {
    TomoIteration it;
    it.iteration = k;
    it.residual = p_norm_ > 0 ? residual_norm / p_norm_ : 0.0;
    it.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    result_.history.push_back(it);
    if (progress_ && !progress_(it)) return stop("interrupted");
    if (o_.tolerance > 0 && it.residual <= o_.tolerance) return stop("tolerance");
    if (k >= o_.iterations) return stop("iterations");
    return true;
  }
  bool stop(const char* reason) {
    result_.stop_reason = reason;
    return false;
  }

 private:
  const TomoOptions& o_;
  const TomoProgress& progress_;
  double p_norm_;
  TomoResult& result_;
  std::chrono::steady_clock::time_point start_;
};

// The pieces CGLS on host vectors needs, as one split provides them. T: the volume vectors' type —
// float where the precision is float32 and the projector is in bricks (the device's iterates are
// float32 then too; three float32 volumes are 12 GiB at 1024³ where double would take 24), double
// otherwise. Dot products sum in double.
template <typename T>
struct HostCgls {
  // N v: the lines this worker holds (all of them, or its share of the views).
  std::function<std::vector<double>(const std::vector<T>&)> project;
  // out = Nᵀ y over the voxels this worker holds (out resized to them).
  std::function<void(const std::vector<double>&, std::vector<T>&)> backproject;
  // ⟨a, b⟩ over the lines, and over the volume, each summed over the workers where they split it.
  std::function<double(const std::vector<double>&, const std::vector<double>&)> dot_lines;
  std::function<double(const std::vector<T>&, const std::vector<T>&)> dot_volume;
  // Whether any worker's flag is set (collective); unset: this worker's alone (every worker holds
  // the same iterate).
  std::function<bool(bool)> any;
};

// ⟨a, b⟩ in double, in index order.
template <typename A, typename B>
double host_dot(const A& a, const B& b) {
  double total = 0;
  for (std::size_t i = 0; i < a.size(); ++i) total += double(a[i]) * double(b[i]);
  return total;
}

// CGLS on host vectors: the same iteration as the device's cgls() on the stacked system
// [N; √λ I] of Tikhonov, with non-negativity restarting from the projected iterate; the iterates
// equal the in-core solver's up to rounding. Every worker of a split runs it together (the
// callbacks' sums are collective) and holds the same iterate where they share voxels.
template <typename T>
void cgls_host(const HostCgls<T>& A, const std::vector<double>& p, std::vector<T>& x,
               const TomoOptions& o, Monitor& m) {
  static_assert(std::is_same_v<T, double> || std::is_same_v<T, float>);
  const double lambda = o.tikhonov;
  // r = p − N x (data part; the Tikhonov part −√λ x is kept implicitly through x);
  // s = Nᵀ r − λ x.
  auto residual = [&] {
    std::vector<double> r = A.project(x);
    for (std::size_t i = 0; i < r.size(); ++i) r[i] = p[i] - r[i];
    return r;
  };
  auto gradient = [&](const std::vector<double>& r, std::vector<T>& s) {
    A.backproject(r, s);
    if (lambda > 0)
      for (std::size_t i = 0; i < s.size(); ++i) s[i] = T(s[i] - lambda * x[i]);
  };
  std::vector<double> r = residual();
  std::vector<T> s;
  gradient(r, s);
  std::vector<T> d = s;
  double gamma = A.dot_volume(s, s);
  for (int k = 1;; ++k) {
    if (gamma > 0) {
      const std::vector<double> q = A.project(d);
      const double delta = A.dot_lines(q, q) + lambda * A.dot_volume(d, d);
      if (!(delta > 0)) return (void)m.stop("converged");
      const double alpha = gamma / delta;
      bool restart = false;
      for (std::size_t i = 0; i < x.size(); ++i) x[i] = T(x[i] + alpha * d[i]);
      for (std::size_t i = 0; i < r.size(); ++i) r[i] -= alpha * q[i];
      if (o.nonneg)
        for (T& v : x)
          if (v < 0) v = 0, restart = true;
      // (Restarting is collective: where another worker's voxels went negative, all restart.)
      if (o.nonneg && A.any) restart = A.any(restart);
      if (restart) r = residual();
      gradient(r, s);
      const double gamma_next = A.dot_volume(s, s);
      for (std::size_t i = 0; i < d.size(); ++i)
        d[i] = restart ? s[i] : T(s[i] + gamma_next / gamma * d[i]);
      gamma = gamma_next;
    }
    if (!m.next(k, std::sqrt(A.dot_lines(r, r)))) return;
    if (!(gamma > 0)) return (void)m.stop("converged");
  }
}

}  // namespace ivr
