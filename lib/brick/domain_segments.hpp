// domain_segments.hpp — internal: domain-parallel over independent segments (SlabMarch::segments,
// docs/scaling.md): every worker marches its slab's segment of every ray at once, from
// transmittance 1; the segments are exchanged once and composited in order along each ray, and
// the adjoint starts each worker's segment from what lies in front of it.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "brick/bricked_render.hpp"
#include "ivr/domain.hpp"

namespace ivr {

// Forward lanes over segments (lib/brick/bricked_tangent.cpp): each ray's `lanes` tangents of
// `sums` reals in `buffer` (kernels/bricked_tangent.cl: d T and d (r, g, b), or d τ), zero before
// `sweep` — the tangent kernel's sweeps — marches them with the segments; the first `used` lanes
// are sent (the rest of a pass is padding, left 0).
struct SegmentTangents {
  const cl::Buffer* buffer = nullptr;
  int lanes = 0, sums = 0, used = 0;
  std::function<void()> sweep;
};

// One march's segments, composited. Constructing it runs the march (its BEGIN at each ray's
// window in the worker's slab, its sweeps: the render's, or with `tangents` theirs) and the one
// exchange (part.all_gather): afterwards every worker holds the same composited rays (and their
// tangents: dC = dC₁ + dT₁·C₂ + T₁·dC₂, dT = dT₁·T₂ + T₁·dT₂; under absorption the dτ add).
class SegmentMarch {
 public:
  SegmentMarch(BrickedMarch& march, const Scene& scene, const DomainPart& part,
               DomainStats* stats, const SegmentTangents* tangents = nullptr);
  // The composited image (the same on every worker), as the one-process render writes it.
  Image image() const;
  // Every worker's samples, over all rays.
  std::uint64_t samples() const { return samples_; }
  // The whole rays' sums into the march's states: what the adjoint's BEGIN turns into the loss
  // and dL/dpixel (kernels/bricked_adjoint.cl).
  void write_totals();
  // The whole rays' tangents into the tangents' buffer: what FINISH turns into the pixels'
  // derivatives (with `tangents` only).
  void write_tangents();
  // After the adjoint's BEGIN: each ray's adjoint march restarted at its window in this worker's
  // slab, from the transmittance and radiance in front of it, ending where its segment ended.
  void seed_adjoint();

 private:
  struct States {
    std::vector<double> reals;
    std::vector<std::uint32_t> uints;
  };
  States read() const;
  void write(const States& states);
  void composite(const DomainPart& part, DomainStats* stats);

  BrickedMarch& march_;
  const Scene& scene_;
  bool emission_;
  std::size_t rays_;
  States start_, end_;  // after BEGIN, after the sweeps
  // Per ray: (T, r, g, b) under emission–absorption, (τ, 0, 0, 0) under absorption — the whole
  // ray's, and the part in front of this worker's segment.
  std::vector<double> total_, front_;
  const SegmentTangents* tangents_;
  std::vector<double> tangent_end_, tangent_total_;  // this worker's segments', the whole rays' 
  std::uint64_t samples_ = 0;
};

}  // namespace ivr
