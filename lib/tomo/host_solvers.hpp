// host_solvers.hpp — internal: CGLS, SIRT and LSQR on host vectors over any split of the projector
// pair (bricks, a worker's views, a worker's slab: HostSplit's callbacks), the same iterations as
// the device's cgls(), sirt() and lsqr() in lib/tomo/tomo.cpp on the same stacked system
// [N; L] x ≈ [p; 0] (L = √λ·I for Tikhonov, S·D for TV), and solve_host(), which runs the one asked.
#pragma once
#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "ivr/error.hpp"
#include "tomo/host_split.hpp"

namespace ivr {

// The stacked system's regulariser rows and the solvers' block vectors on host vectors: what the
// device's StackedSystem (lib/tomo/tomo.cpp) and TV kernels (kernels/linalg.cl) do.
template <typename T>
class HostSystem {
 public:
  struct Block {
    std::vector<double> data;  // the lines this worker holds
    std::vector<T> reg;        // L x's rows: n (Tikhonov) or 3n (TV), else none
  };
  HostSystem(const HostSplit<T>& A, const TomoOptions& o, std::size_t n)
      : A_(A), o_(o), n_(n), root_(std::sqrt(o.tikhonov)) {
    if (o.tv > 0) sw_.assign(n, 0.0);
  }
  // The TV weights at x: sw = √λ (|D x|² + ε²)^(−1/4) (lagged diffusivity).
  void reweight(const std::vector<T>& x) {
    if (o_.tv <= 0) return;
    const double root = std::sqrt(o_.tv), eps2 = o_.tv_epsilon * o_.tv_epsilon;
    for (std::size_t i = 0; i < n_; ++i) {
      double sq = eps2;
      for (int k = 0; k < 3; ++k)
        if (has_next(i, k)) {
          const double d = double(x[i + step(k)]) - double(x[i]);
          sq += d * d;
        }
      sw_[i] = root / std::sqrt(std::sqrt(sq));
    }
  }
  // out = A v
  void apply(const std::vector<T>& v, Block& out) const {
    out.data = A_.project(v);
    if (o_.tikhonov > 0) {
      out.reg.resize(n_);
      for (std::size_t i = 0; i < n_; ++i) out.reg[i] = T(root_ * v[i]);
    } else if (o_.tv > 0) {
      apply_regularizer(v, out);
    }
  }
  // out = Aᵀ u
  void apply_transpose(const Block& u, std::vector<T>& out) const {
    A_.backproject(u.data, out);
    if (o_.tikhonov > 0)
      for (std::size_t i = 0; i < n_; ++i) out[i] = T(out[i] + root_ * u.reg[i]);
    if (o_.tv > 0) add_tv_adjoint(1.0, u.reg, out);
  }
  // r = b − A x (tmp receives A x)
  void residual(const std::vector<double>& p, const std::vector<T>& x, Block& tmp, Block& r) const {
    apply(x, tmp);
    r.data.resize(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) r.data[i] = p[i] - tmp.data[i];
    r.reg.resize(tmp.reg.size());
    for (std::size_t i = 0; i < tmp.reg.size(); ++i) r.reg[i] = -tmp.reg[i];
  }
  double dot(const Block& a, const Block& b) const {
    // (a slab: Tikhonov's rows over the planes it owns, TV's over the rows it holds, summed)
    const double reg = o_.tikhonov > 0 ? A_.dot_volume(a.reg, b.reg)
                       : o_.tv > 0     ? total(host_dot(a.reg, b.reg))
                                       : 0.0;
    return A_.dot_lines(a.data, b.data) + reg;
  }
  // g −= the regulariser's gradient at x (LᵀL x)
  void add_regularizer_descent(const std::vector<T>& x, std::vector<T>& g) const {
    if (o_.tikhonov > 0)
      for (std::size_t i = 0; i < n_; ++i) g[i] = T(g[i] - o_.tikhonov * x[i]);
    if (o_.tv > 0) {
      Block lx;
      apply_regularizer(x, lx);
      add_tv_adjoint(-1.0, lx.reg, g);
    }
  }
  // out = base + a bound on the regulariser's Hessian row sums: λ, or twice the TV rows' diagonal
  // (over slabs the rows' parts of a shared plane joined).
  void add_curvature(const std::vector<T>& base, std::vector<T>& out) const {
    out.resize(n_);
    if (o_.tv <= 0) {
      for (std::size_t i = 0; i < n_; ++i) out[i] = T(double(base[i]) + o_.tikhonov);
      return;
    }
    out.assign(base.begin(), base.end());
    add_parts(1.0, out, [&](std::size_t i) {
      double sum = 0;
      for (int k = 0; k < 3; ++k) {
        if (has_row(i, k)) sum += sw_[i] * sw_[i];
        if (has_prev(i, k) && has_row(i - step(k), k)) sum += sw_[i - step(k)] * sw_[i - step(k)];
      }
      return 2 * sum;
    });
  }

