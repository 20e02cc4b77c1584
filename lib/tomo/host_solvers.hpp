// host_solvers.hpp — internal: SIRT and LSQR on host vectors over any split of the projector pair
// (bricks, a worker's views, a worker's slab: HostCgls's callbacks), the same iterations as the
// device's sirt() and lsqr() in lib/tomo/tomo.cpp, and solve_host(), which runs the one asked for.
#pragma once
#include <cmath>
#include <string>
#include <vector>

#include "ivr/error.hpp"
#include "tomo/host_cgls.hpp"

namespace ivr {

// TV needs the device's difference operators: refused on host vectors (`where` names the split).
inline void check_host_solver(const TomoOptions& o, const std::string& where) {
  if (o.tv > 0)
    throw Error(Status::unsupported, where + ": TV regularisation is not available (its "
                                             "difference operators run in core only); use "
                                             "tikhonov or nonneg");
}

// x = max(x, 0); whether anything moved on any worker (A.any: collective where workers hold
// different voxels).
template <typename T>
bool clamp_host(const HostCgls<T>& A, std::vector<T>& x) {
  bool moved = false;
  for (T& v : x)
    if (v < 0) v = 0, moved = true;
  return A.any ? A.any(moved) : moved;
}

// SIRT: x += C ⊙ (Nᵀ R (p − N x) − λ x), R = 1/(N 1) per ray, C = ω/(Nᵀ 1 + λ) per voxel (a
// reciprocal of a sum that is not > 0 is 0: a ray or voxel nothing crosses takes no update).
template <typename T>
void sirt_host(const HostCgls<T>& A, const std::vector<double>& p, std::vector<T>& x,
               const TomoOptions& o, Monitor& m) {
  const std::size_t n = x.size();
  std::vector<double> R = A.project(std::vector<T>(n, T(1)));
  for (double& v : R) v = v > 0 ? 1 / v : 0.0;
  std::vector<T> C;
  A.backproject(std::vector<double>(p.size(), 1.0), C);
  for (T& v : C) {
    const double sum = double(v) + o.tikhonov;
    v = T(sum > 0 ? o.relaxation / sum : 0.0);
  }
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
    for (std::size_t i = 0; i < n; ++i)
      x[i] = T(x[i] + (double(g[i]) - o.tikhonov * double(x[i])) * double(C[i]));
    if (o.nonneg) clamp_host(A, x);
    if (!m.next(k, residual())) return;
  }
}

// LSQR (Paige & Saunders) on the stacked system [N; √λ I] x ≈ [p; 0]: vectors of the lines and,
// with Tikhonov, a volume part. Non-negativity restarts the bidiagonalisation from the projected
// iterate, as the device's lsqr().
template <typename T>
void lsqr_host(const HostCgls<T>& A, const std::vector<double>& p, std::vector<T>& x,
               const TomoOptions& o, Monitor& m) {
  const std::size_t n = x.size();
  const double root = std::sqrt(o.tikhonov);
  struct Block {
    std::vector<double> data;  // the lines this worker holds
    std::vector<T> reg;        // √λ x's rows (with Tikhonov)
  };
  auto apply = [&](const std::vector<T>& v, Block& out) {  // out = A v
    out.data = A.project(v);
    out.reg.resize(o.tikhonov > 0 ? n : 0);
    for (std::size_t i = 0; i < out.reg.size(); ++i) out.reg[i] = T(root * v[i]);
  };
  auto apply_transpose = [&](const Block& u, std::vector<T>& out) {  // out = Aᵀ u
    A.backproject(u.data, out);
    for (std::size_t i = 0; i < u.reg.size(); ++i) out[i] = T(out[i] + root * u.reg[i]);
  };
  auto dot = [&](const Block& a, const Block& b) {
    return A.dot_lines(a.data, b.data) + (a.reg.empty() ? 0.0 : A.dot_volume(a.reg, b.reg));
  };
  auto scale = [](double s, Block& u) {
    for (double& v : u.data) v *= s;
    for (T& v : u.reg) v = T(s * v);
  };
  Block u, Av;
  std::vector<T> v, w, Atu;
  double alpha = 0, rho_bar = 0, phi_bar = 0;
  auto norm_volume = [&](const std::vector<T>& a) { return std::sqrt(A.dot_volume(a, a)); };
  auto start = [&] {  // u = b − A x normalised, v = Aᵀ u normalised, w = v
    apply(x, Av);
    u.data.resize(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) u.data[i] = p[i] - Av.data[i];
    u.reg = Av.reg;
    for (T& r : u.reg) r = -r;
    const double beta = std::sqrt(dot(u, u));
    if (beta > 0) scale(1 / beta, u);
    apply_transpose(u, v);
    alpha = norm_volume(v);
    if (alpha > 0)
      for (T& e : v) e = T(e * (1 / alpha));
    w = v;
    rho_bar = alpha;
    phi_bar = beta;
  };
  start();
  for (int k = 1;; ++k) {
    if (alpha > 0 && phi_bar > 0) {
      apply(v, Av);
      for (std::size_t i = 0; i < u.data.size(); ++i) u.data[i] = Av.data[i] - alpha * u.data[i];
      for (std::size_t i = 0; i < u.reg.size(); ++i) u.reg[i] = T(Av.reg[i] - alpha * u.reg[i]);
      const double beta = std::sqrt(dot(u, u));
      if (beta > 0) scale(1 / beta, u);
      apply_transpose(u, Atu);
      for (std::size_t i = 0; i < n; ++i) v[i] = T(Atu[i] - beta * v[i]);
      alpha = norm_volume(v);
      if (alpha > 0)
        for (T& e : v) e = T(e * (1 / alpha));
      const double rho = std::hypot(rho_bar, beta), c = rho_bar / rho, s = beta / rho;
      const double theta = s * alpha, phi = c * phi_bar;
      rho_bar = -c * alpha;
      phi_bar = s * phi_bar;
      for (std::size_t i = 0; i < n; ++i) x[i] = T(x[i] + phi / rho * w[i]);
      for (std::size_t i = 0; i < n; ++i) w[i] = T(v[i] - theta / rho * w[i]);
      if (o.nonneg && clamp_host(A, x)) start();
    }
    if (!m.next(k, std::abs(phi_bar))) return;
    if (!(alpha > 0 && phi_bar > 0)) return (void)m.stop("converged");
  }
}

// The solver `o` asks for on host vectors.
template <typename T>
void solve_host(const HostCgls<T>& A, const std::vector<double>& p, std::vector<T>& x,
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
