// ivr/reconstruct.hpp — inverse rendering: recover the voxel densities, the transfer function or
// both from images of known cameras, one iteration at a time (coarse to fine, random view
// batches, priors), with checkpoints that continue bit-for-bit. What `ivr reconstruct` runs.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/domain.hpp"
#include "ivr/export.h"
#include "ivr/adjoint.hpp"
#include "ivr/optimize.hpp"
#include "ivr/planner.hpp"
#include "ivr/scene.hpp"

namespace ivr {

// Where the unknowns start: the scene's own volume / TF, zeros, or a constant density
// (init_value; a TF is then the scene's). Zero densities are a stationary point of the
// emission–absorption loss (σ = 0 and c·σ = 0 have zero derivatives there), so `zeros` suits
// absorption scenes only; `constant` is the usual start for emission–absorption.
enum class Init { scene, zeros, constant };

// OptimizerOptions with lr = 0: the reconstruction chooses it.
inline OptimizerOptions automatic_lr() {
  OptimizerOptions o;
  o.lr = 0;
  return o;
}

struct ReconstructOptions {
  // What is optimised (at least one): every voxel (adjoint mode) and/or the TF's parameters in
  // the layout of tf_gradient_shape (alone: in forward mode, see `mode`).
  bool density = true;
  bool tf = false;
  int iterations = 300;  // in total, over every coarse-to-fine level
  // kind, lr, schedule, Adam/SGD/L-BFGS settings. lr is relative to each parameter's scale
  // (densities: the TF's density span, see density_scale; TF columns: colours 1, extinctions
  // their largest value): 0 (the default) picks 0.025 for Adam, 0.05 as L-BFGS's first step; SGD
  // needs one. The bounds are set per parameter (density ≥ 0, colours in [0, 1], extinction ≥ 0,
  // Gaussian widths > 0); schedules restart with the fresh moments of every level.
  OptimizerOptions optimizer = automatic_lr();
  bool automatic_optimizer = true;  // adam, or lbfgs when only the TF is optimised
  Loss loss = Loss::mse;
  // Priors added to the image loss: tv · mean(sqrt(|∇x|² + ε²) − ε) + smoothness · mean |∇x|²
  // over the voxels (forward differences), and tf_smoothness · mean over consecutive TF rows of
  // the squared difference of their normalised parameters.
  double tv = 0, smoothness = 0, tf_smoothness = 0, tv_epsilon = 1e-2;
  int batch = 0;   // views per iteration, drawn at random (0: every view)
  int levels = 0;  // coarse-to-fine levels, each doubling the grid (0: 3 when the grid allows)
  Init init = Init::scene;
  double init_value = 0.5;  // Init::constant
  std::uint64_t seed = 1;   // of the view batches
  Precision precision = Precision::f32;
  double step = 0;  // > 0 overrides the scene's integrator step (voxel units)
  // The TF alone: forward or adjoint; automatic = forward up to 32 parameters (deterministic:
  // runs repeat bit for bit), else the planner's choice. Density gradients are always adjoint.
  Mode mode = Mode::automatic;
  // Densities' gradients summed in fixed point (AdjointOptions::deterministic, where the
  // device has 64-bit integer atomics): a run repeats bit for bit whatever the thread
  // scheduling, so a resumed run equals an uninterrupted one. The joint mode's TF rows keep
  // their float atomics (their last bits vary).
  bool deterministic = true;
  // Data-parallel over views (mpirun -np N ivr reconstruct; docs/scaling.md): this worker is
  // `worker` of `workers`. Every worker draws the same batch, differentiates its contiguous share
  // of the batch's views, and `sum` adds the loss and the gradients over the workers in place
  // (every worker getting the sum: an MPI_Allreduce), so that every worker takes the same step and
  // holds the same iterate: with `deterministic` fixed-point density gradients (on every worker's
  // device) the one process's bit for bit when the TF is fixed (each share scaled as the batch's
  // one march, the integer sums added exactly), else up to the rounding of the sums. `sum` must
  // add doubles holding integers below 2^53 exactly (an MPI_Allreduce does). Cameras only (not a
  // ray list); every batch needs at least `workers` views; checkpoints are every worker's.
  int worker = 0, workers = 1;
  std::function<void(std::vector<double>&)> sum;
  // Domain-parallel over slabs of z planes instead (mpirun -np N ivr reconstruct --split slabs;
  // docs/scaling.md): worker `worker` holds only planes domain_slab(nz, worker, workers, shares) of
  // the densities (scene.volume.data holds just those: domain_share(), load_scene(path, planes))
  // and their optimiser state; every worker marches every view of each batch through its slab
  // (gradient_domain: the rays' states pass between the workers), the planes neighbours share are
  // joined and the priors' differences across slabs counted once, so every worker's iterate is
  // one process's to rounding on its planes. Densities (and the TF jointly, its slab parts summed)
  // with Adam or SGD, cameras only; coarse-to-fine levels gather the coarse grid on every worker
  // when a level ends (and a scene start once, to resample it), each keeping its fine planes, and
  // have at least one cell per worker along z. With `deterministic` the slabs' bricks sum the
  // density in fixed point where every worker's device has 64-bit integer atomics: one
  // process's gradient bit for bit (slab_march states; the priors summed whole per voxel by its
  // plane's owner), so the densities are one process's bits (densities alone: a TF learnt jointly
  // keeps float sums) and a resumed run equals an uninterrupted one (independent segments: the
  // same bits on every run).
  // result() holds this worker's planes of the current level's grid; checkpoints are each
  // worker's own (give each its own prefix). `all_gather` passes bytes between the
  // workers (an MPI_Allgatherv); empty: built from `sum` (all_gather_by_sum).
  bool slabs = false;
  AllGather all_gather;
  // Over slabs: pass the rays' march states (exact, early termination included) or march each
  // worker's segments of every ray at once and composite them (ivr/domain.hpp, SlabMarch).
  SlabMarch slab_march = SlabMarch::states;
  // Over views: each worker's weight, its share of each batch's views in proportion
  // (view_shares; every worker passing the same; empty: equal shares). MultiDeviceReconstruction:
  // one a device, empty taking share_weights() — their speeds; a device whose share of a batch
  // would be empty does not take part. Over slabs (slabs): each worker's share of the volume's
  // planes, domain_slab(nz, worker, workers, shares) at every level (empty: equal slabs; every
  // worker passing the same); MultiDeviceReconstruction: share_weights(), every device a slab.
  std::vector<double> shares{};
};

// Throws ivr::Error(invalid_argument) naming the first bad option.
IVR_API void validate_reconstruct(const ReconstructOptions& options);

struct IterationRecord {
  int iteration = 0;   // 1-based, over all levels
  int level = 0;       // 0 = the coarsest
  double loss = 0;     // image loss of the iteration's batch, at its start
  double prior = 0;    // the priors' value there
  double lr = 0;       // the learning rate used (L-BFGS: its initial step)
  double seconds = 0;  // wall time of the iteration
  int views = 0;       // in the batch
  // Device memory held during the iteration: the gradient evaluation's buffers plus the
  // densities and the optimiser's moments (0 for the TF alone, whose state is a few values).
  std::uint64_t device_bytes = 0;
  // The densities' gradient was summed in fixed point (`deterministic` where the devices can;
  // like device_bytes, not kept by checkpoints).
  bool deterministic = false;
};

class IVR_API Reconstruction {
 public:
  // `targets`: the images of every camera of `scene` (its render's shape). The scene's volume
  // gives the grid (and the start with Init::scene), its TF the known or starting TF.
  Reconstruction(Device& device, const Scene& scene, const Image& targets,
                 const ReconstructOptions& options = {});
  ~Reconstruction();
  Reconstruction(Reconstruction&&) noexcept;
  Reconstruction& operator=(Reconstruction&&) noexcept;

