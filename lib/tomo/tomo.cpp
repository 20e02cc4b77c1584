// tomo.cpp — absorption tomography solvers on the device: CGLS, SIRT and LSQR on the projector
// pair (lib/tomo/project.cpp), with optional Tikhonov or TV regularisation and non-negativity.
#include "ivr/tomo.hpp"

#include <chrono>
#include <functional>
#include <cmath>
#include <string>
#include <type_traits>

#include "ivr/error.hpp"
#include "brick/bricked_project.hpp"
#include "tomo/host_solvers.hpp"
#include "tomo/linalg.hpp"
#include "tomo/project.hpp"
#include "scene/scene.hpp"

namespace ivr {

const char* solver_name(Solver solver) {
  switch (solver) {
    case Solver::cgls:
      return "cgls";
    case Solver::sirt:
      return "sirt";
    case Solver::lsqr:
      return "lsqr";
  }
  return "?";
}

Solver parse_solver(const std::string& name, const std::string& where) {
  for (Solver s : {Solver::cgls, Solver::sirt, Solver::lsqr})
    if (name == solver_name(s)) return s;
  throw Error(Status::invalid_argument,
              where + ": unknown solver '" + name + "' (known: cgls, sirt, lsqr)");
}

void check_tomo_options(const TomoOptions& o) {
  auto fail = [](const std::string& what) { throw Error(Status::invalid_argument, what); };
  if (o.iterations < 1) fail("iterations must be >= 1, got " + std::to_string(o.iterations));
  if (!(o.tolerance >= 0) || !std::isfinite(o.tolerance))
    fail("tolerance must be >= 0, got " + number_text(o.tolerance));
  if (!(o.tikhonov >= 0) || !std::isfinite(o.tikhonov))
    fail("tikhonov must be >= 0, got " + number_text(o.tikhonov));
  if (!(o.tv >= 0) || !std::isfinite(o.tv)) fail("tv must be >= 0, got " + number_text(o.tv));
  if (o.tikhonov > 0 && o.tv > 0) fail("give either tikhonov or tv, not both");
  if (!(o.tv_epsilon > 0) || !std::isfinite(o.tv_epsilon))
    fail("tv_epsilon must be > 0, got " + number_text(o.tv_epsilon));
  if (o.tv_reweight < 1) fail("tv_reweight must be >= 1, got " + std::to_string(o.tv_reweight));
  if (!(o.relaxation > 0 && o.relaxation < 2))
    fail("relaxation must be in (0, 2), got " + number_text(o.relaxation));
}

namespace {

// The first non-finite value of `v`, named with `where(i)` (its view and pixel, or its voxel).
template <class Where>
void check_finite(const std::vector<double>& v, const char* what, Where&& where) {
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!std::isfinite(v[i]))
      throw Error(Status::invalid_argument, std::string(what) + ": value " + number_text(v[i]) +
                                                " at index " + std::to_string(i) + " (" + where(i) +
                                                "); values must be finite");
}

// A vector of the stacked system A = [N; L], b = [p; 0]: ray values, then the regulariser's rows.
struct Block {
  cl::Buffer data, reg;
};

// min ‖A x − b‖² with L = none, √λ·I (Tikhonov) or √λ·W^½·D (TV, W the lagged-diffusivity
// weights, updated by reweight()).
class StackedSystem {
 public:
  StackedSystem(Projector::Impl& p, DeviceVectors& v, const TomoOptions& o) : p_(p), v_(v), o_(o) {
    reg_size_ = o.tikhonov > 0 ? p.voxels : (o.tv > 0 ? 3 * p.voxels : 0);
    if (o.tv > 0) sw_ = p.vector(p.voxels, "the TV weights");
  }
  std::size_t reg_size() const { return reg_size_; }
  Block block(const char* what) const {
    return {p_.vector(p_.rays, what), p_.vector(std::max<std::size_t>(reg_size_, 1), what)};
  }
  void reweight(const cl::Buffer& x) {
    if (o_.tv > 0) v_.tv_weights(o_.tv_epsilon, o_.tv, x, sw_);
  }
  // out = base + a bound on the regulariser's Hessian row sums per voxel: λ (Tikhonov, λ·I), twice
  // the TV rows' diagonal at the current weights; base itself without a regulariser.
  void add_curvature(const cl::Buffer& base, const cl::Buffer& out) {
    if (o_.tv > 0) return v_.tv_diagonal(sw_, base, out);
    v_.fill(out, p_.voxels, o_.tikhonov);
    v_.axpy(p_.voxels, 1.0, base, out);
  }
  // out = A x
  void apply(const cl::Buffer& x, const Block& out) {
    p_.project(x, out.data);
    if (o_.tikhonov > 0) v_.scale(p_.voxels, std::sqrt(o_.tikhonov), x, out.reg);
    if (o_.tv > 0) v_.tv_forward(x, sw_, out.reg);
  }
  // out = Aᵀ u
  void apply_transpose(const Block& u, const cl::Buffer& out) {
    p_.backproject(u.data, out);
    if (o_.tikhonov > 0) v_.axpy(p_.voxels, std::sqrt(o_.tikhonov), u.reg, out);
    if (o_.tv > 0) v_.tv_adjoint(1.0, u.reg, sw_, out);
  }
  // g += −(gradient of the regulariser at x) = −LᵀL x
  void add_regularizer_descent(const cl::Buffer& x, const cl::Buffer& tmp3, const cl::Buffer& g) {
    if (o_.tikhonov > 0) v_.axpy(p_.voxels, -o_.tikhonov, x, g);
    if (o_.tv > 0) {
      v_.tv_forward(x, sw_, tmp3);
      v_.tv_adjoint(-1.0, tmp3, sw_, g);
    }
  }
  // r = b − A x (tmp receives A x)
  void residual(const cl::Buffer& p, const cl::Buffer& x, const Block& tmp, const Block& r) {
    apply(x, tmp);
    v_.copy(p, r.data, p_.rays);
    v_.axpy(p_.rays, -1.0, tmp.data, r.data);
    if (reg_size_) v_.scale(reg_size_, -1.0, tmp.reg, r.reg);
  }
  double dot(const Block& a, const Block& b) {
    return v_.dot(p_.rays, a.data, b.data) + (reg_size_ ? v_.dot(reg_size_, a.reg, b.reg) : 0.0);
  }
  void axpy(double a, const Block& x, const Block& y) {
    v_.axpy(p_.rays, a, x.data, y.data);
    if (reg_size_) v_.axpy(reg_size_, a, x.reg, y.reg);
  }
  void xpby(const Block& x, double b, const Block& y) {
    v_.xpby(p_.rays, x.data, b, y.data);
    if (reg_size_) v_.xpby(reg_size_, x.reg, b, y.reg);
  }
  void scale(double a, const Block& x, const Block& y) {
    v_.scale(p_.rays, a, x.data, y.data);
    if (reg_size_) v_.scale(reg_size_, a, x.reg, y.reg);
  }

