// bricked_gradient.cpp — the out-of-core gradient: density, transfer function and background by the
// adjoint, the other groups by forward lanes (lib/brick/bricked_tangent.cpp).
#include "brick/bricked_gradient.hpp"

#include <algorithm>
#include <array>
#include <deque>
#include <memory>
#include <set>
#include <string>

#include "adjoint/adjoint.hpp"
#include "adjoint/private_sums.hpp"
#include "brick/bricked_fixed.hpp"
#include "brick/bricked_tangent.hpp"
#include "brick/domain.hpp"
#include "brick/domain_segments.hpp"
#include "ivr/error.hpp"
#include "ivr/jacobian.hpp"
#include "ivr/tf_parameters.hpp"
#include "jacobian/jacobian.hpp"
#include "runtime/launch.hpp"
#include "runtime/real_args.hpp"

namespace ivr {

namespace {
constexpr int kAdjointBegin = 3, kAdjointMarch = 4;  // kernels/bricked_adjoint.cl
constexpr int kAdjointReals = 8;
// Private sums (lib/adjoint/private_sums.hpp) for the packet march over one brick at a time:
// their copies hold a brick's gradient each, in what the plan's budget leaves.
PrivateSums bricked_private_sums(const Device::Impl& dev, const BrickPlan& plan, bool packet,
                                 std::size_t real_size, std::size_t rays) {
  if (tuning_probe()) return {};
  PrivateSumsQuery q;
  q.packet = packet;
  q.density = true;
  q.eligible = true;
  q.voxels = plan.layout.largest_voxels();
  q.real_size = real_size;
  q.pixels = rays;
  q.longest_edge = plan.layout.edge + 1;
  if (plan.budget) q.room = plan.budget > plan.bricked_bytes ? plan.budget - plan.bricked_bytes : 0;
  return private_sums_for(dev.info, q);
}

// At most this many slots of a brick's gradient (kernels' writes and the host's reads in flight),
// or $IVR_GRADIENT_SLOTS (1–64).
std::uint64_t most_gradient_slots() {
  const int v = count_from_env("IVR_GRADIENT_SLOTS", 64, "a slot count (1 to 64)");
  return v ? std::uint64_t(v) : 8;
}

// The slots of a brick's gradient (adjoint_bricked's ring), `slot_bytes` each (0: no density
// gradient, one slot of a real): the plan's room for two float slots (`float_slot` bytes each)
// and what its budget leaves beside the private sums' copies; at most one a brick.
std::vector<cl::Buffer> gradient_slots(Device::Impl& dev, const BrickPlan& plan,
                                       std::size_t slot_bytes, std::size_t float_slot,
                                       std::size_t private_bytes) {
  const std::uint64_t most = most_gradient_slots();  // (checked whatever the groups)
  if (slot_bytes == 0)
    return {dev.buffer(CL_MEM_READ_WRITE, 8, nullptr, "a brick's density gradient")};
  std::uint64_t room = 2 * std::uint64_t(float_slot);  // (no budget known: the plan's two)
  if (plan.budget > plan.bricked_bytes + private_bytes)
    room += plan.budget - plan.bricked_bytes - private_bytes;
  const std::size_t slots = std::size_t(std::clamp<std::uint64_t>(
      room / slot_bytes, 1,
      std::min<std::uint64_t>(most, std::uint64_t(plan.layout.total()))));
  std::vector<cl::Buffer> out;
  for (std::size_t i = 0; i < slots; ++i)
    out.push_back(dev.buffer(CL_MEM_READ_WRITE, slot_bytes, nullptr, "a brick's density gradient"));
  return out;
}

}  // namespace

// The adjoint's groups (density, tf, background: each once) out of core; `fixed_exponent` set: the
// deterministic density gradient's second pass, at that scale.
static Gradient adjoint_bricked(Device& device, const Scene& scene, const Image& target,
                                const std::vector<std::string>& groups, const GradientOptions& o,
                                const BrickPlan& plan, const DomainPart* domain,
                                DomainStats* domain_stats, const std::vector<double>* densities,
                                const FixedShare* share, const int* fixed_exponent = nullptr) {
  bool density = false, tf = false, background = false;
  for (const std::string& g : groups) {
    density = density || g == "density";
    tf = tf || g == "tf";
    background = background || g == "background";
  }
  RenderOptions ro;
  ro.precision = o.precision;
  ro.step = o.step;
  BrickedMarch march(device, scene, ro, plan, "gradient");
  march.densities_f64 = densities;
  const bool segments = domain && domain->march == SlabMarch::segments;
  if (domain && !segments) attach_exchange(march, *domain, domain_stats);
  Session::Impl& s = march.s;
  check_brick_halo(scene, s.integrator().step, plan.layout);
  march.session().set_target(target);
  // Over independent segments: this worker's segments, composited with the others'.
  std::unique_ptr<SegmentMarch> composited;
  if (segments)
    composited = std::make_unique<SegmentMarch>(march, scene, *domain, domain_stats);
  else
    march.render();

  const BrickLayout& l = plan.layout;
  const ImageExtent e = image_extent(scene);
  const std::size_t rays = e.pixels();
  Device::Impl& dev = s.dev;
  // Deterministic: the density gradient in fixed point where the device has 64-bit integer
  // atomics (lib/brick/bricked_fixed.hpp), without private sums; else the float sums (and the
  // result says which).
  std::unique_ptr<BrickedFixed> fixed;
  // (A data-parallel share summed in fixed point: every worker voted for it.)
  if (density && (share || (o.deterministic && !tuning_probe() &&
                            BrickedFixed::everywhere(domain, has_int64_atomics(dev)))))
    fixed = std::make_unique<BrickedFixed>(scene, l, target, o.loss, densities, domain, share,
                                           fixed_exponent);
  // BEGIN one ray per work-item; the sweeps' march in packets of rays where the render's is,
  // there with private sums where they pay and fit beside the plan's bricks (their copies are a
  // brick's gradient per compute unit).
  KernelConfig config = march.variant.config("bricked_adjoint.cl", "bricked_adjoint");
  const std::vector<std::size_t> tf_shape = tf_gradient_shape(scene.tf);
  const std::size_t tf_size = tf_shape[0] * tf_shape[1];
  config.set(Switch::loss_l1, o.loss == Loss::l1).set(Switch::loss_dot, o.loss == Loss::dot);
  config.set(Switch::grad_density, density).set(Switch::grad_tf, tf);
  config.set(Switch::deterministic, bool(fixed));
  // IVR_TF_ROWS sizes the per-ray TF-gradient cache (kernels/adjoint_tf.cl), as in core.
  config.set(Switch::tf_rows, int(std::min<std::size_t>(tf_shape[0], 1 << 20)));
  config.with_atomics(atomic_add_for(dev.info, s.f64));
  cl::Kernel& k = s.kernels.get(config, &march.op.stats.build_seconds);
  const PrivateSums priv =
      density && !fixed ? bricked_private_sums(dev, plan, march.lanes() > 1, s.real_size, rays)
                        : PrivateSums{};
  cl::Kernel* marching = &k;
  KernelConfig packet = config;
  if (march.lanes() > 1) {
    packet.set(Switch::rays, march.lanes()).set(Switch::private_sums, priv.on);
    marching = &s.kernels.get(packet, &march.op.stats.build_seconds);
  }
  const cl::Buffer adj = dev.buffer(CL_MEM_READ_WRITE, rays * kAdjointReals * s.real_size, nullptr,
                                    "the per-ray pixel adjoints");
  // Per pixel: its loss and dL/dbackground terms (kernels/bricked_adjoint.cl).
  const cl::Buffer pixel_terms = dev.buffer(CL_MEM_READ_WRITE, rays * 4 * s.real_size, nullptr,
                                            "the per-pixel loss and background terms");
  // Slots for a brick's gradient, taken in turn: the device marches a brick into one while the
  // host adds the bricks before it, read back from the others, into the volume's. The plan
  // counts two float slots; more where the budget leaves room (up to 8, $IVR_GRADIENT_SLOTS), so that
  // the host waits for a brick's read only when its slot comes round again, not after every
  // brick (on a GPU a brick's march is microseconds: waiting after each left the device idle
  // while the host added). In fixed point a slot holds the header and a long a voxel.
  const std::size_t float_slot = l.largest_voxels() * s.real_size;  // (the plan's two)
  const std::size_t slot_bytes =
      fixed ? (BrickedFixed::kHeader + l.largest_voxels()) * sizeof(cl_long) : float_slot;
  const std::vector<cl::Buffer> grads = gradient_slots(
      dev, plan, density ? slot_bytes : 0, float_slot, priv.on ? priv.bytes(s.real_size) : 0);
  const std::size_t tf_bytes = std::max<std::size_t>(tf_size, 1) * s.real_size;
  const cl::Buffer grad_tf =
      dev.buffer(CL_MEM_READ_WRITE, tf_bytes, nullptr, "the transfer-function gradient");
  if (tf) dev.queue.enqueueFillBuffer(grad_tf, cl_uchar(0), 0, tf_bytes);
  cl::Buffer copies;
  if (priv.on) {  // zero once: each brick's sum of the copies leaves them 0
    copies = dev.buffer(CL_MEM_READ_WRITE, priv.bytes(s.real_size), nullptr,
                        "the brick gradient's private copies");
    dev.queue.enqueueFillBuffer(copies, cl_uchar(0), 0, priv.bytes(s.real_size));
  }
  int a0 = 0;  // the adjoint's arguments' first index, in both kernels
  for (cl::Kernel* kernel : {&k, marching}) {
    a0 = march.arguments(*kernel);
    cl_call("setting the bricked adjoint's arguments", [&] {
      kernel->setArg(a0 + 4 + 2, adj);
      kernel->setArg(a0 + 4 + 3, buffer_of(s.target));
      // (A share of a batch: the batch's mean, each share holding its part of it.)
      set_real(*kernel, a0 + 4 + 4, s.f64,
               1.0 / double(share ? share->elements : rays * scene.channels()));
      kernel->setArg(a0 + 4 + 5, pixel_terms);
      kernel->setArg(a0 + 4 + 6, kernel == marching && priv.on ? copies : grads[0]);
      kernel->setArg(a0 + 4 + 7, cl_int4{{0, 0, 0, 0}});
      kernel->setArg(a0 + 4 + 8, cl_int(0));
      kernel->setArg(a0 + 4 + 9, cl_int(0));
      kernel->setArg(a0 + 4 + 10, grad_tf);
      kernel->setArg(a0 + 4 + 11, cl::Local(tf ? tf_bytes : s.real_size));
      kernel->setArg(a0 + 4 + 12, cl_int(tf ? tf_size : 0));
    });
  }
  const int a_grad = a0 + 4 + 6, a_rect = a_grad + 1;
  // The adjoint's BEGIN: each pixel's loss terms and adjoint from the composited rays (over
  // segments written into the states first; each ray's march then restarted at its segment).
  if (composited) composited->write_totals();
  march.launch_all(k, kAdjointBegin);
  if (composited) composited->seed_adjoint();

  const std::size_t planes = std::size_t(l.held_planes());  // all, or a worker's (with its halo)
  std::vector<double> gradient(density ? planes * l.dims[1] * l.dims[0] : 0, 0.0);
  // The bricks read back (asynchronously) and not yet added, oldest first: added in the order
  // the bricks were marched (the float sums' order, whatever the reads' timing).
  struct Pending {
    int brick = -1;
    cl::Event read;
    std::vector<unsigned char> host;
  };
  std::vector<Pending> pending(grads.size());
  std::deque<int> unadded;  // slots, oldest first
  // Should anything throw with reads in flight, they finish before their host memory goes.
  struct DrainReads {
    std::vector<Pending>& pending;
    ~DrainReads() {
      for (Pending& p : pending) try {
          if (p.brick >= 0) p.read.wait();
        } catch (...) {  // (the error already thrown says why)
        }
    }
  } drain{pending};
  auto add_oldest = [&] {
    Pending& p = pending[std::size_t(unadded.front())];
    unadded.pop_front();
    p.read.wait();
    if (fixed)
      fixed->add(p.host, l, p.brick);
    else
      add_brick(p.host, l, p.brick, s.f64, gradient.data());
    p.brick = -1;
  };
  // Up to (and with) slot i's brick, in order.
  auto add_through = [&](int i) {
    while (pending[std::size_t(i)].brick >= 0) add_oldest();
  };
  auto read_done = [](const cl::Event& e) {
    return e.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>() == CL_COMPLETE;
  };
  int turn = 0;      // the slot of the brick being marched
  BrickHooks hooks;  // (the TF gradient alone has nothing to do per brick)
  cl::Kernel* sum = priv.on ? &s.kernels.get(packet.with_entry("sum_private_copies")) : nullptr;
  if (density) {
    hooks.before = [&](int b, std::vector<cl::Event>& wait) {
      add_through(turn);    // the slot's last brick, before the slot is written again
      if (priv.on) return;  // (the sum of the copies overwrites the slot)
      marching->setArg(a_grad, grads[turn]);
      cl::Event zeroed;
      if (fixed) {  // the scale and cap, the counters and sums zeroed
        const std::size_t header = sizeof(cl_long) * BrickedFixed::kHeader;
        dev.queue.enqueueFillBuffer(grads[turn], cl_long(0), header,
                                    l.voxels(b) * sizeof(cl_long));
        dev.queue.enqueueWriteBuffer(grads[turn], CL_FALSE, 0, header, fixed->header().data(),
                                     nullptr, &zeroed);
      } else {
        dev.queue.enqueueFillBuffer(grads[turn], cl_uchar(0), 0, l.voxels(b) * s.real_size,
                                    nullptr, &zeroed);
      }
      wait.push_back(zeroed);
    };
    if (priv.on)  // one work-group of one item per compute unit, taking turns of the tiles
      hooks.launch = [&](const TileRect& r, const std::vector<cl::Event>& wait) {
        marching->setArg(a_rect, cl_int4{{r.x, r.y, r.across, r.down}});
        marching->setArg(a_rect + 1, cl_int(r.first_view));
        marching->setArg(a_rect + 2, cl_int(r.across * r.down * r.views));
        cl::Event ev;
        dev.queue.enqueueNDRangeKernel(*marching, cl::NullRange, cl::NDRange(priv.groups),
                                       cl::NDRange(1), &wait, &ev);
        return ev;
      };
    hooks.after = [&](int b, const std::vector<cl::Event>& marched) {
      if (marched.empty()) return;
      std::vector<cl::Event> done = marched;
      if (sum) {  // the copies into the brick's gradient (which leaves them 0)
        const std::size_t voxels = l.voxels(b);
        sum->setArg(0, cl_int(voxels));
        sum->setArg(1, cl_int(priv.groups));
        sum->setArg(2, copies);
        sum->setArg(3, grads[turn]);
        cl::Event summed;
        dev.queue.enqueueNDRangeKernel(
            *sum, cl::NullRange, cl::NDRange((voxels + IVR_PRIVATE_ALIGN - 1) / IVR_PRIVATE_ALIGN),
            cl::NullRange, &marched, &summed);
        march.op.events.push_back(summed);
        done = {summed};
      }
      Pending& p = pending[turn];
      p.host.resize(fixed ? (BrickedFixed::kHeader + l.voxels(b)) * sizeof(cl_long)
                          : l.voxels(b) * s.real_size);
      dev.queue.enqueueReadBuffer(grads[turn], CL_FALSE, 0, p.host.size(), p.host.data(), &done,
                                  &p.read);
      dev.queue.flush();
      p.brick = b;
      unadded.push_back(turn);
      turn = (turn + 1) % int(grads.size());
      // The bricks whose reads are done already, while the device marches on.
      while (!unadded.empty() && read_done(pending[std::size_t(unadded.front())].read))
        add_oldest();
    };
  }
  if (marching == &k)
    march.sweep(k, kAdjointMarch, hooks, "bricked");
  else
    march.sweep(*marching, kAdjointMarch, hooks, "bricked_packet", march.tile());
  while (!unadded.empty()) add_oldest();
  if (fixed) {
    // Where the scale failed (a segment over the cap) or was far too loose: once more at the
    // scale the largest segment calls for (every worker alike).
    const int next = fixed->next();
    if (next != fixed->exponent()) {
      if (fixed_exponent)
        throw Error(Status::opencl, "the out-of-core fixed-point density gradient overflowed at "
                                    "scale 2^" + std::to_string(next));
      return adjoint_bricked(device, scene, target, groups, o, plan, domain, domain_stats,
                             densities, share, &next);
    }
    gradient = fixed->values(s.f64);
  }

  // The loss and the background gradient: the per-pixel terms' column sums (in float64).
  const std::vector<double> terms = download_reals(dev, s.f64, pixel_terms, rays * 4);
  double sums[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < rays; ++i)
    for (int c = 0; c < 4; ++c) sums[c] += terms[i * 4 + c];
  Gradient d;
  d.loss = sums[0];
  d.step = s.integrator().step;
  d.plan.mode = Mode::adjoint;
  d.plan.model = "out of core";
  std::vector<double> tf_values;
  if (tf) tf_values = download_reals(dev, s.f64, grad_tf, tf_size);
  for (const std::string& g : groups) {  // in the order asked for
    if (g == "density")
      d.groups.push_back({"density",
                          {planes, std::size_t(scene.volume.ny), std::size_t(scene.volume.nx)},
                          std::move(gradient)});
    else if (g == "tf")
      d.groups.push_back({"tf", tf_shape, std::move(tf_values)});
    else if (scene.channels() == 4)
      d.groups.push_back({"background", {3}, {sums[1], sums[2], sums[3]}});
    else
      d.groups.push_back({"background", {1}, {sums[1]}});
    d.parameters += d.groups.back().values.size();
  }
  const OperationStats st = march.session().last_stats();
  d.kernel_seconds = st.kernel_seconds;
  // (The plan counts two float slots of a brick's gradient; the ring may hold more, or fewer.)
  const std::uint64_t slots_bytes = density ? grads.size() * slot_bytes : 0;
  const std::uint64_t planned_slots = 2 * std::uint64_t(float_slot);
  d.device_bytes = plan.bricked_bytes - std::min(plan.bricked_bytes, planned_slots) + slots_bytes +
                   (priv.on ? priv.bytes(s.real_size) : 0);
  d.bricks = plan.bricks();
  d.atomics = atomic_add_name(atomic_add_for(dev.info, s.f64));
  d.deterministic = bool(fixed);
  return d;
}

// Which way each group goes out of core: the adjoint's (density, tf, background, unless forward
// mode is asked for), the forward lanes' (camera, tf_points, scales, voxels, rays; tf and
// background in forward mode) or neither (step: the render is flat in it).
Gradient gradient_bricked(Device& device, const Scene& scene, const Image& target,
                          const std::vector<std::string>& groups, const GradientOptions& o,
                          const BrickPlan& plan, const DomainPart* domain,
                          DomainStats* domain_stats, const std::vector<double>* densities,
                          const FixedShare* share) {
  const std::string where = "out-of-core gradient (the volume is split into " +
                            std::to_string(plan.bricks()) + " bricks; docs/scaling.md)";
  std::vector<std::string> adjoint_groups, forward_groups;
  std::set<std::string> seen;
  for (const std::string& g : groups) {
    if (!seen.insert(g.rfind("voxels:", 0) == 0 ? "voxels" : g).second)
      throw Error(Status::invalid_argument, where + ": group " + g + " asked for twice");
    const bool adjoint = g == "density" || g == "tf" || g == "background";
    if (domain && adjoint && o.mode == Mode::forward)  // (their parts are per slab)
      throw Error(Status::unsupported, where + ": over slabs, " + g +
                                           " is differentiated by the adjoint, not forward mode");
    if (g == "density" && o.mode == Mode::forward)
      throw Error(Status::unsupported,
                  where +
                      ": density in forward mode (a tangent lane per voxel) is not run out of "
                      "core; the adjoint computes it (mode automatic or adjoint)");
    if (!adjoint && o.mode == Mode::adjoint && g != "step")
      throw Error(Status::invalid_argument,
                  "mode adjoint cannot compute group '" + g + "' out of core (forward lanes)");
    if (adjoint && o.mode != Mode::forward)
      adjoint_groups.push_back(g);
    else if (g != "step")
      forward_groups.push_back(g);
  }

  Gradient d;
  if (!adjoint_groups.empty())
    d = adjoint_bricked(device, scene, target, adjoint_groups, o, plan, domain, domain_stats,
                        densities, share);
  BrickedTangent t;
  std::vector<cl_int4> lanes;
  std::vector<std::size_t> counts;
  for (const std::string& g : forward_groups) {
    const std::vector<cl_int4> l = lanes_of(scene, parameters_of(scene, g));
    lanes.insert(lanes.end(), l.begin(), l.end());
    counts.push_back(l.size());
  }
  if (!forward_groups.empty() || adjoint_groups.empty()) {
    t = tangent_bricked(device, scene, target, lanes, o, plan, domain, domain_stats, densities);
    if (adjoint_groups.empty()) {
      d.loss = t.loss;
      d.step = o.step > 0 ? o.step : scene.integrator.step;
      d.bricks = plan.bricks();
    }
    d.kernel_seconds += t.kernel_seconds;
    d.device_bytes = std::max(d.device_bytes, t.device_bytes);
  }
  d.plan.mode = adjoint_groups.empty() ? Mode::forward : Mode::adjoint;
  d.plan.model = forward_groups.empty()   ? "out of core"
                 : adjoint_groups.empty() ? "out of core (forward lanes)"
                                          : "out of core (adjoint, and forward lanes for " +
                                                forward_groups.front() + ")";
  d.plan.passes = forward_groups.empty() ? 0 : t.passes;
  d.plan.lanes = forward_groups.empty() ? 0 : t.lanes;

  // Every group in the order asked for.
  std::vector<GroupGradient> adjoint_parts = std::move(d.groups);
  d.groups.clear();
  d.parameters = 0;
  std::size_t at = 0, next_forward = 0, next_adjoint = 0;
  for (const std::string& g : groups) {
    GroupGradient out;
    out.name = g.rfind("voxels:", 0) == 0 ? "voxels" : g;
    if (g == "step") {
      out.shape = {1};
      out.values = {0.0};  // the render depends on the step only through the sample count
    } else if (next_adjoint < adjoint_groups.size() && adjoint_groups[next_adjoint] == g) {
      out = std::move(adjoint_parts[next_adjoint++]);
    } else {
      const std::size_t n = counts[next_forward++];
      out.values.assign(t.gradient.begin() + std::ptrdiff_t(at),
                        t.gradient.begin() + std::ptrdiff_t(at + n));
      at += n;
      if (g == "tf")
        out.shape = tf_gradient_shape(scene.tf);
      else if (g == "camera")
        out.shape = {scene.cameras.size(), 7};
      else if (g == "rays")
        out.shape = {scene.rays.count(), std::size_t(RayList::kColumns)};
      else
        out.shape = {n};
    }
    d.parameters += out.values.size();
    d.groups.push_back(std::move(out));
  }
  return d;
}

}  // namespace ivr
