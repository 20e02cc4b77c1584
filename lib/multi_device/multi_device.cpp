// multi_device.cpp — several devices in one process: a scene's views (or a ray list's rays) split
// into contiguous shares, one per device, each share rendered, differentiated or solved for
// (tomography) on its device in a thread of its own, and the results combined on the host in
// device order (docs/scaling.md).
#include <algorithm>
#include <cmath>

#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/planner.hpp"
#include "ivr/render.hpp"
#include "ivr/tomo.hpp"
#include "multi_device/run_shares.hpp"

namespace ivr {

std::vector<std::pair<std::size_t, std::size_t>> view_shares(std::size_t n, std::size_t parts) {
  if (parts == 0) return {};
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (const auto& share : view_shares(n, std::vector<double>(parts, 1.0)))
    if (share.second) out.push_back(share);  // (empty shares dropped)
  return out;
}

std::vector<std::pair<std::size_t, std::size_t>> view_shares(std::size_t n,
                                                             const std::vector<double>& weights) {
  if (weights.empty()) throw Error(Status::invalid_argument, "shares: no weights");
  double total = 0;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!(weights[i] > 0) || !std::isfinite(weights[i]))
      throw Error(Status::invalid_argument, "shares[" + std::to_string(i) + "]: " +
                                                std::to_string(weights[i]) +
                                                " (a weight must be > 0 and finite)");
    total += weights[i];
  }
  if (!std::isfinite(total)) throw Error(Status::invalid_argument, "shares: the weights' sum overflows");
  std::vector<std::size_t> count(weights.size());
  if (std::all_of(weights.begin(), weights.end(), [&](double w) { return w == weights[0]; })) {
    for (std::size_t d = 0; d < weights.size(); ++d)  // (as equal as can be, the first larger)
      count[d] = n / weights.size() + (d < n % weights.size() ? 1 : 0);
  } else {
    // Largest remainder: each share its quota's floor, the views left over to the largest
    // fractions (ties to the lower index).
    std::vector<double> fraction(weights.size());
    std::size_t given = 0;
    for (std::size_t d = 0; d < weights.size(); ++d) {
      // (n · w first: where the weights are counts summing to n, each quota is its count exactly,
      // so a share's counts given back as weights split the same way)
      double quota = double(n) * weights[d] / total;
      if (!std::isfinite(quota)) quota = double(n) * (weights[d] / total);
      count[d] = std::min(n - given, std::size_t(std::floor(quota)));
      fraction[d] = quota - std::floor(quota);
      given += count[d];
    }
    std::vector<std::size_t> order(weights.size());
    for (std::size_t d = 0; d < order.size(); ++d) order[d] = d;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return fraction[a] > fraction[b]; });
    for (std::size_t k = 0; given < n; k = (k + 1) % order.size(), ++given) ++count[order[k]];
  }
  std::vector<std::pair<std::size_t, std::size_t>> out;
  std::size_t first = 0;
  for (std::size_t c : count) {
    out.push_back({first, c});
    first += c;
  }
  return out;
}

std::vector<std::pair<std::size_t, std::size_t>> view_shares_each(
    std::size_t n, const std::vector<double>& weights) {
  std::vector<std::pair<std::size_t, std::size_t>> out = view_shares(n, weights);  // (checked)
  if (n < weights.size())  // one view each to the first n: the equal split's
    return view_shares(n, std::vector<double>(weights.size(), 1.0));
  const bool empty = std::any_of(out.begin(), out.end(), [](const auto& s) { return s.second == 0; });
  if (!empty) return out;
  // One view each first, the rest by the weights (their split of n - parts, shifted).
  const auto rest = view_shares(n - weights.size(), weights);
  std::size_t first = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = {first, rest[i].second + 1};
    first += out[i].second;
  }
  return out;
}

std::pair<std::size_t, std::size_t> worker_share(std::size_t n, int worker, int workers,
                                                 const std::vector<double>& shares) {
  if (!shares.empty() && shares.size() != std::size_t(workers))
    throw Error(Status::invalid_argument, "shares: " + std::to_string(shares.size()) +
                                              " weights for " + std::to_string(workers) +
                                              " workers");
  return view_shares(n, shares.empty() ? std::vector<double>(std::size_t(workers), 1.0)
                                       : shares)[std::size_t(worker)];
}

