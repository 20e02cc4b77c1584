// domain.hpp — internal: the domain-parallel parts of the out-of-core march
// (include/ivr/domain.hpp): a worker's slab plan, and the exchange of the rays' march states
// between workers after each sweep.
#pragma once
#include "brick/bricked_render.hpp"
#include "ivr/domain.hpp"

namespace ivr {

// Error(invalid_argument) where `part` is not one worker of ranks ≥ 1, or several lack an
// all_gather.
void check_domain_part(const DomainPart& part);
// The worker's slab: domain_slab(nz, rank, ranks, shares) of its part.
Slab part_slab(int nz, const DomainPart& part);

// The plan of worker part.rank's slab: its planes in bricks (forced_edge, else as its device's
// memory needs, else one brick of the whole slab), each holding `halo` voxels more on every side
// (brick_halo) — at the slab's ends from its neighbours' planes (layout.data_first, data_last).
BrickPlan plan_domain(Device& device, const Scene& scene, Precision precision, int forced_edge,
                      bool gradient, const Slab& slab, int halo = 0);

// The values of planes layout.data_first … data_last (a slab's gradient plan with a halo): `mine`,
// the slab's planes, and its neighbours' beyond them (an all_gather of every slab's end planes).
// Throws Error(unsupported) where the halo reaches past a neighbour's slab. (T: float, double.)
template <typename T>
std::vector<T> with_neighbour_planes(const DomainPart& part, const Slab& slab,
                                     const BrickLayout& layout, const std::vector<T>& mine);

// gradient_domain() marching `densities` (the slab's planes in float64, where given) instead of
// scene.volume.data's floats: a float64 reconstruction's iterate (lib/reconstruct/).
Gradient gradient_domain_values(Device& device, const Scene& scene, const Image& target,
                                const DomainPart& part, const GradientOptions& options,
                                DomainStats* domain, const std::vector<std::string>& groups,
                                const std::vector<double>* densities);
// The slab's planes of `gradient` (planes data_first … data_last), plus what the other workers'
// halos gathered into them (an all_gather; each plane added by one worker, its owner).
std::vector<double> return_halo(const DomainPart& part, const Slab& slab, const BrickLayout& layout,
                                const std::vector<double>& gradient);

// The scene's densities, checked to be the slab's planes (else Error(invalid_argument)).
const std::vector<float>& slab_values(const Scene& scene, const Slab& slab);

// Makes `march` pass the rays' states between the workers: before its sweeps it keeps a host copy
// of the states; after each sweep the rays this worker's bricks moved go to every worker
// (part.all_gather) and the rays the others moved are written into its states. A ray's march
// stands at the start of exactly one brick's window, so in one sweep only one worker moves it:
// every worker ends each sweep with the same states (checked: a ray moved twice is an error).
void attach_exchange(BrickedMarch& march, const DomainPart& part, DomainStats* stats);

// Every worker's doubles, in rank order (part.all_gather; each as many as `mine`, else an error
// naming `what` and the worker).
std::vector<std::vector<double>> gather_doubles(const DomainPart& part,
                                                const std::vector<double>& mine, const char* what);
// The elementwise sum over the workers, added in rank order (the same bits on every worker).
std::vector<double> sum_over(const DomainPart& part, const std::vector<double>& mine,
                             const char* what);

// A slab's values (its planes of `plane` values each, x fastest) whose first and last planes hold
// only this worker's part of planes it shares with its neighbours: adds the neighbours' parts
// there (one exchange of the end planes), so both workers hold the same sums (a + b = b + a).
template <typename T>
void join_shared_planes(const DomainPart& part, std::size_t plane, std::vector<T>& values,
                        const char* what) {
  if (part.ranks == 1) return;
  const std::size_t n = values.size();
  std::vector<double> ends(2 * plane);
  for (std::size_t i = 0; i < plane; ++i)
    ends[i] = double(values[i]), ends[plane + i] = double(values[n - plane + i]);
  const std::vector<std::vector<double>> all = gather_doubles(part, ends, what);
  if (part.rank > 0)
    for (std::size_t i = 0; i < plane; ++i)
      values[i] = T(values[i] + all[std::size_t(part.rank - 1)][plane + i]);
  if (part.rank + 1 < part.ranks)
    for (std::size_t i = 0; i < plane; ++i)
      values[n - plane + i] = T(values[n - plane + i] + all[std::size_t(part.rank + 1)][i]);
}

}  // namespace ivr
