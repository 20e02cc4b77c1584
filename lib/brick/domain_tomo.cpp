// domain_tomo.cpp — CGLS over slabs (tomo_domain): each worker holds its slab of the iterate and
// projects it; the lines are summed over the workers, the shared planes' back-projections joined.
#include <algorithm>
#include <chrono>

#include "brick/bricked_project.hpp"
#include "brick/domain.hpp"
#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "scene/scene.hpp"
#include "tomo/host_solvers.hpp"
#include "tomo/project.hpp"

namespace ivr {

namespace {

constexpr const char* kWhat = "domain reconstruction";

template <typename T>
void solve(Projector::Impl& P, const DomainPart& part, const std::vector<double>& lines,
           const TomoOptions& o, Monitor& m, std::vector<T>& x) {
  const BrickLayout& l = P.bricks;
  const std::size_t plane = std::size_t(l.dims[0]) * l.dims[1], held = l.held();
  const bool below = part.rank > 0;
  HostSplit<T> A;
  A.project = [&](const std::vector<T>& v) {  // Σ_j N_j v_j: every line on every worker
    return sum_over(part, project_bricked(P, l, v.data()), kWhat);
  };
  A.backproject = [&](const std::vector<double>& y, std::vector<T>& out) {
    out.resize(held);
    backproject_bricked(P, l, y, out.data());
    join_shared_planes(part, plane, out, kWhat);  // each neighbour's part of a shared plane
  };
  A.dot_lines = [](const std::vector<double>& a, const std::vector<double>& b) {
    return host_dot(a, b);  // the lines are whole on every worker
  };
  A.dot_volume = [&](const std::vector<T>& a, const std::vector<T>& b) {
    // Over the planes this worker owns (a shared plane is its lower neighbour's).
    double mine = 0;
    for (std::size_t i = below ? plane : 0; i < a.size(); ++i) mine += double(a[i]) * double(b[i]);
    return sum_over(part, {mine}, kWhat)[0];
  };
  A.any = [&](bool flag) { return sum_over(part, {flag ? 1.0 : 0.0}, kWhat)[0] > 0; };
  // TV: the slab's grid, the rows of the planes it owns (its last is the next slab's), the rows'
  // sums over the workers and their parts of the shared planes joined.
  A.nx = l.dims[0], A.ny = l.dims[1], A.nz = int(held / plane);
  A.row_planes = part.rank + 1 < part.ranks ? A.nz - 1 : A.nz;
  A.total = [&](double mine) { return sum_over(part, {mine}, kWhat)[0]; };
  A.join = [&](std::vector<T>& v) { join_shared_planes(part, plane, v, kWhat); };
  solve_host(A, lines, x, o, m);
}

}  // namespace

TomoResult tomo_domain(Device& device, const Scene& scene, const std::vector<double>& lines,
                       const DomainPart& part, const TomoOptions& options,
                       const TomoProgress& progress) {
  check_domain_part(part);
  check_tomo_options(options);
  const auto t0 = std::chrono::steady_clock::now();
  const Slab slab = part_slab(scene.volume.nz, part);
  Projector projector(device, description_of(scene), options.precision);
  Projector::Impl& P = projector.impl();
  if (lines.size() != P.rays)
    throw Error(Status::invalid_argument, "projections: " + std::to_string(lines.size()) +
                                              " values for the scene's " + std::to_string(P.rays) +
                                              " rays (every worker passes all of them)");
  // The slab's bricks: as its device's memory needs, else one brick of the whole slab.
  Scene slab_scene = description_of(scene);
  slab_scene.volume.nz = slab.planes();
  int edge = plan_projector(device, slab_scene, options.precision).edge;
  if (!edge) edge = std::max({scene.volume.nx - 1, scene.volume.ny - 1, slab.planes() - 1, 1});
  P.bricks =
      brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, edge, slab.first, slab.last);
  TomoResult result;
  result.bricks = P.bricks.total();
  result.setup_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const TomoProgress agreed = agreed_progress(
      progress, [&](double v) { return sum_over(part, {v}, kWhat)[0]; });
  Monitor monitor(options, agreed, std::sqrt(host_dot(lines, lines)), result);
  if (options.precision == Precision::f32) {  // float iterates, as the out-of-core solver's
    result.volume.assign(P.bricks.held(), 0.0f);
    solve(P, part, lines, options, monitor, result.volume);
    return result;
  }
  std::vector<double> x(P.bricks.held(), 0.0);
  solve(P, part, lines, options, monitor, x);
  result.volume.assign(x.begin(), x.end());
  result.volume_f64 = std::move(x);
  return result;
}

}  // namespace ivr
