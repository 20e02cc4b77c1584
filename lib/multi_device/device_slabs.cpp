// device_slabs.cpp — domain-parallel over several devices in one process: the volume's slabs, one
// per device (render, gradient, tomography), each on a thread of its own, the devices meeting
// in-process (WorkerGather) where MPI ranks would meet over the network (docs/scaling.md).
#include <algorithm>

#include "ivr/domain.hpp"
#include "ivr/error.hpp"
#include "multi_device/run_shares.hpp"

namespace ivr {

namespace {

// Runs job(i, part) for device i of n with its DomainPart, every device's collectives in this
// process; a device that fails stops the others' collectives (its own error is the one thrown).
// The slabs follow share_weights(devices, shares): the shares given, else the devices' speeds.
template <class Job>
void on_device_slabs(const std::vector<Device*>& devices, const Scene& scene, SlabMarch march,
                     const std::vector<double>& shares, Job&& job) {
  check_devices(devices);
  const int n = int(devices.size());
  const std::vector<double> weights = share_weights(devices, shares);
  // More devices than cells, or a bad weight: said before any thread starts.
  domain_slab(scene.volume.nz, 0, n, weights);
  WorkerGather meeting(n);
  run_shares(
      devices.size(),
      [&](std::size_t i) {
        DomainPart part;
        part.rank = int(i), part.ranks = n, part.march = march, part.shares = weights;
        part.all_gather = meeting.of(int(i));
        job(i, part);
      },
      [&] { meeting.abort(); });
}

}  // namespace

Image render_domain(const std::vector<Device*>& devices, const Scene& scene, SlabMarch march,
                    const RenderOptions& options, RenderStats* stats, DomainStats* domain) {
  std::vector<Image> images(devices.size());
  std::vector<RenderStats> st(devices.size());
  std::vector<DomainStats> ds(devices.size());
  on_device_slabs(devices, scene, march, options.shares, [&](std::size_t i, const DomainPart& part) {
    images[i] = render_domain(*devices[i], domain_share(scene, part.rank, part.ranks, part.shares), part,
                              options, &st[i], &ds[i]);
  });
  if (stats) {
    *stats = st[0];
    for (std::size_t i = 1; i < st.size(); ++i) {
      stats->kernel_seconds = std::max(stats->kernel_seconds, st[i].kernel_seconds);
      stats->samples += st[i].samples;
      stats->device_bytes = std::max(stats->device_bytes, st[i].device_bytes);
      stats->bricks += st[i].bricks;
      stats->uploaded_bytes += st[i].uploaded_bytes;
      stats->brick_uploads += st[i].brick_uploads;
    }
    stats->devices = int(devices.size());
  }
  if (domain) *domain = ds[0];
  return std::move(images[0]);  // (every device holds the whole image)
}

Gradient gradient_domain(const std::vector<Device*>& devices, const Scene& scene,
                         const Image& target, SlabMarch march, const GradientOptions& options,
                         DomainStats* domain, const std::vector<std::string>& groups) {
  if (options.workers > 1)
    throw Error(Status::invalid_argument,
                "gradient_domain: " + std::to_string(devices.size()) + " devices for worker " +
                    std::to_string(options.worker) + " of " + std::to_string(options.workers) +
                    ": give each worker one device");
  std::vector<Gradient> g(devices.size());
  std::vector<DomainStats> ds(devices.size());
  on_device_slabs(devices, scene, march, options.shares, [&](std::size_t i, const DomainPart& part) {
    g[i] = gradient_domain(*devices[i], domain_share(scene, part.rank, part.ranks, part.shares), target, part,
                           options, &ds[i], groups);
  });
  Gradient out = std::move(g[0]);
  for (std::size_t k = 0; k < out.groups.size(); ++k) {
    GroupGradient& group = out.groups[k];
    if (group.name == "tf") {  // each device's part: its slab's samples, added in device order
      for (std::size_t i = 1; i < g.size(); ++i)
        for (std::size_t j = 0; j < group.values.size(); ++j)
          group.values[j] += g[i].groups[k].values[j];
    } else if (group.name == "density") {
      std::vector<std::vector<double>> slabs{std::move(group.values)};
      for (std::size_t i = 1; i < g.size(); ++i) slabs.push_back(std::move(g[i].groups[k].values));
      group.values = domain_join(scene.volume.nx, scene.volume.ny, scene.volume.nz, slabs);
      group.shape[0] = std::size_t(scene.volume.nz);
    }  // (the background and the forward lanes: whole on every device)
  }
  out.parameters = 0;
  for (const GroupGradient& group : out.groups) out.parameters += group.values.size();
  for (std::size_t i = 1; i < g.size(); ++i) {
    out.kernel_seconds = std::max(out.kernel_seconds, g[i].kernel_seconds);
    out.device_bytes = std::max(out.device_bytes, g[i].device_bytes);
    out.bricks += g[i].bricks;
  }
  out.devices = int(devices.size());
  if (domain) *domain = ds[0];
  return out;
}

TomoResult tomo_domain(const std::vector<Device*>& devices, const Scene& scene,
                       const std::vector<double>& lines, const TomoOptions& options,
                       const TomoProgress& progress) {
  std::vector<TomoResult> r(devices.size());
  on_device_slabs(devices, scene, SlabMarch::states, options.shares,
                  [&](std::size_t i, const DomainPart& part) {
    // `progress` asked on device 0 alone; tomo_domain stops every worker where any says stop.
    r[i] = tomo_domain(*devices[i], scene, lines, part, options,
                       i == 0 ? progress : TomoProgress{});
  });
  const int nx = scene.volume.nx, ny = scene.volume.ny, nz = scene.volume.nz;
  std::vector<std::vector<double>> slabs, slabs_f64;
  for (const TomoResult& one : r) {
    slabs.emplace_back(one.volume.begin(), one.volume.end());
    if (options.precision == Precision::f64) slabs_f64.push_back(one.volume_f64);
  }
  TomoResult out = std::move(r[0]);
  const std::vector<double> joined = domain_assemble(nx, ny, nz, slabs);
  out.volume.assign(joined.begin(), joined.end());
  if (options.precision == Precision::f64) out.volume_f64 = domain_assemble(nx, ny, nz, slabs_f64);
  for (std::size_t i = 1; i < r.size(); ++i) {
    out.bricks += r[i].bricks;
    out.setup_seconds = std::max(out.setup_seconds, r[i].setup_seconds);
  }
  return out;
}

}  // namespace ivr
