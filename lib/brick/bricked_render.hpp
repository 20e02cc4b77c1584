// bricked_render.hpp — internal: the out-of-core render (kernels/bricked.cl): when it is needed,
// and the render itself, bricks streamed through the device with their uploads overlapped with the
// marching of the bricks before them.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>

#include "brick/brick_layout.hpp"
#include "brick/brick_stream.hpp"
#include "ivr/render.hpp"
#include "ivr/session.hpp"
#include "render/render.hpp"
#include "runtime/variants.hpp"
#include "session/session.hpp"

namespace ivr {

// The out-of-core march's per-ray state (kernels/bricked_state.cl): IVR_BRICK_REALS reals and
// IVR_BRICK_UINTS uints a ray.
constexpr int kBrickStateReals = 25, kBrickStateUints = 5;

// How a render runs: in core (bricks = 1, layout.edge = 0) or in bricks, with how many bricks the
// device holds at once.
struct BrickPlan {
  BrickLayout layout;        // edge 0: in core
  int slots = 0;             // bricks resident at once
  std::uint64_t budget = 0;  // the device memory the plan keeps within
  std::uint64_t in_core_bytes = 0, bricked_bytes = 0;
  int bricks() const { return layout.edge ? layout.total() : 1; }
};

// The plan of a render of `scene`: bricks of `forced_edge` cells where it is > 0 (or
// $IVR_VOLUME_BRICK is set), else in core where the volume and the render's buffers fit the budget
// (device_memory_budget), else the largest power-of-two edge whose two bricks and the per-ray state
// fit. Throws Error(out_of_memory) where not even bricks of one cell fit.
// The budget is what the cap leaves beside the device's buffers already alive.
// `gradient`: the plan of the density gradient (the volume's gradient in core; out of core a
// brick's gradient, the pixel adjoints and the target beside the render's buffers); `halo`: the
// bricks hold that many voxels more on every side (brick_halo: the endpoint schemes' gradients).
BrickPlan plan_render(Device& device, const Scene& scene, Precision precision, int forced_edge,
                      bool gradient = false, int halo = 0);

struct DomainPart;
struct DomainStats;

// Renders `scene` brick by brick as `plan` says; the image equals render()'s in core to rounding.
// `domain` (lib/brick/domain.cpp): this worker marches its slab's bricks alone (plan.layout's
// planes; scene.volume.data holds them) and exchanges the rays' states with the other workers.
Image render_bricked(Device& device, const Scene& scene, const RenderOptions& options,
                     const BrickPlan& plan, RenderStats* stats, const DomainPart* domain = nullptr,
                     DomainStats* domain_stats = nullptr);

// The views that share a brick order (front to back for all their rays), as runs of views.
struct ViewGroup {
  std::vector<int> order;
  std::vector<std::pair<int, int>> runs;  // (first view, count)
};

// A rectangle of a sweep's work-items (tiles of pixels): the first's x and y, how many across and
// down, and the views.
struct TileRect {
  int x = 0, y = 0, across = 0, down = 0;
  int first_view = 0, views = 0;
};

// Per brick of a sweep: `before` may add to the events the brick's marches wait for, `after`
// gets the brick's march events; `launch`, where set, enqueues the marching kernel (its brick
// arguments set) over a rectangle in place of the sweep's pixel launch.
struct BrickHooks {
  std::function<void(int brick, std::vector<cl::Event>& wait)> before;
  std::function<void(int brick, const std::vector<cl::Event>& marched)> after;
  std::function<cl::Event(const TileRect& tiles, const std::vector<cl::Event>& wait)> launch;
};

// One out-of-core march (kernels/bricked.cl): a session without densities (cameras, TF,
// integrator, kernels), the per-ray state, the brick stream and the view groups; sweeps of a
// marching kernel over the bricks until no ray is pending. The render and the gradient
// (lib/brick/bricked_gradient.cpp) are built from it.
class BrickedMarch {
 public:
  BrickedMarch(Device& device, const Scene& scene, const RenderOptions& options,
               const BrickPlan& plan, const char* operation);
  // Sets a marching kernel's leading arguments (the scene's, then the state at +4, +5); returns
  // the index of its `phase` argument.
  int arguments(cl::Kernel& k);
  void set_brick(cl::Kernel& k, int brick, int slot);
  void launch_all(cl::Kernel& k, int phase);  // every ray (one per work-item), no brick
  // The sweeps it took; `tuning`: k's name in the launch-parameter database
  // (lib/runtime/device_params_db.inc); `tile`: the pixels a work-item of k marches (a packet
  // kernel's tile).
  int sweep(cl::Kernel& k, int phase, const BrickHooks& hooks, const char* tuning,
            PacketShape tile = {});
  // BEGIN: every ray's march restarted (with `segments`, at its window in the slab).
  void begin();
  void render();  // BEGIN, the sweeps, FINISH: `image`, `samples`
  // Independent segments (lib/brick/domain_segments.cpp): render()'s BEGIN starts each ray where
  // its window in the layout's planes along z (a worker's slab) starts, from transmittance 1, and
  // the march ends it where that window ends; the image is then this slab's segments alone.
  bool segments = false;
  Session& session() { return session_; }
  const cl::Buffer& state() const { return state_; }
  const cl::Buffer& state_u() const { return state_u_; }
  std::size_t rays() const { return e_.pixels(); }
  // Domain-parallel (lib/brick/domain.cpp): called before a sweep() begins and after each sweep's
  // bricks (before the pending rays are counted), and how many workers march the volume.
  std::function<void()> before_sweeps, after_sweep;
  int workers = 1;
  // Per-ray buffers that move with the state between workers (forward mode's tangents), read
  // when a sweep() begins.
  std::vector<cl::Buffer> carried;
  // Where set, the densities the bricks are filled from (the held planes, x fastest) instead of
  // the scene's floats: a float64 run's iterate kept in float64 (a reconstruction over slabs).
  const std::vector<double>* densities_f64 = nullptr;
  BrickStream& stream() { return stream_; }
  cl::Kernel& render_kernel() { return *render_; }
  // On CPUs (midpoint), the rays a packet kernel marches in lanes, and their tile; 0 elsewhere.
  int lanes() const { return lanes_; }
  PacketShape tile() const { return tile_; }
  const BrickPlan& plan() const { return plan_; }

 private:
  const Scene& scene_;
  const BrickPlan& plan_;
  Session session_;

 public:
  Session::Impl& s;
  OperationRecord& op;
  RenderVariant variant;
  DeviceArray image;
  cl::Buffer samples;

 private:
  ImageExtent e_;
  BrickStream stream_;
  cl::Buffer state_, state_u_, pending_;
  cl::Kernel* render_ = nullptr;
  // On CPUs, the midpoint march in packets of rays (kernels/bricked_packet.cl), and its tile.
  cl::Kernel* march_packet_ = nullptr;
  PacketShape tile_;
  int lanes_ = 0;
  int a0_ = 0;
  std::vector<ViewGroup> groups_;
};

// A finished march's stats (kernel and build time, samples, bricks, sweeps, uploads) into *stats
// (where given).
void bricked_render_stats(BrickedMarch& march, const BrickPlan& plan, RenderStats* stats);

// The count $`name` sets, an integer from 1 to `most` (0 when unset). Throws
// Error(invalid_argument) on anything else: "NAME: 'value' is not `what`".
int count_from_env(const char* name, int most, const char* what);

// $IVR_VOLUME_BRICK (cells per brick edge; 0 when unset). Throws on a malformed value.
int volume_brick_from_env();

}  // namespace ivr