 private:
  Projector::Impl& p_;
  DeviceVectors& v_;
  const TomoOptions& o_;
  std::size_t reg_size_ = 0;
  cl::Buffer sw_;
};

// CGLS (Björck): CG on AᵀA x = Aᵀb without forming AᵀA; ‖b − A x‖ decreases monotonically.
// Non-negativity and TV re-weighting restart it from the projected iterate.
void cgls(Projector::Impl& P, DeviceVectors& V, StackedSystem& A, const cl::Buffer& p,
          const cl::Buffer& x, const TomoOptions& o, Monitor& m) {
  const std::size_t n = P.voxels;
  const Block r = A.block("the residual"), q = A.block("A d");
  const cl::Buffer s = P.vector(n, "Aᵀ r"), d = P.vector(n, "the search direction");
  A.reweight(x);
  A.residual(p, x, q, r);
  A.apply_transpose(r, s);
  V.copy(s, d, n);
  double gamma = V.dot(n, s, s);
  for (int k = 1;; ++k) {
    bool restart = false;
    if (gamma > 0) {
      A.apply(d, q);
      const double delta = A.dot(q, q);
      if (!(delta > 0)) return (void)m.stop("converged");
      const double alpha = gamma / delta;
      V.axpy(n, alpha, d, x);
      A.axpy(-alpha, q, r);
      if (o.nonneg && V.clamp_nonneg(n, x) > 0) restart = true;
      if (o.tv > 0 && k % o.tv_reweight == 0) restart = true, A.reweight(x);
      if (restart) A.residual(p, x, q, r);
      A.apply_transpose(r, s);
      const double gamma_next = V.dot(n, s, s);
      if (restart)
        V.copy(s, d, n);
      else
        V.xpby(n, s, gamma_next / gamma, d);
      gamma = gamma_next;
    }
    if (!m.next(k, std::sqrt(V.dot(P.rays, r.data, r.data)))) return;
    if (!(gamma > 0)) return (void)m.stop("converged");
  }
}

// SIRT: x += ω·C ⊙ (Nᵀ R (p − N x) − ∇ regulariser), R = 1/(N 1) per ray, C = 1/(Nᵀ 1) per voxel
// — with a regulariser C = 1/(Nᵀ 1 + K), K a bound on the regulariser's Hessian row sums (λ for
// Tikhonov, twice the TV rows' diagonal at the current weights, so refreshed with them): without
// K a voxel that rays barely touch (Nᵀ1 ~ 1e-12 where a ray clips its corner) took 1e12 times
// the regulariser's gradient and the iterate blew up.
void sirt(Projector::Impl& P, DeviceVectors& V, StackedSystem& A, const cl::Buffer& p,
          const cl::Buffer& x, const TomoOptions& o, Monitor& m) {
  const std::size_t n = P.voxels, rays = P.rays;
  const bool regularised = o.tikhonov > 0 || o.tv > 0;
  const cl::Buffer R = P.vector(rays, "SIRT's row weights"),
                   C = P.vector(n, "SIRT's column weights"),
                   column_sums = regularised ? P.vector(n, "SIRT's column sums") : C;
  const cl::Buffer ones = P.vector(std::max(n, rays), "ones");
  V.fill(ones, std::max(n, rays), 1.0);
  P.project(ones, R);
  P.backproject(ones, column_sums);
  V.safe_reciprocal(rays, R);
  auto column_weights = [&] {  // C = ω / (Nᵀ1 [+ K])
    if (regularised) A.add_curvature(column_sums, C);
    V.safe_reciprocal(n, C);
    V.scale(n, o.relaxation, C, C);
  };
  if (o.tv == 0) column_weights();
  const cl::Buffer r = P.vector(rays, "the residual"), g = P.vector(n, "the update");
  const cl::Buffer tmp3 = P.vector(o.tv > 0 ? 3 * n : 1, "TV differences");
  auto residual = [&] {
    P.project(x, r);
    V.xpby(rays, p, -1.0, r);  // r = p − N x
    return std::sqrt(V.dot(rays, r, r));
  };
  residual();
  for (int k = 1;; ++k) {
    V.multiply(rays, R, r);
    P.backproject(r, g);
    A.reweight(x);
    if (o.tv > 0) column_weights();  // K follows the TV weights
    A.add_regularizer_descent(x, tmp3, g);
    V.multiply(n, C, g);
    V.axpy(n, 1.0, g, x);
    if (o.nonneg) V.clamp_nonneg(n, x);
    if (!m.next(k, residual())) return;
  }
}

// LSQR (Paige & Saunders 1982) on the stacked system; the residual it reports is its own
// estimate φ̄ of ‖b − A x‖ (the data residual when there is no regulariser). Non-negativity and
// TV re-weighting restart the bidiagonalisation from the projected iterate.
void lsqr(Projector::Impl& P, DeviceVectors& V, StackedSystem& A, const cl::Buffer& p,
          const cl::Buffer& x, const TomoOptions& o, Monitor& m) {
  const std::size_t n = P.voxels;
  const Block u = A.block("LSQR's u"), Av = A.block("A v");
  const cl::Buffer v = P.vector(n, "LSQR's v"), w = P.vector(n, "LSQR's w"),
                   Atu = P.vector(n, "Aᵀ u");
  double alpha = 0, rho_bar = 0, phi_bar = 0;
  auto start = [&] {  // u = b − A x normalised, v = Aᵀ u normalised, w = v
    A.residual(p, x, Av, u);
    const double beta = std::sqrt(A.dot(u, u));
    if (beta > 0) A.scale(1 / beta, u, u);
    A.apply_transpose(u, v);
    alpha = std::sqrt(V.dot(n, v, v));
    if (alpha > 0) V.scale(n, 1 / alpha, v, v);
    V.copy(v, w, n);
    rho_bar = alpha;
    phi_bar = beta;
  };
  A.reweight(x);
  start();
  for (int k = 1;; ++k) {
    if (alpha > 0 && phi_bar > 0) {
      A.apply(v, Av);
      A.xpby(Av, -alpha, u);  // u = A v − α u
      const double beta = std::sqrt(A.dot(u, u));
      if (beta > 0) A.scale(1 / beta, u, u);
      A.apply_transpose(u, Atu);
      V.xpby(n, Atu, -beta, v);  // v = Aᵀ u − β v
      alpha = std::sqrt(V.dot(n, v, v));
      if (alpha > 0) V.scale(n, 1 / alpha, v, v);
      const double rho = std::hypot(rho_bar, beta), c = rho_bar / rho, s = beta / rho;
      const double theta = s * alpha, phi = c * phi_bar;
      rho_bar = -c * alpha;
      phi_bar = s * phi_bar;
      V.axpy(n, phi / rho, w, x);
      V.xpby(n, v, -theta / rho, w);  // w = v − (θ/ρ) w
      bool restart = o.nonneg && V.clamp_nonneg(n, x) > 0;
      if (o.tv > 0 && k % o.tv_reweight == 0) restart = true, A.reweight(x);
      if (restart) start();
    }
    if (!m.next(k, std::abs(phi_bar))) return;
    if (!(alpha > 0 && phi_bar > 0)) return (void)m.stop("converged");
  }
}

}  // namespace

