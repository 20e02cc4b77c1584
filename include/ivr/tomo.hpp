// ivr/tomo.hpp — absorption tomography: the exact projector N (log(I/I_in) = −N v), its exact
// transpose Nᵀ, and least-squares solvers on the device (CGLS, SIRT, LSQR).
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// N and Nᵀ for a scene's grid (volume dims and box) and cameras. (N v)[ray] = ∫ v(x(t)) dt over
// the ray's part in the box, with v the trilinear interpolant of the voxel values (docs/design.md
// conventions; t in world units), evaluated exactly: the `exact` integrator's pieces between
// centre planes, whatever the scene's integrator and step. Rays are the cameras' pixel rays
// (perspective: cone beam on a flat detector; orthographic: parallel beam), ordered (view, y, x).
// The scene's model and transfer function are not used: the voxel values are σ per world unit.
// Backproject computes exactly the transpose: ⟨N x, y⟩ = ⟨x, Nᵀ y⟩ up to rounding.
class IVR_API Projector {
 public:
  Projector(Device& device, const Scene& scene, Precision precision = Precision::f32);
  ~Projector();
  Projector(Projector&&) noexcept;
  Projector& operator=(Projector&&) noexcept;

  std::size_t voxel_count() const;  // nx·ny·nz
  std::size_t ray_count() const;    // views·height·width
  int views() const;
  int height() const;
  int width() const;
  Precision precision() const;

  // N v; v has voxel_count() values (x fastest), the result ray_count().
  std::vector<double> project(const std::vector<double>& volume) const;
  // Nᵀ p; p has ray_count() values, the result voxel_count().
  std::vector<double> backproject(const std::vector<double>& lines) const;
  // Device time of the last project/backproject kernel, seconds.
  double last_kernel_seconds() const;
  // The bricks the volume is split into (1: in core). Where the volume and the lines do not fit
  // the device memory ($IVR_DEVICE_MEMORY_LIMIT), or $IVR_VOLUME_BRICK asks, project() and
  // backproject() stream it through the device brick by brick (docs/scaling.md), the same N and
  // its exact transpose.
  int bricks() const;

  struct Impl;
  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

enum class Solver { cgls, sirt, lsqr };
IVR_API const char* solver_name(Solver solver);
// "cgls" | "sirt" | "lsqr"; throws ivr::Error(invalid_argument) naming `where` and the known ones.
IVR_API Solver parse_solver(const std::string& name, const std::string& where = "solver");

// Minimises ½‖N x − p‖² (SIRT: the row-normalised ‖·‖²_R) plus an optional regulariser:
//   tikhonov  λ/2 ‖x‖²
//   tv        λ Σ_i sqrt(|(D x)_i|² + ε²) (smoothed isotropic TV, forward differences), by lagged
//             diffusivity: the quadratic majoriser at x_k is re-weighted every `tv_reweight`
//             iterations (CGLS and LSQR restart there; SIRT re-weights every iteration)
// and optionally x ≥ 0 (projection after every iteration; CGLS and LSQR restart where the
// projection moved the iterate).
struct TomoOptions {
  Solver solver = Solver::cgls;
  Precision precision = Precision::f32;
  int iterations = 50;
  double tolerance = 0;      // > 0: stop once ‖p − N x‖ / ‖p‖ ≤ tolerance
  bool nonneg = false;       // project onto x ≥ 0
  double tikhonov = 0;       // λ ≥ 0
  double tv = 0;             // λ ≥ 0 (not together with tikhonov)
  double tv_epsilon = 1e-3;  // ε > 0 of the smoothed TV
  int tv_reweight = 10;      // CGLS/LSQR iterations between re-weightings
  double relaxation = 1.0;   // SIRT's ω in (0, 2)
  // Several devices (render, gradient, tomo over a vector of devices; docs/scaling.md): each
  // device's weight, its share of the views in proportion (view_shares) — or over slabs
  // (render_domain, tomo_domain over devices) of the volume's planes (domain_slab); one a device,
  // each > 0 and finite. Empty: each device's samples_per_second() (its calibration, else an
  // estimate from its size), so a GPU beside the CPU takes most views, or the longest slab.
  std::vector<double> shares{};
};

struct TomoIteration {
  int iteration = 0;    // 1-based
  double residual = 0;  // ‖p − N x‖ / ‖p‖ (the data term; 0 when p = 0)
  double seconds = 0;   // wall time since the solver started
};

struct TomoResult {
  std::vector<float> volume;           // the last iterate, the scene volume's shape
  std::vector<double> volume_f64;      // the same iterate unrounded (Precision::f64 only)
  std::vector<TomoIteration> history;  // one entry per completed iteration
  std::string stop_reason;             // "iterations", "tolerance", "interrupted"
  double setup_seconds = 0;            // compiling, uploads, SIRT's normalisations
  int bricks = 1;                      // the projector's bricks (> 1: out of core, host vectors)
};

// Called after each iteration with the iterate's statistics; return false to stop (the last
// iterate is then the result, stop_reason "interrupted").
using TomoProgress = std::function<bool(const TomoIteration&)>;

// Solves N x ≈ p for the scene's grid and cameras; p has ray_count() values (view, y, x), finite.
// x0 (optional, voxel_count() values) is the starting iterate, else zeros.
IVR_API TomoResult tomo(Device& device, const Scene& scene, const std::vector<double>& lines,
                        const TomoOptions& options, const TomoProgress& progress = {},
                        const std::vector<double>* x0 = nullptr);

// The same over several devices of one process: device i of n takes share i of the views
// (view_shares; a ray list: rays) and their lines, each a worker of tomo_shared() on a thread of
// its own, the sums meeting in the process; every device holds the whole iterate, and device 0's
// is returned (bricks: the largest device's). One process's to rounding. `progress` is asked on
// device 0 and stops every device. Throws Error(invalid_argument) for no or null devices.
IVR_API TomoResult tomo(const std::vector<Device*>& devices, const Scene& scene,
                        const std::vector<double>& lines, const TomoOptions& options,
                        const TomoProgress& progress = {});

// One worker's part of a reconstruction spread over workers by views (MPI ranks; docs/scaling.md):
// `share` holds this worker's views (scene_share()) and `lines` their projections; `sum` adds a
// vector over the workers in place (every worker getting the sum; an MPI_Allreduce). CGLS, SIRT or
// LSQR (with nonneg, Tikhonov or TV) on host vectors; every worker returns the same iterate. Each
// worker's `progress` (or none) is asked after every iteration and all stop where any says stop
// (one more sum of one value per iteration).
IVR_API TomoResult tomo_shared(Device& device, const Scene& share, const std::vector<double>& lines,
                               const TomoOptions& options,
                               const std::function<void(std::vector<double>&)>& sum,
                               const TomoProgress& progress = {});

// Line integrals from intensities: p = −log(I / I_in) / a, with I_in the scene's background and a
// the identity TF's extinction_scale (other TFs are refused: only the identity TF keeps log I
// linear in the voxels). I ≤ 0 or non-finite → ivr::Error naming the view and pixel, unless
// clamp > 0: then I is raised to clamp·I_in first (never NaN). The count must be ray_count().
IVR_API std::vector<double> lines_from_intensities(const Scene& scene,
                                                   const std::vector<double>& intensities,
                                                   double clamp = 0);

}  // namespace ivr