 private:
  std::size_t step(int k) const {
    return k == 0 ? 1 : k == 1 ? std::size_t(A_.nx) : std::size_t(A_.nx) * std::size_t(A_.ny);
  }
  int coordinate(std::size_t i, int k) const {
    return k == 0 ? int(i % std::size_t(A_.nx))
         : k == 1 ? int(i / std::size_t(A_.nx) % std::size_t(A_.ny))
                  : int(i / (std::size_t(A_.nx) * std::size_t(A_.ny)));
  }
  bool has_next(std::size_t i, int k) const {
    return coordinate(i, k) + 1 < (k == 0 ? A_.nx : k == 1 ? A_.ny : A_.nz);
  }
  bool has_prev(std::size_t i, int k) const { return coordinate(i, k) > 0; }
  // Whether this worker holds voxel i's TV row along axis k (over slabs: its row planes only).
  bool has_row(std::size_t i, int k) const {
    return has_next(i, k) && (A_.row_planes < 0 || coordinate(i, 2) < A_.row_planes);
  }
  double total(double mine) const { return A_.total ? A_.total(mine) : mine; }
  // out.reg = S D x (the TV rows; 0 where another worker holds the row)
  void apply_regularizer(const std::vector<T>& x, Block& out) const {
    out.reg.resize(3 * n_);
    for (std::size_t i = 0; i < n_; ++i)
      for (int k = 0; k < 3; ++k)
        out.reg[3 * i + k] =
            has_row(i, k) ? T(sw_[i] * (double(x[i + step(k)]) - double(x[i]))) : T(0);
  }
  // out += a · Dᵀ(sw ⊙ g) (over slabs each worker's rows' part, the shared planes joined)
  void add_tv_adjoint(double a, const std::vector<T>& g, std::vector<T>& out) const {
    add_parts(a, out, [&](std::size_t i) {
      double sum = 0;
      for (int k = 0; k < 3; ++k) {
        if (has_row(i, k)) sum -= sw_[i] * double(g[3 * i + k]);
        if (has_prev(i, k) && has_row(i - step(k), k))
          sum += sw_[i - step(k)] * double(g[3 * (i - step(k)) + k]);
      }
      return sum;
    });
  }
  // out[i] += a · part(i), part(i) this worker's TV rows' share at voxel i: in place where a
  // worker holds the whole grid; over slabs (A_.join) gathered in a volume vector first and the
  // neighbours' shares of the shared planes added.
  template <typename Part>
  void add_parts(double a, std::vector<T>& out, Part&& part) const {
    if (!A_.join) {
      for (std::size_t i = 0; i < n_; ++i) out[i] = T(out[i] + a * part(i));
      return;
    }
    std::vector<T> parts(n_);
    for (std::size_t i = 0; i < n_; ++i) parts[i] = T(part(i));
    A_.join(parts);
    for (std::size_t i = 0; i < n_; ++i) out[i] = T(out[i] + a * double(parts[i]));
  }

