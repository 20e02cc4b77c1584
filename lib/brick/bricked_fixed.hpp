// bricked_fixed.hpp — internal: the out-of-core adjoint's deterministic density gradient — each
// brick's contributions summed in fixed point on the device (kernels/adjoint_scatter.cl's
// fixed_add into the brick's slot), the slots' integer sums added on the host, one conversion.
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
// schedules the rays and the host the bricks. The scale 2^S is the in-core adjoint's rule
// (lib/adjoint/adjoint_bound.hpp) applied to a ray's *segment* in a brick: the kernel checks each
// segment's Σ |contribution| against a cap of 2^62 / (rays · segments a ray may have), so no
// voxel's sum over every brick leaves the 64-bit range; the a-priori bound (on a whole ray's
// Σ |contribution|, so on every segment's) sets the first scale, a second pass runs where it
// failed or was far too loose. Over slabs every worker takes the same scale and the same
// decision (all-gathered); a data-parallel share of a batch (FixedShare) takes the batch's scale
// and, through the share's collectives, the batch's decision and the shares' summed integers.
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

 private:
  const DomainPart* domain_;
  const FixedShare* share_;
  int exponent_ = 0, cap_exponent_ = 0;
  std::array<cl_long, kHeader> header_{};
  std::int64_t over_cap_ = 0;
  bool nonfinite_ = false;  // a slot's largest contribution or segment was not finite
  float largest_ = 0, largest_ray_ = 0;
  std::vector<std::int64_t> sums_;
};

}  // namespace ivr