std::vector<double> share_weights(const std::vector<Device*>& devices,
                                  const std::vector<double>& given) {
  check_devices(devices);
  if (!given.empty()) {
    if (given.size() != devices.size())
      throw Error(Status::invalid_argument, "shares: " + std::to_string(given.size()) +
                                                " weights for " + std::to_string(devices.size()) +
                                                " devices");
    view_shares(0, given);  // (each weight checked)
    return given;
  }
  if (devices.size() == 1) return {1.0};  // (one device takes every view: no cost model read)
  std::vector<double> out;
  for (const Device* d : devices) {
    const double speed = samples_per_second(d->info());
    if (!(speed > 0) || !std::isfinite(speed))
      throw Error(Status::invalid_argument,
                  "shares: device " + d->info().name + "'s cost model gives " +
                      std::to_string(speed) + " samples per second (" +
                      load_cost_model(d->info()).source + "); give the shares");
    out.push_back(speed);
  }
  return out;
}

std::vector<std::size_t> active_shares(const std::vector<Device*>& devices, std::size_t n,
                                       const std::vector<double>& given,
                                       std::vector<std::pair<std::size_t, std::size_t>>& parts,
                                       std::vector<double>* weights) {
  const std::vector<double> w = share_weights(devices, given);
  parts = view_shares(n, w);
  // The active devices' weights are their counts: a worker splitting the same n by them gets the
  // same shares back (by the remaining weights alone the remainders could fall otherwise).
  std::vector<std::size_t> active;
  for (std::size_t i = 0; i < parts.size(); ++i)
    if (parts[i].second > 0) {
      active.push_back(i);
      if (weights) weights->push_back(double(parts[i].second));
    }
  return active;
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
  std::vector<std::pair<std::size_t, std::size_t>> parts;
  const std::vector<std::size_t> active =
      active_shares(devices, share_items(scene), options.shares, parts, nullptr);
  if (active.size() <= 1)  // (no views at all: device 0 says what is wrong with the scene)
    return render(*devices[active.empty() ? 0 : active[0]], scene, options, stats);
  std::vector<Image> images(active.size());
  std::vector<RenderStats> st(active.size());
  run_shares(active.size(), [&](std::size_t i) {
    const auto [first, count] = parts[active[i]];
    images[i] = render(*devices[active[i]], scene_share(scene, first, count), options, &st[i]);
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
    stats->devices = int(active.size());
  }
  return out;
}

Gradient gradient(const std::vector<Device*>& devices, const Scene& scene, const Image& target,
                  const std::vector<std::string>& groups, const GradientOptions& options) {
  check_devices(devices);
  // (one device as a data-parallel worker: options.shares are the workers')
  if (devices.size() == 1 && options.workers > 1)
    return gradient(*devices[0], scene, target, groups, options);
  if (options.workers > 1)
    throw Error(Status::invalid_argument,
                "gradient: " + std::to_string(devices.size()) + " devices for worker " +
                    std::to_string(options.worker) + " of " + std::to_string(options.workers) +
                    ": give each worker one device");
  std::vector<std::pair<std::size_t, std::size_t>> parts;
  std::vector<double> weights;
  const std::vector<std::size_t> active =
      active_shares(devices, share_items(scene), options.shares, parts, &weights);
  const std::size_t workers = active.size();
  if (workers <= 1) {
    GradientOptions one = options;
    one.shares.clear();
    return gradient(*devices[active.empty() ? 0 : active[0]], scene, target, groups, one);
  }
  // Each device a worker of its own (gradient_shared), summing through a rendezvous of threads.
  WorkerSum sum{int(workers)};
  std::vector<Gradient> g(workers);
  run_shares(
      workers,
      [&](std::size_t i) {
        GradientOptions o = options;
        o.worker = int(i), o.workers = int(workers), o.sum = sum.of(int(i));
        o.shares = weights;  // (the active devices' counts: each its share of `parts`)
        g[i] = gradient(*devices[active[i]], scene, target, groups, o);
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
  const std::size_t items = share_items(scene);
  std::vector<std::pair<std::size_t, std::size_t>> parts;
  const std::vector<std::size_t> active = active_shares(devices, items, options.shares, parts, nullptr);
  const std::size_t workers = active.size();
  if (workers <= 1) return tomo(*devices[active.empty() ? 0 : active[0]], scene, lines, options, progress);
  if (lines.size() % items != 0)
    throw Error(Status::invalid_argument,
                "projections: " + std::to_string(lines.size()) + " values for the scene's " +
                    std::to_string(items) + (scene.has_ray_list() ? " rays" : " views"));
  const std::size_t per_item = lines.size() / items;
  WorkerSum sum{int(workers)};
  std::vector<TomoResult> r(workers);
  run_shares(
      workers,
      [&](std::size_t i) {
        const auto [first, count] = parts[active[i]];
        const std::vector<double> mine(lines.begin() + std::ptrdiff_t(first * per_item),
                                       lines.begin() + std::ptrdiff_t((first + count) * per_item));
        r[i] = tomo_shared(*devices[active[i]], scene_share(scene, first, count), mine, options,
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
