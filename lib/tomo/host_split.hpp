// host_split.hpp — internal: the solvers' iteration bookkeeping (Monitor), and what the host
// solvers (host_solvers.hpp) need of a split of the projector pair: bricks streamed through one
// device (lib/tomo/tomo.cpp), a worker's share of the views (tomo_shared) or its slab of the
// volume (tomo_domain, lib/brick/domain_tomo.cpp).
#pragma once
#include <chrono>
#include <functional>
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

// A progress every worker answers alike: each asks its own (none given: go on) and all stop after
// an iteration where any of them says stop — a worker that stopped alone would leave the others
// waiting in the next iteration's sums. `total` sums one value over the workers (collective: one
// per iteration on every worker, whether or not it has a progress).
inline TomoProgress agreed_progress(const TomoProgress& progress,
                                    std::function<double(double)> total) {
  return [&progress, total = std::move(total)](const TomoIteration& it) {
    const bool go = !progress || progress(it);
    return total(go ? 0.0 : 1.0) == 0.0;
  };
}

// The pieces the solvers on host vectors need, as one split provides them. T: the volume vectors' type —
// float where the precision is float32 and the projector is in bricks (the device's iterates are
// float32 then too; three float32 volumes are 12 GiB at 1024³ where double would take 24), double
// otherwise. Dot products sum in double.
template <typename T>
struct HostSplit {
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
  // The grid of the voxels this worker holds (TV's differences): the volume's, or a slab's planes.
  int nx = 0, ny = 0, nz = 0;
  // A slab (tomo_domain): the planes whose TV rows (forward differences) this worker holds, its
  // first `row_planes` (a plane it shares with the next slab has its rows there, where the next
  // plane is); `total` sums a value over the workers; `join` adds to the planes it shares with its
  // neighbours their parts (as backproject's). Unset where a worker holds the whole grid.
  int row_planes = -1;
  std::function<double(double)> total;
  std::function<void(std::vector<T>&)> join;
};

// ⟨a, b⟩ in double, in index order.
template <typename A, typename B>
double host_dot(const A& a, const B& b) {
  double total = 0;
  for (std::size_t i = 0; i < a.size(); ++i) total += double(a[i]) * double(b[i]);
  return total;
}

}  // namespace ivr
