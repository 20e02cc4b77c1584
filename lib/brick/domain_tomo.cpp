// domain_tomo.cpp — CGLS over slabs (tomo_domain): each worker holds its slab of the iterate and
// projects it; the lines are summed over the workers, the shared planes' back-projections joined.
#include <algorithm>
#include <chrono>
#include <cstring>

#include "brick/bricked_project.hpp"
#include "brick/domain.hpp"
#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "scene/scene.hpp"
#include "tomo/host_solvers.hpp"
#include "tomo/project.hpp"

namespace ivr {

namespace {

// Every worker's doubles, in rank order (through the part's all_gather).
std::vector<std::vector<double>> gather_doubles(const DomainPart& part,
                                                const std::vector<double>& mine) {
  std::vector<unsigned char> bytes(mine.size() * sizeof(double));
  if (!mine.empty()) std::memcpy(bytes.data(), mine.data(), bytes.size());
  const std::vector<std::vector<unsigned char>> all = part.all_gather(bytes);
  if (int(all.size()) != part.ranks)
    throw Error(Status::invalid_argument, "domain reconstruction: all_gather gave " +
                                              std::to_string(all.size()) + " parts for " +
                                              std::to_string(part.ranks) + " workers");
  std::vector<std::vector<double>> out(all.size());
  for (std::size_t w = 0; w < all.size(); ++w) {
    if (all[w].size() != bytes.size())
      throw Error(Status::invalid_argument, "domain reconstruction: worker " + std::to_string(w) +
                                                " sent " + std::to_string(all[w].size()) +
                                                " bytes, not " + std::to_string(bytes.size()) +
                                                " (do the workers share one scene?)");
    out[w].resize(mine.size());
    if (!mine.empty()) std::memcpy(out[w].data(), all[w].data(), all[w].size());
  }
  return out;
}

// The sum over the workers, added in rank order (the same bits on every worker).
std::vector<double> sum_over(const DomainPart& part, const std::vector<double>& mine) {
  if (part.ranks == 1) return mine;
  const std::vector<std::vector<double>> all = gather_doubles(part, mine);
  std::vector<double> sum(mine.size(), 0.0);
  for (const std::vector<double>& w : all)
    for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += w[i];
  return sum;
}

template <typename T>
void solve(Projector::Impl& P, const DomainPart& part, const std::vector<double>& lines,
           const TomoOptions& o, Monitor& m, std::vector<T>& x) {
  const BrickLayout& l = P.bricks;
  const std::size_t plane = std::size_t(l.dims[0]) * l.dims[1], held = l.held();
  const bool below = part.rank > 0, above = part.rank + 1 < part.ranks;
  HostSplit<T> A;
  A.project = [&](const std::vector<T>& v) {  // Σ_j N_j v_j: every line on every worker
    return sum_over(part, project_bricked(P, l, v.data()));
  };
  A.backproject = [&](const std::vector<double>& y, std::vector<T>& out) {
    out.resize(held);
    backproject_bricked(P, l, y, out.data());
    if (part.ranks == 1) return;
    // A shared plane holds each neighbour's part: each adds the other's (a + b = b + a, so both
    // workers hold the same values there).
    std::vector<double> ends(2 * plane);
    for (std::size_t i = 0; i < plane; ++i)
      ends[i] = double(out[i]), ends[plane + i] = double(out[held - plane + i]);
    const std::vector<std::vector<double>> all = gather_doubles(part, ends);
    if (below)
      for (std::size_t i = 0; i < plane; ++i) out[i] = T(out[i] + all[part.rank - 1][plane + i]);
    if (above)
      for (std::size_t i = 0; i < plane; ++i)
        out[held - plane + i] = T(out[held - plane + i] + all[part.rank + 1][i]);
  };
  A.dot_lines = [](const std::vector<double>& a, const std::vector<double>& b) {
    return host_dot(a, b);  // the lines are whole on every worker
  };
  A.dot_volume = [&](const std::vector<T>& a, const std::vector<T>& b) {
    // Over the planes this worker owns (a shared plane is its lower neighbour's).
    double mine = 0;
    for (std::size_t i = below ? plane : 0; i < a.size(); ++i) mine += double(a[i]) * double(b[i]);
    return sum_over(part, {mine})[0];
  };
  A.any = [&](bool flag) { return sum_over(part, {flag ? 1.0 : 0.0})[0] > 0; };
  solve_host(A, lines, x, o, m);
}

}  // namespace

TomoResult tomo_domain(Device& device, const Scene& scene, const std::vector<double>& lines,
                       const DomainPart& part, const TomoOptions& options,
                       const TomoProgress& progress) {
  check_domain_part(part);
  check_tomo_options(options);
  check_host_solver(options, "domain-parallel reconstruction", false);
  const auto t0 = std::chrono::steady_clock::now();
  const Slab slab = domain_slab(scene.volume.nz, part.rank, part.ranks);
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
  Monitor monitor(options, progress, std::sqrt(host_dot(lines, lines)), result);
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
