// bricked_fixed.hpp — internal: the out-of-core adjoint's deterministic density gradient — each
// brick's contributions summed in fixed point on the device (kernels/adjoint_scatter.cl's
// integers into the brick's slot), the slots' integer sums added on the host, one conversion.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "brick/brick_layout.hpp"
#include "ivr/domain.hpp"
#include "ivr/gradient.hpp"
#include "ivr/scene.hpp"
#include "runtime/runtime.hpp"

namespace ivr {

// Integer adds do not depend on their order: the same bits on every run, however the device
// schedules the rays and the host the bricks — and the same bits as in core. Each contribution
// becomes its integer before any sum (kernels/adjoint_scatter.cl), the scale 2^S and its cap are
// the in-core adjoint's (lib/adjoint/adjoint_bound.hpp: the bound from the whole volume's range
// of densities, gathered over the slabs; a cap of 2^62 / rays on a ray's Σ |contribution|,
// carried in its state from brick to brick and checked at its end), and a second pass runs where
// the in-core one would, at the scale it would take. Over independent segments
// (SlabMarch::segments) each worker's segment of a ray is checked alone, against
// 2^62 / (rays · workers). Over slabs the planes two workers hold (the shared plane, the halo) are
// summed as integers by their owner (a shared plane's: the upper worker) before the one
// conversion. A data-parallel share of a batch (FixedShare) takes the batch's scale and, through
// the share's collectives, the batch's decision and the shares' summed integers.
class BrickedFixed {
 public:
  // Whether every worker's device has 64-bit integer atomics (`mine`: this one's); a collective
  // over slabs, so that all take fixed point or none.
  static bool everywhere(const DomainPart* domain, bool mine);
  static constexpr std::size_t kHeader = 5;  // IVR_FIXED_HEADER (kernels/ivr_constants.h)
  // The first pass's scale (or `exponent`, a second pass's) for `scene`'s rays over `layout`.
  BrickedFixed(const Scene& scene, const BrickLayout& layout, const Image& target, Loss loss,
               const std::vector<double>* densities, const DomainPart* domain,
               const FixedShare* share, const int* exponent);
  // A slot's header before its brick: the scale, the cap, the counters zeroed.
  const std::array<cl_long, kHeader>& header() const { return header_; }
  // Brick b's slot as read back (the header, then its voxels' sums): its counters, and its sums
  // added into the held voxels'.
  void add(const std::vector<unsigned char>& slot, const BrickLayout& layout, int b);
  // After the sweep: the scale a second pass must run at (agreed over the workers), or the
  // exponent this one ran at where it holds.
  int next() const;
  int exponent() const { return exponent_; }
  // The held voxels' sums as reals: sum · 2^−S, rounded to float first where the kernels' real
  // is float (as the in-core fixed_to_real); a share's after the shares' sums are added (a
  // collective).
  std::vector<double> values(bool f64) const;
  // A worker's slab [first, last] (its bricks' planes) and the planes it holds values of
  // [data_first, data_last] (the slab and its halo).
  struct WorkerPlanes {
    int first, last, data_first, data_last;
  };

 private:
  const DomainPart* domain_;
  const FixedShare* share_;
  int exponent_ = 0, cap_exponent_ = 0;
  std::array<cl_long, kHeader> header_{};
  std::int64_t over_cap_ = 0;
  bool nonfinite_ = false;  // a slot's largest contribution or segment was not finite
  float largest_ = 0, largest_ray_ = 0;
  std::vector<std::int64_t> sums_;
  // Over slabs: every worker's planes, and this worker's layout (owned_sums).
  std::vector<WorkerPlanes> planes_;
  BrickLayout layout_;
  // The held planes' sums where this worker owns the plane (the highest worker whose slab has it),
  // every worker's integers for it added; 0 in the planes another worker owns (a collective).
  std::vector<std::int64_t> owned_sums() const;
};

}  // namespace ivr
