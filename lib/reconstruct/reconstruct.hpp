// reconstruct.hpp — the state of a reconstruction (ivr::Reconstruction), shared by the loop
// (lib/reconstruct/reconstruct.cpp) and its checkpoints (lib/reconstruct/reconstruct_checkpoint.cpp).
#pragma once
#include <memory>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "ivr/domain.hpp"
#include "ivr/reconstruct.hpp"
#include "ivr/session.hpp"
#include "reconstruct/lbfgs.hpp"
#include "reconstruct/priors.hpp"
#include "reconstruct/reconstruct_params.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

struct Reconstruction::Impl {
  Device& device;
  Device::Impl& dev;
  Scene scene;  // the full grid; volume.data: the start (Init::scene) or the fixed volume (TF)
  Image targets;
  ReconstructOptions o;  // resolved: optimiser kind and lr
  bool f64 = false;
  double scale = 1;  // density_scale(scene), over slabs the whole volume's: steps are lr · scale

  std::vector<std::vector<int>> dims;  // per level (nx, ny, nz)
  std::vector<int> level_end;          // completed iterations at the end of each level
  int level = -1;                      // the level on the device (-1: none yet)
  int k = 0;                           // completed iterations
  int fixed_everywhere = -1;  // workers: every device sums in fixed point (1) or not (0); -1 unasked
  std::vector<IterationRecord> history;

  // Density (o.density): the level's grid, resident in a session (densities, cameras, TF); the
  // targets on the device once, batches gathered there.
  Scene level_scene;  // the level's grid; volume.data empty (the densities live in the session)
  std::unique_ptr<Session> session;
  DeviceArray all_targets;
  std::unique_ptr<Optimizer> density_opt;
  std::unique_ptr<DensityPrior> prior;

  // Over slabs (o.slabs; lib/reconstruct/reconstruct_domain.cpp): this worker's planes of the
  // level's grid, their densities on the host (level_scene: nx × ny × planes), the exchange.
  Slab slab;
  DomainPart part;
  std::vector<double> slab_x;

  // TF (o.tf): normalised parameters u = value / bounds.scale.
  std::vector<double> u;
  TfBounds bounds;
  std::unique_ptr<Optimizer> tf_opt;
  std::unique_ptr<Lbfgs> lbfgs;

  Impl(Device& device, const Scene& scene, const Image& targets, const ReconstructOptions& o);
  int level_of(int iteration) const;  // the level iteration `iteration` (0-based) runs on
  // Puts `density` (the level's grid, x fastest) on the device with a fresh optimiser.
  void enter_level(int l, const std::vector<double>& density);
  std::vector<double> density_host() const;  // the level's densities, read back
  Volume level_volume() const;
  void apply_tf();  // u → scene.tf and level_scene.tf
  OptimizerOptions density_optimizer_options(int l) const;
  const IterationRecord& step();
  // The targets of `views` on the device: all of them, or a batch gathered from them.
  DeviceArray batch_targets(const std::vector<int>& views);
  // A worker's view of the batch `batch` (o.workers > 1): lib/adjoint/adjoint.hpp.
  FixedShare batch_share(const std::vector<int>& batch) const;

  // Over slabs: checks the options and the slab (of the whole grid), and sets part.
  void setup_slabs();
  // Every worker's planes `mine` of level l's grid joined into its volume (collective), and this
  // worker's planes of a volume of a level's grid.
  Volume gathered(int l, const std::vector<double>& mine) const;
  std::vector<double> slab_of(const Volume& whole) const;
  // The plane below this worker's slab (its lower neighbour's; none for worker 0): a collective.
  std::vector<double> plane_below(std::size_t plane) const;
  double slabs_largest_density() const;  // the largest density over every worker's slab
  // Level l's voxels this worker holds: the grid's, or over slabs its planes'.
  std::size_t held_voxels(int l) const;
  // The batch `views`' loss and this worker's planes of the density gradient (the shared planes
  // joined), with the priors; the TF's gradient summed over the workers (o.tf). Fills r.loss,
  // r.prior and r.device_bytes.
  std::vector<double> slab_gradient(const std::vector<int>& views, IterationRecord& r,
                                    std::vector<double>& tf_grad);
};

}  // namespace ivr