// The solver on host vectors (tomo/host_solvers.hpp) with `N`: the projector streaming bricks (the volume
// does not fit the device; float iterates come with bricks only) or in core over one worker's share
// of the views (docs/scaling.md); `sum` (where given; T = double) adds a vector over the workers,
// every worker getting the sum: their Nᵀ r and their dot products over lines.
template <typename T>
void solve_projector(const Projector& N, const std::vector<double>& p, std::vector<T>& x,
                    const TomoOptions& o, Monitor& m,
                    const std::function<void(std::vector<double>&)>& sum = {}) {
  Projector::Impl& P = N.impl();
  HostSplit<T> A;
  A.project = [&](const std::vector<T>& v) {
    if constexpr (std::is_same_v<T, double>)
      if (!P.bricks.edge) return N.project(v);
    return project_bricked(P, P.bricks, v.data());
  };
  A.backproject = [&](const std::vector<double>& y, std::vector<T>& out) {
    if (P.bricks.edge) {  // written into out: no second volume alive
      out.resize(P.voxels);
      backproject_bricked(P, P.bricks, y, out.data());
    } else if constexpr (std::is_same_v<T, double>) {
      out = N.backproject(y);
    }
    if constexpr (std::is_same_v<T, double>)
      if (sum) sum(out);
  };
  A.dot_lines = [&](const std::vector<double>& a, const std::vector<double>& b) {
    std::vector<double> d{host_dot(a, b)};
    if (sum) sum(d);
    return d[0];
  };
  A.dot_volume = [](const std::vector<T>& a, const std::vector<T>& b) { return host_dot(a, b); };
  A.nx = P.nx, A.ny = P.ny, A.nz = P.nz;  // (every worker holds the whole grid)
  solve_host(A, p, x, o, m);
}

