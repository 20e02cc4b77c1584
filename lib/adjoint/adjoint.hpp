// adjoint.hpp — internal: the adjoint (reverse-mode) operation of a session: the loss and its
// gradients with respect to the densities, the TF, the background and the cameras in one march.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "session/session.hpp"

namespace ivr {

// This call differentiates one worker's share of a batch whose other shares other workers
// differentiate (data-parallel over views: lib/reconstruct/reconstruct.cpp). The loss is the
// batch's mean, so each share's loss and gradients are its part of the batch's sums (the workers'
// results add, unweighted). With fixed point (deterministic) the density gradient is the batch's
// bit for bit: every share scales its rays as the batch's one march would (the batch's ray count
// caps the scale, its target's largest element enters the bound), the workers agree on each
// pass's scale, and their integer sums are added exactly before the one conversion.
struct FixedShare {
  std::size_t elements = 0;  // the batch's target elements (the mean's denominator)
  std::size_t rays = 0;      // the batch's rays
  double target_max = 0;     // the batch's largest |target element|
  // A pass's findings combined over the workers, every worker getting the result: the rays over
  // the cap summed, the largest contribution and the largest ray's sum the maxima.
  std::function<void(std::int64_t& over_cap, float& largest, float& largest_ray)> agree;
  // The workers' fixed-point sums (one per voxel) added exactly, every worker getting the total.
  std::function<void(std::vector<std::int64_t>&)> add;
};
// Sets f.agree and f.add for worker `worker` of `workers` from `sum` (the workers' elementwise sum
// of doubles, every worker getting it: an MPI_Allreduce). Throws Error(invalid_argument) for a
// worker out of range or no sum.
void set_share_collectives(FixedShare& f, int worker, int workers,
                           const std::function<void(std::vector<double>&)>& sum);

struct AdjointRequest {
  bool density = true, tf = false, background = false, camera = false;
  Loss loss = Loss::mse;
  bool deterministic = false;
  const FixedShare* share = nullptr;  // (the whole batch: nullptr)
};
struct AdjointResult {
  DeviceArray loss, density, tf, background, camera, image;
  std::string atomics;
};
// Whether `dev` sums the density gradient in fixed point where asked (64-bit integer atomics).
bool has_int64_atomics(Device::Impl& dev);

AdjointResult enqueue_adjoint(Session::Impl& s, const DeviceArray& target, const AdjointRequest& r,
                              OperationRecord& op);

}  // namespace ivr
