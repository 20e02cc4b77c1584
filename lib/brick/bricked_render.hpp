// bricked_render.hpp — internal: the out-of-core render (kernels/bricked.cl): when it is needed,
// and the render itself, bricks streamed through the device with their uploads overlapped with the
// marching of the bricks before them.
#pragma once
#include <cstdint>

#include "brick/brick_layout.hpp"
#include "ivr/render.hpp"

namespace ivr {

// How a render runs: in core (bricks = 1, layout.edge = 0) or in bricks, with how many bricks the
// device holds at once.
struct BrickPlan {
  BrickLayout layout;   // edge 0: in core
  int slots = 0;        // bricks resident at once
  std::uint64_t budget = 0;  // the device memory the plan keeps within
  std::uint64_t in_core_bytes = 0, bricked_bytes = 0;
  int bricks() const { return layout.edge ? layout.total() : 1; }
};

// The plan of a render of `scene`: bricks of `forced_edge` cells where it is > 0 (or
// $IVR_VOLUME_BRICK is set), else in core where the volume and the render's buffers fit the budget
// (device_memory_budget), else the largest power-of-two edge whose two bricks and the per-ray state
// fit. Throws Error(out_of_memory) where not even bricks of one cell fit.
// The budget is what the cap leaves beside the device's buffers already alive.
BrickPlan plan_render(Device& device, const Scene& scene, Precision precision, int forced_edge);

// Renders `scene` brick by brick as `plan` says; the image equals render()'s in core to rounding.
Image render_bricked(Device& device, const Scene& scene, const RenderOptions& options,
                     const BrickPlan& plan, RenderStats* stats);

// $IVR_VOLUME_BRICK (cells per brick edge; 0 when unset). Throws on a malformed value.
int volume_brick_from_env();

}  // namespace ivr