TomoResult tomo(Device& device, const Scene& scene, const std::vector<double>& lines,
                const TomoOptions& options, const TomoProgress& progress,
                const std::vector<double>* x0) {
  check_tomo_options(options);
  const auto t0 = std::chrono::steady_clock::now();
  Projector projector(device, scene, options.precision);
  Projector::Impl& P = projector.impl();
  if (lines.size() != P.rays)
    throw Error(Status::invalid_argument,
                "projections: " + std::to_string(lines.size()) + " values, but the scene's " +
                    (scene.has_ray_list()
                         ? std::string("ray list has ")
                         : std::to_string(P.views) + " cameras of " + std::to_string(P.width) +
                               "x" + std::to_string(P.height) + " have ") +
                    std::to_string(P.rays) + " rays");
  check_finite(lines, "projections", [&](std::size_t i) {
    if (scene.has_ray_list()) return "ray " + std::to_string(i);
    return "view " + std::to_string(i / (std::size_t(P.width) * P.height)) + ", y " +
           std::to_string(i / P.width % P.height) + ", x " + std::to_string(i % P.width);
  });
  if (x0) {
    if (x0->size() != P.voxels)
      throw Error(Status::invalid_argument, "initial volume: " + std::to_string(x0->size()) +
                                                " values, the grid has " +
                                                std::to_string(P.voxels));
    check_finite(*x0, "initial volume", [&](std::size_t i) {
      return "x " + std::to_string(i % P.nx) + ", y " + std::to_string(i / P.nx % P.ny) + ", z " +
             std::to_string(i / (std::size_t(P.nx) * P.ny));
    });
  }
  if (projector.bricks() > 1) {  // out of core: host vectors, the projector in bricks
    TomoResult result;
    result.bricks = projector.bricks();
    result.setup_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    double p_norm = 0;
    for (double v : lines) p_norm += v * v;
    Monitor monitor(options, progress, std::sqrt(p_norm), result);
    if (options.precision == Precision::f32) {
      result.volume = x0 ? std::vector<float>(x0->begin(), x0->end())
                         : std::vector<float>(P.voxels, 0.0f);
      solve_projector(projector, lines, result.volume, options, monitor);
      return result;
    }
    std::vector<double> x = x0 ? *x0 : std::vector<double>(P.voxels, 0.0);
    solve_projector(projector, lines, x, options, monitor);
    result.volume.assign(x.begin(), x.end());
    result.volume_f64 = std::move(x);
    return result;
  }
  DeviceVectors V(P);
  StackedSystem A(P, V, options);
  const cl::Buffer p = P.upload(lines, "the projections");
  const cl::Buffer x = x0 ? P.upload(*x0, "the iterate") : P.vector(P.voxels, "the iterate");
  if (!x0) V.fill(x, P.voxels, 0.0);
  TomoResult result;
  result.setup_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Monitor monitor(options, progress, V.norm(P.rays, p), result);
  switch (options.solver) {
    case Solver::cgls:
      cgls(P, V, A, p, x, options, monitor);
      break;
    case Solver::sirt:
      sirt(P, V, A, p, x, options, monitor);
      break;
    case Solver::lsqr:
      lsqr(P, V, A, p, x, options, monitor);
      break;
  }
  const std::vector<double> values = P.download(x, P.voxels);
  result.volume.assign(values.begin(), values.end());
  if (options.precision == Precision::f64) result.volume_f64 = values;
  return result;
}

