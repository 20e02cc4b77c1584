// ivr/domain.hpp — domain-parallel render and density gradient (docs/scaling.md): the volume cut
// into slabs of z planes, one per worker (an MPI rank); each worker holds only its slab and
// marches the parts of the rays inside it, and the rays' march states pass between the workers
// until every ray is done, so that the image and the gradient equal one process's.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/gradient.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "ivr/tomo.hpp"

namespace ivr {

// A worker's planes of the volume: [first, last] (neighbours share one plane, the halo).
struct Slab {
  int first = 0, last = 0;
  int planes() const { return last - first + 1; }
};

// Worker `rank` of `ranks`' slab of a volume of nz planes: its nz − 1 cells in near-equal runs.
// Throws Error(invalid_argument) where there are more workers than cells (ranks > nz − 1).
IVR_API Slab domain_slab(int nz, int rank, int ranks);

// The same with each worker's share of the cells in proportion to its weight in `shares` (one a
// worker, each > 0 and finite; a device's speed, share_weights()): the largest-remainder split of
// view_shares_each(), every worker at least one cell. Empty or all equal: the near-equal runs
// above. A fast device's slab is longer, so that the workers' marches take about as long.
IVR_API Slab domain_slab(int nz, int rank, int ranks, const std::vector<double>& shares);

// `scene` with only worker rank's slab of its densities in volume.data (what render_domain() and
// gradient_domain() take; a worker that loads the whole volume keeps only this).
IVR_API Scene domain_share(const Scene& scene, int rank, int ranks);
IVR_API Scene domain_share(const Scene& scene, int rank, int ranks,
                           const std::vector<double>& shares);

// Every worker's bytes, in rank order, handed to every worker (an MPI_Allgatherv); called by all
// workers together.
using AllGather =
    std::function<std::vector<std::vector<unsigned char>>(const std::vector<unsigned char>& mine)>;

// An AllGather built from a sum over the workers alone (`sum` replaces a vector by its elementwise
// sum over the workers, every worker getting it: an MPI_Allreduce with MPI_SUM, as bindings have
// it): the sizes, then the bytes (4 a double, as integers, so the sums are exact) each in its
// worker's place among zeros. Costs the workers' total bytes twice over per call.
IVR_API AllGather all_gather_by_sum(int rank, int ranks,
                                    std::function<void(std::vector<double>&)> sum);

// How the workers march the rays through their slabs (docs/scaling.md).
enum class SlabMarch {
  // The rays' march states passed between the workers after each sweep: the unsplit march exactly
  // (early termination included), but a ray is marched by one worker at a time.
  states,
  // Every worker marches its slab's segment of every ray at once, from transmittance 1; the
  // segments are exchanged once and composited in order along each ray, and the adjoint starts
  // each worker's segment from the transmittance and radiance in front of it. Equal to the
  // unsplit march to rounding where early termination is off (integrator.min_transmittance 0);
  // with it on, a segment stops where its own transmittance falls below the threshold, so a ray
  // goes on where the unsplit march would have stopped (a difference below min_transmittance
  // times the radiance and background behind). Render, the density, TF and background gradients
  // (the adjoint), and the forward lanes' (camera, scales, tf_points, voxels, rays: each
  // segment's tangents composited as dC = dC₁ + dT₁·C₂ + T₁·dC₂, dT = dT₁·T₂ + T₁·dT₂).
  segments,
};

// This worker's part of a domain-parallel operation.
struct DomainPart {
  int rank = 0, ranks = 1;
  AllGather all_gather;  // the exchange of the rays' states after each sweep over the slabs
  SlabMarch march = SlabMarch::states;  // (every worker the same)
  // Each worker's weight, its slab domain_slab(nz, rank, ranks, shares) (every worker the same;
  // empty: equal slabs). The worker's scene holds that slab (domain_share with the same shares).
  std::vector<double> shares{};
};

// How a domain-parallel operation went, per worker.
struct DomainStats {
  int exchanges = 0;                 // rounds of the rays' states passed between workers
  std::uint64_t sent_bytes = 0;      // this worker's changed ray states sent, all rounds
  std::uint64_t received_bytes = 0;  // the other workers' states received
};

// The scene's description (dims, box, cameras, TF, integrator) and, in scene.volume.data, only
// this worker's slab: planes domain_slab(nz, rank, ranks, part.shares) of the densities (x fastest,
// planes × ny × nx values). Every worker gets the whole image. The midpoint, trapezoid,
// preintegrated and exact schemes; the step must be given (integrator.step or options.step) where
// integrator.tolerance is set. options.volume_brick cuts the slab further (else as its device
// memory needs).
IVR_API Image render_domain(Device& device, const Scene& scene, const DomainPart& part,
                            const RenderOptions& options = {}, RenderStats* stats = nullptr,
                            DomainStats* domain = nullptr);

// The gradient of the loss against `target` (every worker passes the whole target) from this
// worker's slab, the groups `groups` asks for in its order: "density" of shape (planes, ny, nx) —
// the planes a slab shares with its neighbours hold only this worker's part: add the slabs where
// they overlap to get the volume's gradient (domain_join()) — and "tf" (tf_gradient_shape), the
// part of the samples in this slab: sum it over the workers; "background" is the whole gradient on
// every worker (not a part), as are the forward lanes' groups (camera, scales, tf_points,
// voxels:LIST: their tangents travel with the rays' states). Every scheme (density, tf and
// background by the adjoint): the trapezoid and preintegrated schemes' bricks hold a halo of
// brick_halo planes beyond the slab's ends, fetched from the neighbours' slabs, and what the halo
// gathers is sent back and added by the plane's owner (two all_gathers of a few planes more);
// `loss` is the whole loss on every worker.
IVR_API Gradient gradient_domain(Device& device, const Scene& scene, const Image& target,
                                 const DomainPart& part, const GradientOptions& options = {},
                                 DomainStats* domain = nullptr,
                                 const std::vector<std::string>& groups = {"density"});

// The same over several devices in one process (docs/scaling.md): `scene` holds the whole
// volume; device i of n takes its slab, domain_share(scene, i, n, w), and marches it on a thread of
// its own, the devices meeting in this process where ranks would over MPI — so a volume that fits
// no one device's memory is spread over all of theirs (and each slab is streamed in bricks where
// its device needs it). The slabs follow the weights w = share_weights(devices, options.shares):
// the options' shares, else each device's speed (samples_per_second), so that a GPU beside a CPU
// takes the longer slab (equal speeds: equal slabs). The image equals render_domain()'s over n
// workers with those shares. Stats: samples summed, the
// slowest device's kernel time, the largest device's memory, bricks summed over the devices;
// `domain` is device 0's. Throws Error(invalid_argument) for no or null devices and for more
// devices than the volume has cells along z.
IVR_API Image render_domain(const std::vector<Device*>& devices, const Scene& scene,
                            SlabMarch march = SlabMarch::states, const RenderOptions& options = {},
                            RenderStats* stats = nullptr, DomainStats* domain = nullptr);

// The gradient over several devices' slabs, as whole as one process's: "density" of the whole
// volume (the slabs joined, domain_join()), "tf" summed over the devices in device order, the
// other groups whole on every device and taken from device 0; the slabs as render_domain()'s, by
// share_weights(devices, options.shares). options.workers must be 1 (a data-parallel worker's
// devices are not split further).
IVR_API Gradient gradient_domain(const std::vector<Device*>& devices, const Scene& scene,
                                 const Image& target, SlabMarch march = SlabMarch::states,
                                 const GradientOptions& options = {}, DomainStats* domain = nullptr,
                                 const std::vector<std::string>& groups = {"density"});

// CGLS, SIRT or LSQR (with nonneg, Tikhonov or TV: each worker holds the TV rows of the planes it
// owns, their parts of a shared plane joined) over slabs: the projections `lines` (every worker passes all of
// them) of `scene`'s rays, this worker holding and solving for planes
// domain_slab(nz, rank, ranks, part.shares) of the volume (scene.volume.data is not read). Each iteration sums the workers' parts of N x over
// the lines and joins the planes neighbours share; every worker's iterate equals one process's to
// rounding on its planes (the shared ones on both workers alike). Returns this worker's planes
// (planes × ny × nx) in volume (and volume_f64 in float64); domain_assemble() joins them. Each
// worker's `progress` (or none) is asked after every iteration and all stop where any says stop.
IVR_API TomoResult tomo_domain(Device& device, const Scene& scene, const std::vector<double>& lines,
                               const DomainPart& part, const TomoOptions& options = {},
                               const TomoProgress& progress = {});

// The same over several devices in one process: device i of n solves for slab i on a thread of
// its own, the devices meeting in this process where ranks would over MPI, the slabs sized as
// render_domain()'s by share_weights(devices, options.shares). Returns the whole
// iterate (the slabs joined, domain_assemble()), equal to tomo_domain()'s over n workers and to
// one process's to rounding; history and stop_reason are device 0's (every device's alike),
// bricks summed, setup_seconds the slowest device's. `progress` is asked on device 0 and its
// answer reaches every device (all stop after the same iteration). Throws Error(invalid_argument)
// for no or null devices and for more devices than the volume has cells along z.
IVR_API TomoResult tomo_domain(const std::vector<Device*>& devices, const Scene& scene,
                               const std::vector<double>& lines, const TomoOptions& options = {},
                               const TomoProgress& progress = {});

// The volume's values (nz × ny × nx) from every worker's slab values, in rank order: the shared
// planes summed. Each slab's place follows from the sizes (consecutive slabs share one plane), so
// equal and weighted slabs alike; slabs that are not whole planes, or do not cover the nz planes
// exactly, are refused.
IVR_API std::vector<double> domain_join(int nx, int ny, int nz,
                                        const std::vector<std::vector<double>>& slabs);
// The volume (nz × ny × nx) from every worker's slab of one volume (tomo_domain's iterates), in rank
// order: a shared plane taken once, from the lower worker.
IVR_API std::vector<double> domain_assemble(int nx, int ny, int nz,
                                            const std::vector<std::vector<double>>& slabs);

}  // namespace ivr
