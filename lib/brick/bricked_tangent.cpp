// bricked_tangent.cpp — forward mode out of core: passes of tangent lanes through the bricks.
#include "brick/bricked_tangent.hpp"

#include <algorithm>
#include <string>

#include "brick/domain.hpp"
#include "brick/domain_segments.hpp"
#include "ivr/error.hpp"
#include "ivr_constants.h"
#include "jacobian/jacobian.hpp"
#include "runtime/device_memory.hpp"
#include "runtime/launch.hpp"
#include "runtime/real_args.hpp"

namespace ivr {

namespace {
constexpr int kTangentMarch = 5, kTangentFinish = 6;  // kernels/bricked_tangent.cl
constexpr int kColumns = RayList::kColumns;

// One pass: the lanes it carries (`rays`: every listed ray's own columns, IVR_RAY_GRADIENT).
struct Pass {
  std::size_t first = 0, count = 0;
  int lanes = 1;
  bool rays = false;
};
}  // namespace

BrickedTangent tangent_bricked(Device& device, const Scene& scene, const Image& target,
                               const std::vector<cl_int4>& requested, const GradientOptions& o,
                               const BrickPlan& plan, const DomainPart* domain,
                               DomainStats* domain_stats, const std::vector<double>* densities) {
  const ImageExtent e = image_extent(scene);
  const std::size_t rays = e.pixels();
  const std::size_t real_size = o.precision == Precision::f64 ? 8 : 4;
  const int sums = scene.model == Model::absorption ? 1 : 4;  // IVR_TANGENT_SUMS

  // A ray list's own columns apart (as in core, lib/jacobian/jacobian.cpp): one pass of its 8
  // columns gives every ray's own derivatives.
  std::vector<cl_int4> others;
  std::vector<long long> source;  // ray · 8 + column, or −1 − the place among the others
  bool ray_lanes = false;
  for (const cl_int4& l : requested)
    if (l.s[0] == IVR_LANE_RAY) {
      source.push_back((long long)l.s[2] * kColumns + l.s[1]);
      ray_lanes = true;
    } else {
      source.push_back(-1 - (long long)others.size());
      others.push_back(l);
    }

  // Lanes per pass: up to 32, halved while their per-ray tangents do not fit beside the plan's
  // bricks — with fewer bricks resident (down to two) where that makes room.
  BrickPlan p = plan;
  const std::uint64_t slot = p.layout.largest_voxels() * real_size;
  const int fewest = std::min(p.layout.total(), 2);
  auto room = [&] {
    return p.budget ? (p.budget > p.bricked_bytes ? p.budget - p.bricked_bytes : 0)
                    : ~std::uint64_t(0);
  };
  auto pass_bytes = [&](int lanes, bool rays_pass) {
    return std::uint64_t(rays) * lanes * sums * real_size +
           (rays_pass ? std::uint64_t(rays) * kColumns * real_size : 0) +
           (rays + 1) * std::uint64_t(lanes + 1) * real_size + lanes * sizeof(cl_int4);
  };
  auto make_room = [&](std::uint64_t bytes) {
    while (room() < bytes && p.slots > fewest) --p.slots, p.bricked_bytes -= slot;
    return room() >= bytes;
  };
  int lanes =
      lanes_for(std::min<std::size_t>(std::max<std::size_t>(others.size(), 1), IVR_MAX_LANES));
  while (lanes > 1 && !make_room(pass_bytes(lanes, false))) lanes /= 2;
  for (bool r : {false, ray_lanes})
    if (!make_room(pass_bytes(r ? kColumns : lanes, r)))
      throw Error(Status::out_of_memory,
                  "out-of-core forward mode: the per-ray tangents of " +
                      std::to_string(r ? kColumns : lanes) + " lane(s) (" +
                      memory_text(pass_bytes(r ? kColumns : lanes, r)) +
                      ") do not fit beside the bricks in the device-memory budget of " +
                      memory_text(p.budget));
  std::vector<Pass> passes;
  for (std::size_t first = 0; first < others.size() || (first == 0 && !ray_lanes);
       first += std::size_t(lanes)) {
    passes.push_back({first, std::min<std::size_t>(lanes, others.size() - first), lanes, false});
    if (others.empty()) break;
  }
  if (ray_lanes) passes.push_back({0, 0, kColumns, true});

  RenderOptions ro;
  ro.precision = o.precision;
  ro.step = o.step;
  BrickedMarch march(device, scene, ro, p, "gradient");
  march.densities_f64 = densities;
  // Over independent segments each pass's march is this worker's segments, composited with the
  // others' (their tangents too) before FINISH; over states the tangents move with the states.
  const bool segments = domain && domain->march == SlabMarch::segments;
  if (domain && !segments) attach_exchange(march, *domain, domain_stats);
  Session::Impl& s = march.s;
  check_brick_halo(scene, s.integrator().step, p.layout);
  Device::Impl& dev = s.dev;
  march.session().set_target(target);
  BrickedTangent out;
  std::vector<double> gradient(others.size(), 0.0), ray_values;
  const std::size_t per_ray_size = ray_lanes ? rays * kColumns : 1;
  const cl::Buffer per_ray =
      dev.buffer(CL_MEM_READ_WRITE, per_ray_size * s.real_size, nullptr, "the rays' gradients");
  // The loss gradient's kernel `name` (bricked_tangent, or its packets bricked_tangent_packet).
  const auto loss_config = [&](const char* name) {
    return march.variant.config("bricked_tangent.cl", name)
        .set(Switch::jacobian, false)
        .set(Switch::loss_gradient, true)
        .set(Switch::loss_l1, o.loss == Loss::l1)
        .set(Switch::loss_dot, o.loss == Loss::dot);
  };
  for (std::size_t pass = 0; pass < passes.size(); ++pass) {
    const Pass& ps = passes[pass];
    std::vector<cl_int4> pass_lanes(std::size_t(ps.lanes), cl_int4{{IVR_LANE_NONE, 0, 0, 0}});
    bool tf = false, camera = ps.rays, voxel = false;
    if (ps.rays)
      for (int k = 0; k < kColumns; ++k) pass_lanes[std::size_t(k)] = {{IVR_LANE_RAY, k, 0, 0}};
    for (std::size_t k = 0; k < ps.count; ++k) {
      pass_lanes[k] = others[ps.first + k];
      tf |= pass_lanes[k].s[0] == IVR_LANE_TF;
      camera |= pass_lanes[k].s[0] == IVR_LANE_CAMERA;
      voxel |= pass_lanes[k].s[0] == IVR_LANE_VOXEL;
    }
    const auto pass_config = [&](const char* name) {
      return loss_config(name)
          .set(Switch::lanes, ps.lanes)
          .set(Switch::tangent_tf, tf)
          .set(Switch::tangent_camera, camera)
          .set(Switch::tangent_voxel, voxel)
          .set(Switch::ray_gradient, ps.rays);
    };
    const KernelConfig config = pass_config("bricked_tangent");
    cl::Kernel& k = s.kernels.get(config, &march.op.stats.build_seconds);
    march.op.stats.variant = config.label();
    // On CPUs a pass of TF and background lanes marches packets of rays in vector lanes, as in
    // core (march.lanes(): the fixed-step schemes on CPUs); camera, voxel and ray lanes, whose
    // geometry is per ray, one ray per work-item. FINISH is the one-ray kernel's either way.
    cl::Kernel* packet = nullptr;
    if (march.lanes() > 1 && !camera && !voxel && !ps.rays) {
      const KernelConfig pc =
          pass_config("bricked_tangent_packet").set(Switch::rays, march.lanes());
      packet = &s.kernels.get(pc, &march.op.stats.build_seconds);
      march.op.stats.variant = pc.label();
    }
    cl::Kernel& marching = packet ? *packet : k;
    const auto sweep = [&] {
      if (packet)
        march.sweep(*packet, kTangentMarch, {}, "bricked_packet", march.tile());
      else
        march.sweep(k, kTangentMarch, {}, "bricked");
    };
    const PixelLaunch finish = pixel_launch(dev, k, "jacobian", e.width, e.height, e.views, true);
    const std::size_t groups = finish.groups_per_view * std::size_t(e.views);
    const std::size_t row = std::size_t(ps.lanes) + 1;
    const std::size_t tangent_count = rays * std::size_t(ps.lanes * sums);
    const cl::Buffer tangents =
        dev.buffer(CL_MEM_READ_WRITE, tangent_count * s.real_size, nullptr, "the per-ray tangents");
    const cl::Buffer partial = dev.buffer(CL_MEM_READ_WRITE, groups * row * s.real_size, nullptr,
                                          "the tangent partial sums");
    const cl::Buffer lanes_buf =
        dev.buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, pass_lanes.size() * sizeof(cl_int4),
                   pass_lanes.data(), "the tangent lanes");
    int a0 = 0;
    for (cl::Kernel* kernel : {&marching, &k})
      cl_call("setting the bricked tangent's arguments", [&] {
        a0 = march.arguments(*kernel);
        int a = a0 + 6;
        kernel->setArg(a++, tangents);
        kernel->setArg(a++, lanes_buf);
        kernel->setArg(a++, s.camera_params);
        kernel->setArg(a++, buffer_of(s.target));
        set_real(*kernel, a++, s.f64, 1.0 / double(rays * scene.channels()));
        kernel->setArg(a++, buffer_of(march.image));
        kernel->setArg(a++, per_ray);
        kernel->setArg(a++, partial);
        kernel->setArg(a++, cl::Local(std::size_t(finish.group_x) * finish.group_y * row *
                                      s.real_size));
      });
    // The march restarted (BEGIN), the tangents zero, the sweeps, then each pixel's terms.
    dev.queue.enqueueFillBuffer(tangents, cl_uchar(0), 0, tangent_count * s.real_size);
    if (segments) {
      const SegmentTangents carried{&tangents, ps.lanes, sums,
                                    ps.rays ? kColumns : int(ps.count),
                                    sweep};
      SegmentMarch composited(march, scene, *domain, domain_stats, &carried);
      composited.write_totals();
      composited.write_tangents();
    } else {
      march.begin();
      march.carried = {tangents};  // (over slabs: they move with the rays' states)
      sweep();
    }
    cl_call("running the bricked tangent's finish on " + dev.info.name, [&] {
      march.set_brick(k, 0, 0);
      k.setArg(a0, cl_int(kTangentFinish));
      march.op.events.push_back(enqueue(dev, k, finish));
    });
    const std::vector<double> rows = download_reals(dev, s.f64, partial, groups * row);
    std::vector<double> total(row, 0.0);
    for (std::size_t g = 0; g < groups; ++g)
      for (std::size_t c = 0; c < row; ++c) total[c] += rows[g * row + c];
    if (pass == 0) out.loss = total[0];
    for (std::size_t c = 0; c < ps.count; ++c) gradient[ps.first + c] = total[1 + c];
    if (ps.rays) ray_values = download_reals(dev, s.f64, per_ray, rays * kColumns);
    out.device_bytes =
        std::max<std::uint64_t>(out.device_bytes, p.bricked_bytes + pass_bytes(ps.lanes, ps.rays));
  }
  out.gradient.reserve(requested.size());
  for (long long src : source)
    out.gradient.push_back(src >= 0 ? ray_values[std::size_t(src)]
                                    : gradient[std::size_t(-1 - src)]);
  out.passes = passes.size();
  out.lanes = std::size_t(passes.front().lanes);
  out.kernel_seconds = march.session().last_stats().kernel_seconds;
  return out;
}

}  // namespace ivr
