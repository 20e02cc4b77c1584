// gradient_share.cpp — the one-shot gradient as one worker of several, data-parallel over views
// (GradientOptions::workers: mpirun, several devices): the worker's share of the views
// differentiated, and the workers' results combined through their sum, so that every worker holds
// the whole gradient — with fixed point, the one process's density gradient bit for bit.
#include <algorithm>
#include <cmath>

#include "gradient/gradient.hpp"
#include "ivr/error.hpp"
#include "ivr/tolerance.hpp"
#include "multi_device/run_shares.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

namespace {

Error bad(const GradientOptions& o, const std::string& what) {
  return Error(Status::invalid_argument, "gradient: worker " + std::to_string(o.worker) + " of " +
                                             std::to_string(o.workers) + ": " + what);
}

// The step every worker marches: where the scene asks for a tolerance, worker 0 chooses it for
// the whole scene (a share's pilots could choose another) and the others take it.
double agreed_step(Device& device, const Scene& scene, const GradientOptions& o) {
  if (o.step != 0 || scene.integrator.tolerance <= 0) return o.step;
  std::vector<double> step{0.0};
  if (o.worker == 0)
    step[0] = integrator_for(device, scene, 0, o.precision, EmptySpace::automatic).step;
  o.sum(step);
  return step[0];
}

bool whole_when_fixed(const std::string& group) { return group == "density" || group == "voxels"; }

}  // namespace

Gradient gradient_shared(Device& device, const Scene& scene, const Image& target,
                         const std::vector<std::string>& groups, const GradientOptions& o) {
  if (o.workers < 1 || o.worker < 0 || o.worker >= o.workers) throw bad(o, "no such worker");
  if (!o.sum) throw bad(o, "no sum (GradientOptions::sum) to combine the workers' shares");
  // What every worker checks alike, before any collective.
  std::vector<std::vector<std::size_t>> shapes;
  for (const std::string& g : groups) shapes.push_back(group_shape(scene, g));
  const std::size_t n = share_items(scene);
  const std::size_t per_item = scene.has_ray_list()
                                   ? std::size_t(scene.channels())
                                   : std::size_t(target.height) * target.width * target.channels;
  if (n == 0 || target.pixels.size() != n * per_item)
    throw bad(o, "the target holds " + std::to_string(target.pixels.size()) +
                     " values, the scene's images " + std::to_string(n * per_item));
  const auto [first, count] = worker_share(n, o.worker, o.workers, o.shares);
  const bool active = count > 0;

  GradientOptions mine = o;
  mine.worker = 0, mine.workers = 1, mine.sum = {};
  mine.step = agreed_step(device, scene, o);
  // The batch as the one process's adjoint sees it: its normaliser, ray count and target range.
  FixedShare batch;
  batch.elements = target.pixels.size();
  batch.rays = scene.has_ray_list() ? n : n * std::size_t(target.height) * target.width;
  for (float v : target.pixels) batch.target_max = std::max(batch.target_max, std::abs(double(v)));
  set_share_collectives(batch, o.worker, o.workers, o.sum);
  const bool density = std::any_of(groups.begin(), groups.end(), [&](const std::string& g) {
    return whole_when_fixed(g.substr(0, g.find(':')));  // (voxels:LIST)
  });
  bool fixed = false;
  // Fixed point where every worker votes for it, in core or over bricks of any edge alike: the
  // out-of-core integer sums are the in-core ones bit for bit (lib/brick/bricked_fixed.hpp), so
  // the shares' sums are one process's whatever each worker's device holds.
  const ShareDecision decide = [&](Mode planned) -> const FixedShare* {
    std::vector<double> votes{o.deterministic && active && density && planned == Mode::adjoint &&
                                      has_int64_atomics(device.impl())
                                  ? 1.0
                                  : 0.0};
    o.sum(votes);
    fixed = votes[0] == double(o.workers);
    return fixed ? &batch : nullptr;
  };
  Gradient out;
  if (active) {
    out = gradient_one(device, scene_share(scene, first, count),
                       target_share(scene, target, first, count), groups, mine, decide);
  } else {  // no view for this worker: zeros of every group's shape, in every collective
    decide(Mode::forward);
    for (std::size_t k = 0; k < groups.size(); ++k) {
      GroupGradient g;
      g.name = groups[k].substr(0, groups[k].find(':'));
      g.shape = shapes[k];
      if (per_view_group(g.name)) g.shape[0] = 0;
      std::size_t size = 1;
      for (std::size_t d : g.shape) size *= d;
      g.values.assign(size, 0.0);
      out.groups.push_back(g);
    }
    out.step = mine.step != 0 ? mine.step : scene.integrator.step;
  }
  // The shares' means weighted by their sizes (the mean losses; dot: summed); with fixed point
  // every share already holds its part of the batch's mean, and the density the whole of it.
  const double weight =
      fixed || o.loss == Loss::dot ? 1.0 : double(count) / double(n);
  std::vector<double> sums{weight * out.loss};
  for (const GroupGradient& g : out.groups)
    if (!per_view_group(g.name) && !(fixed && whole_when_fixed(g.name)))
      for (double v : g.values) sums.push_back(weight * v);
  o.sum(sums);
  out.loss = sums[0];
  std::size_t at = 1;
  for (std::size_t k = 0; k < out.groups.size(); ++k) {
    GroupGradient& g = out.groups[k];
    if (per_view_group(g.name)) {  // rows in view order: each worker's in its place among zeros
      std::size_t row = 1;
      for (std::size_t d = 1; d < shapes[k].size(); ++d) row *= shapes[k][d];
      std::vector<double> rows(n * row, 0.0);
      for (std::size_t i = 0; i < std::min(g.values.size(), count * row); ++i)
        rows[first * row + i] = weight * g.values[i];
      o.sum(rows);
      g.values = rows;
      g.shape = shapes[k];
    } else if (!(fixed && whole_when_fixed(g.name))) {
      for (double& v : g.values) v = sums[at++];
    }
  }
  out.parameters = 0;
  for (const GroupGradient& g : out.groups) out.parameters += g.values.size();
  out.deterministic = fixed;
  return out;
}

}  // namespace ivr
