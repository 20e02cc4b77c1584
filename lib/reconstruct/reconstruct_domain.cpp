// reconstruct_domain.cpp — the reconstruction over slabs of z planes (ReconstructOptions::slabs):
// each worker's planes of the densities, their domain gradient, the priors counted once across
// slabs, and the planes neighbours share joined before the step.
#include <algorithm>
#include <cstring>
#include <string>

#include "brick/domain.hpp"
#include "ivr/error.hpp"
#include "reconstruct/reconstruct.hpp"
#include "reconstruct/reconstruct_params.hpp"
#include "runtime/real_args.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"

namespace ivr {

namespace {

constexpr const char* kWhat = "reconstruction over slabs";

[[noreturn]] void refuse(const std::string& what) {
  throw Error(Status::invalid_argument, std::string(kWhat) + ": " + what);
}

}  // namespace

void Reconstruction::Impl::setup_slabs() {
  if (!o.density)
    refuse("the TF alone differentiates the whole volume on every worker: split the views");
  if (scene.has_ray_list()) refuse("cameras only (a ray list is one view)");
  if (scene.integrator.tolerance > 0 && o.step == 0)
    refuse("a tolerance's step is chosen from the whole volume: give a step");
  part.rank = o.worker;
  part.ranks = o.workers;
  part.march = o.slab_march;
  part.shares = o.shares;  // (over slabs: each worker's share of the planes)
  if (o.workers > 1)
    part.all_gather = o.all_gather ? o.all_gather : all_gather_by_sum(o.worker, o.workers, o.sum);
  slab = domain_slab(scene.volume.nz, o.worker, o.workers, o.shares);
  // The slab's values as a volume of its planes (finite, >= 0), with the scene's description.
  Scene held = scene;
  held.volume.nz = slab.planes();
  if (held.volume.data.size() != held.volume.voxel_count())
    refuse("worker " + std::to_string(o.worker) + " of " + std::to_string(o.workers) +
           " holds planes " + std::to_string(slab.first) + ".." + std::to_string(slab.last) +
           ": the volume needs " + std::to_string(held.volume.voxel_count()) + " values, got " +
           std::to_string(held.volume.data.size()) + " (domain_share())");
  validate(held);
}

std::vector<double> Reconstruction::Impl::slab_gradient(const std::vector<int>& views,
                                                        IterationRecord& r,
                                                        std::vector<double>& tf_grad) {
  // The batch's cameras and targets; the level's grid, the slab's current densities.
  const std::vector<int>& grid = dims[std::size_t(level)];
  Scene batch = description_of(scene);
  batch.volume.nx = grid[0], batch.volume.ny = grid[1], batch.volume.nz = grid[2];
  batch.cameras.clear();
  for (int v : views) batch.cameras.push_back(scene.cameras[std::size_t(v)]);
  batch.volume.data.assign(slab_x.begin(), slab_x.end());
  const std::size_t per_view = targets.pixels.size() / scene.cameras.size();
  Image target(int(views.size()), targets.height, targets.width, targets.channels);
  for (int v : views)
    target.pixels.insert(target.pixels.end(),
                         targets.pixels.begin() + std::ptrdiff_t(std::size_t(v) * per_view),
                         targets.pixels.begin() + std::ptrdiff_t(std::size_t(v + 1) * per_view));
  GradientOptions go;
  go.precision = o.precision;
  go.step = o.step;
  go.loss = o.loss;
  // The slabs' bricks sum the density in fixed point where every worker's device can
  // (BrickedFixed): a run repeats bit for bit, so a resumed run equals an uninterrupted one.
  go.deterministic = o.deterministic;
  std::vector<std::string> groups = {"density"};
  if (o.tf) groups.push_back("tf");
  // (float64: the iterate as it is, not its floats)
  Gradient g = gradient_domain_values(device, batch, target, part, go, nullptr, groups,
                                      f64 ? &slab_x : nullptr);
  r.loss = g.loss;
  r.deterministic = g.deterministic;
  std::vector<double> grad = std::move(g.groups[0].values);
  const std::size_t voxels = grad.size();
  r.device_bytes = g.device_bytes + voxels * (f64 ? 8 : 4) *
                                        (o.optimizer.kind == OptimizerKind::adam ? 2 : 1);
  if (o.tf) tf_grad = sum_over(part, g.groups[1].values, kWhat);  // each slab's samples' part

  // The priors over the planes this worker owns — its slab less the plane it shares with the next
  // worker, whose first plane it is (the fixed-point density gradient's owner there too) — each
  // voxel's gradient whole and summed as one process sums it, from the slab and the plane below
  // it (its lower neighbour's, fetched); means over the whole volume, the value summed over the
  // workers.
  double prior_part = 0;
  if (o.tv > 0 || o.smoothness > 0) {
    const Volume& v = level_scene.volume;  // nx × ny × the slab's planes
    const std::size_t plane = std::size_t(v.nx) * std::size_t(v.ny);
    const bool first = o.worker == 0, last = o.worker + 1 == o.workers;
    std::vector<double> below = plane_below(plane);
    const int held = v.nz + (first ? 0 : 1);
    below.insert(below.end(), slab_x.begin(), slab_x.end());
    const cl::Buffer x = upload_reals(dev, f64, below, "the slab's densities");
    std::vector<double> held_grad(first ? 0 : plane, 0.0);
    held_grad.insert(held_grad.end(), grad.begin(), grad.end());
    const cl::Buffer gb = upload_reals(dev, f64, held_grad, "the slab's gradient");
    prior_part = prior->add_gradient(v.nx, v.ny, held, o.tv, o.smoothness, o.tv_epsilon, x, gb,
                                     first ? 0 : 1, last ? held : held - 1,
                                     double(grid[0]) * double(grid[1]) * double(grid[2]));
    held_grad = download_reals(dev, f64, gb, held_grad.size());
    grad.assign(held_grad.begin() + std::ptrdiff_t(first ? 0 : plane), held_grad.end());
  }
  r.prior = sum_over(part, {prior_part}, kWhat)[0];
  join_shared_planes(part, std::size_t(grid[0]) * std::size_t(grid[1]), grad, kWhat);
  return grad;
}

std::vector<double> Reconstruction::Impl::plane_below(std::size_t plane) const {
  // Every worker sends the plane below the one it shares with the next (a collective); each takes
  // its lower neighbour's. (A slab has at least 2 planes: one cell.)
  if (o.workers == 1) return {};
  const std::vector<double> mine(slab_x.end() - std::ptrdiff_t(2 * plane),
                                 slab_x.end() - std::ptrdiff_t(plane));
  std::vector<std::vector<double>> all = gather_doubles(part, mine, kWhat);
  return o.worker == 0 ? std::vector<double>{} : std::move(all[std::size_t(o.worker - 1)]);
}

Volume Reconstruction::Impl::gathered(int l, const std::vector<double>& mine) const {
  const std::vector<int>& grid = dims[std::size_t(l)];
  std::vector<std::vector<double>> slabs(std::size_t(o.workers));
  if (o.workers == 1) {
    slabs[0] = mine;
  } else {
    std::vector<unsigned char> bytes(mine.size() * sizeof(double));
    std::memcpy(bytes.data(), mine.data(), bytes.size());
    const std::vector<std::vector<unsigned char>> all = part.all_gather(bytes);
    for (std::size_t w = 0; w < slabs.size() && w < all.size(); ++w) {
      slabs[w].resize(all[w].size() / sizeof(double));
      std::memcpy(slabs[w].data(), all[w].data(), slabs[w].size() * sizeof(double));
    }
  }
  const std::vector<double> whole = domain_assemble(grid[0], grid[1], grid[2], slabs);  // (sizes checked)
  Volume v;
  v.nx = grid[0], v.ny = grid[1], v.nz = grid[2];
  v.data.assign(whole.begin(), whole.end());
  return v;
}

std::vector<double> Reconstruction::Impl::slab_of(const Volume& whole) const {
  const Slab s = domain_slab(whole.nz, o.worker, o.workers, o.shares);
  const std::size_t plane = std::size_t(whole.nx) * std::size_t(whole.ny);
  return std::vector<double>(whole.data.begin() + std::ptrdiff_t(plane * std::size_t(s.first)),
                             whole.data.begin() + std::ptrdiff_t(plane * std::size_t(s.last + 1)));
}

double Reconstruction::Impl::slabs_largest_density() const {
  double largest = 0;
  for (const std::vector<double>& w : gather_doubles(part, {largest_density(scene.volume)}, kWhat))
    largest = std::max(largest, w[0]);
  return largest;
}

std::size_t Reconstruction::Impl::held_voxels(int l) const {
  const std::vector<int>& d = dims[std::size_t(l)];
  const int planes = o.slabs ? domain_slab(d[2], o.worker, o.workers, o.shares).planes() : d[2];
  return std::size_t(d[0]) * std::size_t(d[1]) * std::size_t(planes);
}

}  // namespace ivr
