// bricked_project.cpp — the projector pair brick by brick.
#include "brick/bricked_project.hpp"

#include <algorithm>

#include "brick/brick_stream.hpp"
#include "brick/bricked_render.hpp"
#include "ivr/error.hpp"
#include "runtime/real_args.hpp"
#include "session/session.hpp"
#include "runtime/launch.hpp"
#include "tomo/project.hpp"

namespace ivr {

namespace {

constexpr int kSlots = 2;

// The geometry (arguments 1 … 7) and brick b's planes, extent and origin (arguments 1, 9 … 11).
void set_brick_args(Projector::Impl& p, cl::Kernel& k, const BrickLayout& l, int b) {
  const Scene& scene = p.s.scene;
  const glm::dvec3 h = scene.voxel_size();
  const std::array<int, 3> o = l.origin(b), x = l.extent(b);
  const std::array<double, 3> lo = l.lo(b), hi = l.hi(b);
  k.setArg(1, cl_int4{{x[0], x[1], x[2], 0}});
  set_real4(k, 2, p.s.f64, scene.box_min.x, scene.box_min.y, scene.box_min.z);
  set_real4(k, 3, p.s.f64, scene.box_max.x, scene.box_max.y, scene.box_max.z);
  set_real4(k, 4, p.s.f64, 1 / h.x, 1 / h.y, 1 / h.z);
  k.setArg(5, p.s.cameras);
  k.setArg(6, cl_int(p.width));
  k.setArg(7, cl_int(p.height));
  set_real4(k, 9, p.s.f64, lo[0], lo[1], lo[2]);
  set_real4(k, 10, p.s.f64, hi[0], hi[1], hi[2]);
  k.setArg(11, cl_int4{{o[0], o[1], o[2], 0}});
}

}  // namespace

BrickLayout plan_projector(Device& device, const Scene& scene, Precision precision,
                           int forced_edge) {
  const std::size_t real = precision == Precision::f64 ? 8 : 4;
  const std::uint64_t voxels = scene.volume.voxel_count(), rays = image_extent(scene).pixels();
  const std::uint64_t budget = brick_budget(device);
  const std::uint64_t geometry = (64 * scene.cameras.size() + 8 * scene.rays.count()) * real + 1024;
  if (forced_edge <= 0) forced_edge = volume_brick_from_env();
  if (forced_edge <= 0 && (budget == 0 || (voxels + rays) * real + geometry <= budget)) return {};
  const std::uint64_t fixed = rays * real + geometry;
  const int longest = std::max({scene.volume.nx, scene.volume.ny, scene.volume.nz});
  auto fits = [&](int edge) {
    const BrickLayout l = brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, edge);
    const std::uint64_t slot = l.largest_voxels() * real;
    return slot <= device.info().max_allocation && fixed + kSlots * slot <= budget;
  };
  int edge = forced_edge;
  if (edge <= 0) {
    edge = 1;
    while (edge * 2 < longest && fits(edge * 2)) edge *= 2;
  }
  if (budget && !fits(edge) && forced_edge > 0)
    throw Error(Status::out_of_memory,
                "out-of-core projector: bricks of " + std::to_string(edge) +
                    " cells and the lines (" + memory_text(fixed) +
                    ") do not fit the device-memory budget of " + memory_text(budget) +
                    (device_memory_limit_from_env() ? " (IVR_DEVICE_MEMORY_LIMIT)" : ""));
  if (budget && !fits(edge)) return {};  // the in-core projector reports what does not fit
  return brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, edge);
}

template <typename T>
std::vector<double> project_bricked(Projector::Impl& p, const BrickLayout& l, const T* volume) {
  const bool f64 = p.s.f64;
  const cl::Buffer lines = p.vector(p.rays, "the line integrals");
  BrickStream stream(p.dev, kSlots, l.largest_voxels() * p.real_size);
  double seconds = 0;
  cl_call("running the bricked projector on " + p.dev.info.name, [&] {
    p.dev.queue.enqueueFillBuffer(lines, cl_uchar(0), 0, p.rays * p.real_size);
    cl::Kernel& k = p.s.kernels.get(projector_config(p.s, "project_brick"));
    k.setArg(8, lines);
    std::vector<cl::Event> events;
    for (int b = 0; b < l.total(); ++b) {
      const int i = stream.resident(b, [&](int brick, std::vector<unsigned char>& out) {
        extract_brick(volume, l, brick, f64, out);
      });
      k.setArg(0, stream.buffer(i));
      set_brick_args(p, k, l, b);
      const std::vector<cl::Event> wait{stream.ready(i)};
      cl::Event ev;
      p.dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(p.width, p.height, p.views),
                                       cl::NullRange, &wait, &ev);
      stream.used(i, ev);
      events.push_back(ev);
    }
    cl::WaitForEvents(events);
    for (const cl::Event& e : events) seconds += event_seconds(e);
  });
  p.last_seconds = seconds;
  return p.download(lines, p.rays);
}

template <typename T>
void backproject_bricked(Projector::Impl& p, const BrickLayout& l, const std::vector<double>& lines,
                         T* volume) {
  const bool f64 = p.s.f64;
  const cl::Buffer y = p.upload(lines, "the projections");
  const std::size_t slot_bytes = l.largest_voxels() * p.real_size;
  cl::Buffer out[kSlots];
  for (auto& o : out)
    o = p.dev.buffer(CL_MEM_READ_WRITE, slot_bytes, nullptr, "a brick's back-projection");
  std::fill(volume, volume + l.held(), T(0));
  std::vector<unsigned char> host[kSlots];
  cl::Event read[kSlots];
  double seconds = 0;
  std::vector<cl::Event> events;
  cl_call("running the bricked back-projector on " + p.dev.info.name, [&] {
    cl::Kernel& k = p.s.kernels.get(projector_config(p.s, "backproject_brick"));
    k.setArg(0, y);
    // Brick b on slot b % 2: its kernel runs while the host adds brick b − 1 into the volume.
    auto finish = [&](int b) {
      const int i = b % kSlots;
      read[i].wait();
      add_brick(host[i], l, b, f64, volume);
    };
    for (int b = 0; b < l.total(); ++b) {
      const int i = b % kSlots;
      if (b >= kSlots) finish(b - kSlots);
      const std::size_t bytes = l.voxels(b) * p.real_size;
      cl::Event ev;
      p.dev.queue.enqueueFillBuffer(out[i], cl_uchar(0), 0, bytes);
      k.setArg(8, out[i]);
      set_brick_args(p, k, l, b);
      p.dev.queue.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(p.width, p.height, p.views),
                                       cl::NullRange, nullptr, &ev);
      host[i].resize(bytes);
      p.dev.queue.enqueueReadBuffer(out[i], CL_FALSE, 0, bytes, host[i].data(), nullptr, &read[i]);
      p.dev.queue.flush();
      events.push_back(ev);
    }
    for (int b = std::max(0, l.total() - kSlots); b < l.total(); ++b) finish(b);
    for (const cl::Event& e : events) seconds += event_seconds(e);
  });
  p.last_seconds = seconds;
}

template std::vector<double> project_bricked(Projector::Impl&, const BrickLayout&, const float*);
template std::vector<double> project_bricked(Projector::Impl&, const BrickLayout&, const double*);
template void backproject_bricked(Projector::Impl&, const BrickLayout&, const std::vector<double>&,
                                  float*);
template void backproject_bricked(Projector::Impl&, const BrickLayout&, const std::vector<double>&,
                                  double*);

}  // namespace ivr