  const HostSplit<T>& A_;
  const TomoOptions& o_;
  std::size_t n_;
  double root_;
  std::vector<double> sw_;  // TV weights
};

// x = max(x, 0); whether anything moved on any worker (A.any: collective where workers hold
// different voxels).
template <typename T>
bool clamp_host(const HostSplit<T>& A, std::vector<T>& x) {
  bool moved = false;
  for (T& v : x)
    if (v < 0) v = 0, moved = true;
  return A.any ? A.any(moved) : moved;
}

// CGLS (Björck) on the stacked system, as the device's cgls(): non-negativity and TV re-weighting
// restart it from the projected iterate.
template <typename T>
void cgls_host(const HostSplit<T>& A, const std::vector<double>& p, std::vector<T>& x,
               const TomoOptions& o, Monitor& m) {
  static_assert(std::is_same_v<T, double> || std::is_same_v<T, float>);
  const std::size_t n = x.size();
  HostSystem<T> S(A, o, n);
  typename HostSystem<T>::Block r, q;
  std::vector<T> s, d;
  S.reweight(x);
  S.residual(p, x, q, r);
  S.apply_transpose(r, s);
  d = s;
  double gamma = A.dot_volume(s, s);
  for (int k = 1;; ++k) {
    if (gamma > 0) {
      S.apply(d, q);
      const double delta = S.dot(q, q);
      if (!(delta > 0)) return (void)m.stop("converged");
      const double alpha = gamma / delta;
      for (std::size_t i = 0; i < n; ++i) x[i] = T(x[i] + alpha * d[i]);
      for (std::size_t i = 0; i < r.data.size(); ++i) r.data[i] -= alpha * q.data[i];
      for (std::size_t i = 0; i < r.reg.size(); ++i) r.reg[i] = T(r.reg[i] - alpha * q.reg[i]);
      bool restart = o.nonneg && clamp_host(A, x);
      if (o.tv > 0 && k % o.tv_reweight == 0) restart = true, S.reweight(x);
      if (restart) S.residual(p, x, q, r);
      S.apply_transpose(r, s);
      const double gamma_next = A.dot_volume(s, s);
      for (std::size_t i = 0; i < n; ++i) d[i] = restart ? s[i] : T(s[i] + gamma_next / gamma * d[i]);
      gamma = gamma_next;
    }
    if (!m.next(k, std::sqrt(A.dot_lines(r.data, r.data)))) return;
    if (!(gamma > 0)) return (void)m.stop("converged");
  }
}

// SIRT: x += C ⊙ (Nᵀ R (p − N x) − ∇ regulariser), R = 1/(N 1) per ray, C = ω/(Nᵀ 1 [+ K]) per
// voxel, K the regulariser's curvature bound (λ, or twice the TV rows' diagonal, refreshed with
// the weights every iteration) — as the device's sirt(); a reciprocal of a sum that is not > 0 is
// 0 (a ray or voxel nothing crosses takes no update).
template <typename T>
void sirt_host(const HostSplit<T>& A, const std::vector<double>& p, std::vector<T>& x,
               const TomoOptions& o, Monitor& m) {
  const std::size_t n = x.size();
  HostSystem<T> S(A, o, n);
  const bool regularised = o.tikhonov > 0 || o.tv > 0;
  std::vector<double> R = A.project(std::vector<T>(n, T(1)));
  for (double& v : R) v = v > 0 ? 1 / v : 0.0;
  std::vector<T> column_sums, C;
  A.backproject(std::vector<double>(p.size(), 1.0), column_sums);
  auto column_weights = [&] {  // C = ω / (Nᵀ1 [+ K])
    if (regularised)
      S.add_curvature(column_sums, C);
    else
      C = column_sums;
    for (T& v : C) v = T(v > 0 ? o.relaxation * (1 / double(v)) : 0.0);
  };
  if (o.tv == 0) column_weights();
  std::vector<double> r, weighted(p.size());
  auto residual = [&] {  // r = p − N x, and its norm
    r = A.project(x);
    for (std::size_t i = 0; i < r.size(); ++i) r[i] = p[i] - r[i];
    return std::sqrt(A.dot_lines(r, r));
  };
  residual();
  std::vector<T> g;
  for (int k = 1;; ++k) {
    for (std::size_t i = 0; i < r.size(); ++i) weighted[i] = R[i] * r[i];
    A.backproject(weighted, g);
    S.reweight(x);
    if (o.tv > 0) column_weights();  // K follows the TV weights
    S.add_regularizer_descent(x, g);
    for (std::size_t i = 0; i < n; ++i) x[i] = T(x[i] + double(g[i]) * double(C[i]));
    if (o.nonneg) clamp_host(A, x);
    if (!m.next(k, residual())) return;
  }
}

// LSQR (Paige & Saunders) on the stacked system, as the device's lsqr(): the residual it reports
// is its own estimate φ̄ of ‖b − A x‖; non-negativity and TV re-weighting restart the
// bidiagonalisation from the projected iterate.
template <typename T>
void lsqr_host(const HostSplit<T>& A, const std::vector<double>& p, std::vector<T>& x,
               const TomoOptions& o, Monitor& m) {
  const std::size_t n = x.size();
  HostSystem<T> S(A, o, n);
  typename HostSystem<T>::Block u, Av;
  std::vector<T> v, w, Atu;
  double alpha = 0, rho_bar = 0, phi_bar = 0;
  auto scale = [](double s, typename HostSystem<T>::Block& b) {
    for (double& e : b.data) e *= s;
    for (T& e : b.reg) e = T(s * e);
  };
  auto normalise = [&](std::vector<T>& a) {  // a /= ‖a‖; returns ‖a‖
    const double norm = std::sqrt(A.dot_volume(a, a));
    if (norm > 0)
      for (T& e : a) e = T(e * (1 / norm));
    return norm;
  };
  auto start = [&] {  // u = b − A x normalised, v = Aᵀ u normalised, w = v
    S.residual(p, x, Av, u);
    const double beta = std::sqrt(S.dot(u, u));
    if (beta > 0) scale(1 / beta, u);
    S.apply_transpose(u, v);
    alpha = normalise(v);
    w = v;
    rho_bar = alpha;
    phi_bar = beta;
  };
  S.reweight(x);
  start();
  for (int k = 1;; ++k) {
    if (alpha > 0 && phi_bar > 0) {
      S.apply(v, Av);
      for (std::size_t i = 0; i < u.data.size(); ++i) u.data[i] = Av.data[i] - alpha * u.data[i];
      for (std::size_t i = 0; i < u.reg.size(); ++i) u.reg[i] = T(Av.reg[i] - alpha * u.reg[i]);
      const double beta = std::sqrt(S.dot(u, u));
      if (beta > 0) scale(1 / beta, u);
      S.apply_transpose(u, Atu);
      for (std::size_t i = 0; i < n; ++i) v[i] = T(Atu[i] - beta * v[i]);
      alpha = normalise(v);
      const double rho = std::hypot(rho_bar, beta), c = rho_bar / rho, s = beta / rho;
      const double theta = s * alpha, phi = c * phi_bar;
      rho_bar = -c * alpha;
      phi_bar = s * phi_bar;
      for (std::size_t i = 0; i < n; ++i) x[i] = T(x[i] + phi / rho * w[i]);
      for (std::size_t i = 0; i < n; ++i) w[i] = T(v[i] - theta / rho * w[i]);
      bool restart = o.nonneg && clamp_host(A, x);
      if (o.tv > 0 && k % o.tv_reweight == 0) restart = true, S.reweight(x);
      if (restart) start();
    }
    if (!m.next(k, std::abs(phi_bar))) return;
    if (!(alpha > 0 && phi_bar > 0)) return (void)m.stop("converged");
  }
}

// The solver `o` asks for on host vectors.
template <typename T>
void solve_host(const HostSplit<T>& A, const std::vector<double>& p, std::vector<T>& x,
                const TomoOptions& o, Monitor& m) {
  switch (o.solver) {
    case Solver::cgls:
      return cgls_host(A, p, x, o, m);
    case Solver::sirt:
      return sirt_host(A, p, x, o, m);
    case Solver::lsqr:
      return lsqr_host(A, p, x, o, m);
  }
}

}  // namespace ivr
