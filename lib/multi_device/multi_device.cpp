// multi_device.cpp — several devices in one process: a scene's views (or a ray list's rays) split
// into contiguous shares, one per device, each share rendered, differentiated or solved for
// (tomography) on its device in a thread of its own, and the results combined on the host in
// device order (docs/scaling.md).
#include <algorithm>

#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/render.hpp"
#include "ivr/tomo.hpp"
#include "multi_device/run_shares.hpp"

namespace ivr {

std::vector<std::pair<std::size_t, std::size_t>> view_shares(std::size_t n, std::size_t parts) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  std::size_t first = 0;
  for (std::size_t d = 0; d < parts; ++d) {
    const std::size_t count = n / parts + (d < n % parts ? 1 : 0);
    if (count) out.push_back({first, count});
    first += count;
  }
  return out;
}

Scene scene_share(const Scene& scene, std::size_t first, std::size_t count) {
  if (first + count > share_items(scene))
    throw Error(Status::invalid_argument, "scene share [" + std::to_string(first) + ", " +
                                              std::to_string(first + count) + ") past its " +
                                              std::to_string(share_items(scene)) + " views or rays");
  Scene s = scene;
  if (scene.has_ray_list())
    s.rays.values.assign(scene.rays.values.begin() + first * RayList::kColumns,
                         scene.rays.values.begin() + (first + count) * RayList::kColumns);
  else
    s.cameras.assign(scene.cameras.begin() + first, scene.cameras.begin() + first + count);
  return s;
}

std::size_t share_items(const Scene& scene) {
  return scene.has_ray_list() ? scene.rays.count() : scene.cameras.size();
}

Image target_share(const Scene& scene, const Image& target, std::size_t first, std::size_t count) {
  const std::size_t n = share_items(scene);
  const std::size_t per_item = n ? target.pixels.size() / n : 0;
  if (first + count > n || per_item * n != target.pixels.size())
    throw Error(Status::invalid_argument,
                "target share [" + std::to_string(first) + ", " + std::to_string(first + count) +
                    ") of " + std::to_string(target.pixels.size()) + " values for " +
                    std::to_string(n) + " views or rays");
  Image t = target;
  t.pixels.assign(target.pixels.begin() + first * per_item,
                  target.pixels.begin() + (first + count) * per_item);
  t.pixels_f64.clear();
  if (!target.pixels_f64.empty())
    t.pixels_f64.assign(target.pixels_f64.begin() + first * per_item,
                        target.pixels_f64.begin() + (first + count) * per_item);
  if (scene.has_ray_list())
    t.width = int(count);
  else
    t.views = int(count);
  return t;
}

bool per_view_group(const std::string& group) { return group == "camera" || group == "rays"; }

Image render(const std::vector<Device*>& devices, const Scene& scene, const RenderOptions& options,
             RenderStats* stats) {
  check_devices(devices);
  if (devices.size() == 1) return render(*devices[0], scene, options, stats);
  const auto parts = view_shares(share_items(scene), devices.size());
  std::vector<Image> images(parts.size());
  std::vector<RenderStats> st(parts.size());
  run_shares(parts.size(), [&](std::size_t i) {
    images[i] = render(*devices[i], scene_share(scene, parts[i].first, parts[i].second), options, &st[i]);
  });
  Image out = images[0];
  for (std::size_t i = 1; i < images.size(); ++i) {
    out.pixels.insert(out.pixels.end(), images[i].pixels.begin(), images[i].pixels.end());
    out.pixels_f64.insert(out.pixels_f64.end(), images[i].pixels_f64.begin(),
                          images[i].pixels_f64.end());
    if (scene.has_ray_list())
      out.width += images[i].width;  // (1, 1, rays, C)
    else
      out.views += images[i].views;
  }
  if (stats) {
    *stats = st[0];
    for (std::size_t i = 1; i < st.size(); ++i) {
      stats->kernel_seconds = std::max(stats->kernel_seconds, st[i].kernel_seconds);
      stats->samples += st[i].samples;
      stats->device_bytes = std::max(stats->device_bytes, st[i].device_bytes);
      stats->bricks = std::max(stats->bricks, st[i].bricks);
    }
    stats->devices = int(parts.size());
  }
  return out;
}

Gradient gradient(const std::vector<Device*>& devices, const Scene& scene, const Image& target,
                  const std::vector<std::string>& groups, const GradientOptions& options) {
  check_devices(devices);
  const std::size_t workers = std::min(devices.size(), share_items(scene));
  if (workers <= 1) return gradient(*devices[0], scene, target, groups, options);
  if (options.workers > 1)
    throw Error(Status::invalid_argument,
                "gradient: " + std::to_string(devices.size()) + " devices for worker " +
                    std::to_string(options.worker) + " of " + std::to_string(options.workers) +
                    ": give each worker one device");
  // Each device a worker of its own (gradient_shared), summing through a rendezvous of threads.
  WorkerSum sum{int(workers)};
  std::vector<Gradient> g(workers);
  run_shares(
      workers,
      [&](std::size_t i) {
        GradientOptions o = options;
        o.worker = int(i), o.workers = int(workers), o.sum = sum.of(int(i));
        g[i] = gradient(*devices[i], scene, target, groups, o);
      },
      [&] { sum.abort(); });
  Gradient out = g[0];  // (every worker holds the whole gradient)
  for (std::size_t i = 1; i < g.size(); ++i) {
    out.kernel_seconds = std::max(out.kernel_seconds, g[i].kernel_seconds);
    out.device_bytes = std::max(out.device_bytes, g[i].device_bytes);
    out.bricks = std::max(out.bricks, g[i].bricks);
  }
  out.devices = int(workers);
  return out;
}

TomoResult tomo(const std::vector<Device*>& devices, const Scene& scene,
                const std::vector<double>& lines, const TomoOptions& options,
                const TomoProgress& progress) {
  check_devices(devices);
  const std::size_t items = share_items(scene);
  const std::size_t workers = std::min(devices.size(), items);
  if (workers <= 1) return tomo(*devices[0], scene, lines, options, progress);
  if (lines.size() % items != 0)
    throw Error(Status::invalid_argument,
                "projections: " + std::to_string(lines.size()) + " values for the scene's " +
                    std::to_string(items) + (scene.has_ray_list() ? " rays" : " views"));
  const std::size_t per_item = lines.size() / items;
  const auto parts = view_shares(items, workers);
  WorkerSum sum{int(workers)};
  std::vector<TomoResult> r(workers);
  run_shares(
      workers,
      [&](std::size_t i) {
        const auto [first, count] = parts[i];
        const std::vector<double> mine(lines.begin() + std::ptrdiff_t(first * per_item),
                                       lines.begin() + std::ptrdiff_t((first + count) * per_item));
        r[i] = tomo_shared(*devices[i], scene_share(scene, first, count), mine, options,
                           sum.of(int(i)), i == 0 ? progress : TomoProgress{});
      },
      [&] { sum.abort(); });
  TomoResult out = std::move(r[0]);  // (every device holds the whole iterate)
  for (std::size_t i = 1; i < r.size(); ++i) {
    out.bricks = std::max(out.bricks, r[i].bricks);
    out.setup_seconds = std::max(out.setup_seconds, r[i].setup_seconds);
  }
  return out;
}

}  // namespace ivr