  const IterationRecord& step();  // one iteration; ivr::Error(invalid_argument) once done()
  bool done() const;
  int iteration() const;  // completed iterations
  const std::vector<IterationRecord>& history() const;
  const ReconstructOptions& options() const;  // with the optimiser and lr actually used
  int levels() const;
  std::vector<int> level_dims(int level) const;  // (nx, ny, nz) of a level

  // The estimate so far: the scene with the current densities (at the full grid: upsampled
  // from a coarser level) and TF. Over slabs: this worker's planes of the current level's grid
  // (volume's dims the level's, volume.data only the planes).
  Scene result() const;

  // PREFIX_checkpoint.json and PREFIX_checkpoint_*.npy (float64): iteration, level, parameters,
  // optimiser state and history; each file replaced atomically, the JSON last.
  void save_checkpoint(const std::string& prefix) const;
  // Continues from a checkpoint of the same scene, targets' shape and options (an error names
  // the first that differs); the run then proceeds exactly as the one that wrote it (bit for bit
  // with `deterministic` gradients, the TF alone, or a device that orders its atomics).
  void resume(const std::string& prefix);
  // Deletes the checkpoint files of `prefix` (those that exist): after a finished run.
  static void remove_checkpoint(const std::string& prefix);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// A reconstruction over several devices of one process (docs/scaling.md), each device a worker
// running its part of every step on a thread of its own, the devices' sums and exchanges meeting
// in the process where MPI ranks' would meet over the network. options.slabs chooses the split:
// - slabs (true): device i of n holds planes domain_slab(nz, i, n, w) of the densities and their
//   optimiser state (w = share_weights(devices, options.shares); slab_march as given), so a volume that fits no
//   one device is reconstructed on all of them;
// - views (false): every device holds the whole volume and marches its share of each batch's
//   views, the gradients summed (ReconstructOptions::workers; fixed point where `deterministic`,
//   so the run is one device's bit for bit): several devices' speed on one volume. The shares
//   follow options.shares, else share_weights() — the devices' speeds; a device whose share of a
//   batch would be empty takes no part (devices() counts those that do, and checkpoints are
//   theirs: resume with the same devices and shares).
// Equal to the workers' reconstruction (one process's to rounding). `scene` holds the whole volume
// (the start with Init::scene); options.worker, workers, sum and all_gather must be left unset
// (they are the devices'). After a device fails, the object refuses further steps.
class IVR_API MultiDeviceReconstruction {
 public:
  MultiDeviceReconstruction(const std::vector<Device*>& devices, const Scene& scene,
                            const Image& targets, const ReconstructOptions& options = {});
  ~MultiDeviceReconstruction();
  MultiDeviceReconstruction(MultiDeviceReconstruction&&) noexcept;
  MultiDeviceReconstruction& operator=(MultiDeviceReconstruction&&) noexcept;