TomoResult tomo_shared(Device& device, const Scene& share, const std::vector<double>& lines,
                       const TomoOptions& options,
                       const std::function<void(std::vector<double>&)>& sum,
                       const TomoProgress& progress) {
  check_tomo_options(options);
  const auto t0 = std::chrono::steady_clock::now();
  const Projector projector(device, share, options.precision);
  if (lines.size() != projector.ray_count())
    throw Error(Status::invalid_argument,
                "projections: " + std::to_string(lines.size()) + " values for this share's " +
                    std::to_string(projector.ray_count()) + " rays");
  TomoResult result;
  result.bricks = projector.bricks();
  std::vector<double> norm{0.0};
  for (double v : lines) norm[0] += v * v;
  sum(norm);
  std::vector<double> x(projector.voxel_count(), 0.0);
  result.setup_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const TomoProgress agreed = agreed_progress(progress, [&](double v) {
    std::vector<double> t{v};
    sum(t);
    return t[0];
  });
  Monitor monitor(options, agreed, std::sqrt(norm[0]), result);
  solve_projector(projector, lines, x, options, monitor, sum);
  result.volume.assign(x.begin(), x.end());
  if (options.precision == Precision::f64) result.volume_f64 = std::move(x);
  return result;
}

std::vector<double> lines_from_intensities(const Scene& scene,
                                           const std::vector<double>& intensities, double clamp) {
  if (scene.tf.kind != TfKind::identity)
    throw Error(Status::invalid_argument,
                "intensities: converting them to line integrals needs the scene's tf to be "
                "identity (log I is linear in the voxels only through σ = a·d)");
  const double a = scene.tf.extinction_scale;
  if (!(a > 0))
    throw Error(Status::invalid_argument, "intensities: tf.extinction_scale must be > 0");
  const double i_in = scene.background ? scene.background->x : 1.0;
  if (!(i_in > 0) || !std::isfinite(i_in))
    throw Error(Status::invalid_argument, "intensities: the scene's background (I_in) must be > 0");
  if (!(clamp >= 0) || !(clamp < 1))
    throw Error(Status::invalid_argument,
                "intensities: the clamp must be in [0, 1), got " + number_text(clamp));
  if (scene.cameras.empty() && !scene.has_ray_list())
    throw Error(Status::invalid_argument, "intensities: the scene has no cameras");
  const ImageExtent c = image_extent(scene);
  const std::size_t rays = c.pixels();
  if (intensities.size() != rays)
    throw Error(Status::invalid_argument,
                "intensities: " + std::to_string(intensities.size()) + " values, but the scene's " +
                    (scene.has_ray_list() ? std::string("ray list")
                                          : std::to_string(scene.cameras.size()) + " cameras") +
                    " has " + std::to_string(rays) + " rays");
  std::vector<double> out(intensities.size());
  for (std::size_t i = 0; i < intensities.size(); ++i) {
    double I = intensities[i];
    if (!std::isfinite(I) || (!(I > 0) && clamp == 0)) {
      const std::size_t x = i % c.width, y = (i / c.width) % c.height,
                        view = i / (std::size_t(c.width) * c.height);
      throw Error(Status::invalid_argument,
                  "intensities: value " + number_text(I) + " at (" +
                      (scene.has_ray_list() ? "ray " + std::to_string(i)
                                            : "view " + std::to_string(view) + ", y " +
                                                  std::to_string(y) + ", x " + std::to_string(x)) +
                      (std::isfinite(I) ? ") is not > 0; log I needs positive intensities "
                                          "(or a clamp, --clamp-intensity)"
                                        : ") is not finite"));
    }
    I = std::max(I, clamp * i_in);
    out[i] = -std::log(I / i_in) / a;
  }
  return out;
}

}  // namespace ivr