  const IterationRecord& step();  // device 0's record (the loss and prior are every device's)
  bool done() const;
  int iteration() const;
  const std::vector<IterationRecord>& history() const;
  int devices() const;  // the devices taking part
  const ReconstructOptions& options() const;  // device 0's, with what automatic resolved to
  int levels() const;
  std::vector<int> level_dims(int level) const;  // (nx, ny, nz) of a level's whole grid
  // The current level's grid, whole (slabs: every device's planes joined, domain_assemble;
  // views: device 0's); at the last level the full grid.
  Scene result() const;
  // Device i's checkpoint under PREFIX_deviceI (its planes or volume and state; Reconstruction's
  // files).
  void save_checkpoint(const std::string& prefix) const;
  void resume(const std::string& prefix);
  // Deletes the checkpoint files of `prefix`'s `devices` devices (those that exist).
  static void remove_checkpoint(const std::string& prefix, int devices);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Peak signal-to-noise ratio of `image` against `reference` over every element, with peak 1
// (images in [0, 1]): 10·log10(1 / mse); +infinity when they are equal.
IVR_API double psnr(const Image& image, const Image& reference);

// ‖a − b‖₂ / ‖b‖₂ over the voxels (same shape; 0 when both are zero).
IVR_API double relative_volume_error(const Volume& a, const Volume& b);

// The volume resampled to nx × ny × nz cells over the same box: each new cell is the mean of the
// trilinear density (docs/design.md's convention) at ⌈old/new⌉³ points spread over it.
IVR_API Volume resample_volume(const Volume& volume, int nx, int ny, int nz);

}  // namespace ivr
