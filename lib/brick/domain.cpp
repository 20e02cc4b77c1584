// domain.cpp — domain-parallel render and density gradient: slabs, their plans, and the exchange
// of the rays' march states between workers.
#include "brick/domain.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>

#include "brick/bricked_gradient.hpp"
#include "brick/domain_segments.hpp"
#include "ivr/error.hpp"
#include "session/session.hpp"

namespace ivr {

void check_domain_part(const DomainPart& part) {
  if (part.ranks < 1 || part.rank < 0 || part.rank >= part.ranks)
    throw Error(Status::invalid_argument, "domain: worker " + std::to_string(part.rank) + " of " +
                                              std::to_string(part.ranks) + " workers");
  if (part.ranks > 1 && !part.all_gather)
    throw Error(Status::invalid_argument,
                "domain: " + std::to_string(part.ranks) + " workers need an all_gather");
}

Slab part_slab(int nz, const DomainPart& part) {
  return domain_slab(nz, part.rank, part.ranks, part.shares);
}

namespace {

// The exchange itself (attach_exchange): host copies of the states as the last exchange left them.
// A ray's entry holds its march state and, beside it, its part of every buffer the march carries
// per ray (BrickedMarch::carried: forward mode's tangents).
class StateExchange {
 public:
  StateExchange(BrickedMarch& march, const DomainPart& part, DomainStats* stats)
      : march_(march), part_(part), stats_(stats), rays_(march.rays()) {}

  // Before a march's sweeps: what it carries now, and the states to tell moved rays by.
  void keep() {
    buffers_ = {march_.state(), march_.state_u()};
    buffers_.insert(buffers_.end(), march_.carried.begin(), march_.carried.end());
    sizes_.clear();
    entry_ = 4;
    for (const cl::Buffer& b : buffers_) {
      const std::size_t bytes = b.getInfo<CL_MEM_SIZE>();
      if (bytes % rays_)
        throw Error(Status::opencl, "domain exchange: a per-ray buffer of " +
                                        std::to_string(bytes) + " bytes for " +
                                        std::to_string(rays_) + " rays");
      sizes_.push_back(bytes / rays_);
      entry_ += sizes_.back();
    }
    kept_ = read();
    kept_.resize(2);  // a ray moved where its state changed
  }

  void exchange() {
    std::vector<std::vector<unsigned char>> now = read();
    // The rays this worker moved, as (ray, state, carried …) entries.
    std::vector<unsigned char> mine;
    std::vector<int> mover(rays_, -1);
    for (std::size_t i = 0; i < rays_; ++i) {
      bool moved = false;
      for (std::size_t k = 0; k < 2; ++k)
        moved = moved || std::memcmp(&now[k][i * sizes_[k]], &kept_[k][i * sizes_[k]], sizes_[k]);
      if (!moved) continue;
      mover[i] = part_.rank;
      const std::uint32_t ray = std::uint32_t(i);
      std::size_t at = mine.size();
      mine.resize(at + entry_);
      std::memcpy(&mine[at], &ray, 4);
      at += 4;
      for (std::size_t k = 0; k < buffers_.size(); ++k) {
        std::memcpy(&mine[at], &now[k][i * sizes_[k]], sizes_[k]);
        at += sizes_[k];
      }
    }
    const std::vector<std::vector<unsigned char>> all = part_.all_gather(mine);
    if (int(all.size()) != part_.ranks)
      throw Error(Status::invalid_argument, "domain exchange: all_gather gave " +
                                                std::to_string(all.size()) + " parts for " +
                                                std::to_string(part_.ranks) + " workers");
    bool others = false;
    for (int w = 0; w < part_.ranks; ++w) {
      if (w == part_.rank) continue;
      const std::vector<unsigned char>& from = all[w];
      if (from.size() % entry_)
        throw Error(Status::invalid_argument, "domain exchange: worker " + std::to_string(w) +
                                                  " sent " + std::to_string(from.size()) +
                                                  " bytes, not whole rays");
      for (std::size_t at = 0; at < from.size(); at += entry_) {
        std::uint32_t ray = 0;
        std::memcpy(&ray, &from[at], 4);
        if (ray >= rays_ || mover[ray] >= 0)
          throw Error(Status::invalid_argument,
                      "domain exchange: ray " + std::to_string(ray) + " moved by worker " +
                          std::to_string(w) +
                          (ray < rays_ ? " and worker " + std::to_string(mover[ray]) +
                                             " in one sweep (do the workers share one scene?)"
                                       : " (no such ray)"));
        mover[ray] = w;
        std::size_t from_at = at + 4;
        for (std::size_t k = 0; k < buffers_.size(); ++k) {
          std::memcpy(&now[k][ray * sizes_[k]], &from[from_at], sizes_[k]);
          from_at += sizes_[k];
        }
        others = true;
      }
      if (stats_) stats_->received_bytes += from.size();
    }
    if (others) write(now);
    now.resize(2);
    kept_.swap(now);
    if (stats_) ++stats_->exchanges, stats_->sent_bytes += mine.size();
  }

 private:
  std::vector<std::vector<unsigned char>> read() {
    std::vector<std::vector<unsigned char>> out(buffers_.size());
    cl::CommandQueue& q = march_.s.dev.queue;
    for (std::size_t k = 0; k < buffers_.size(); ++k) {
      out[k].resize(rays_ * sizes_[k]);
      q.enqueueReadBuffer(buffers_[k], CL_FALSE, 0, out[k].size(), out[k].data());
    }
    q.finish();
    return out;
  }
  void write(const std::vector<std::vector<unsigned char>>& values) {
    cl::CommandQueue& q = march_.s.dev.queue;
    for (std::size_t k = 0; k < buffers_.size(); ++k)
      q.enqueueWriteBuffer(buffers_[k], CL_FALSE, 0, values[k].size(), values[k].data());
    q.finish();
  }

  BrickedMarch& march_;
  DomainPart part_;
  DomainStats* stats_;
  std::size_t rays_, entry_ = 0;
  std::vector<cl::Buffer> buffers_;
  std::vector<std::size_t> sizes_;
  std::vector<std::vector<unsigned char>> kept_;  // the states (reals, uints) after the last round
};

}  // namespace

namespace {

// A message of plane ranges and their values: int32 pairs [first, last] (first > last: none),
// then the ranges' values in order (T: float volumes, double gradients).
template <typename T>
std::vector<unsigned char> planes_message(const std::vector<std::array<int, 2>>& ranges,
                                          const T* values, int values_first, std::size_t plane) {
  const std::size_t bytes = plane * sizeof(T);
  std::size_t planes = 0;
  for (const std::array<int, 2>& r : ranges) planes += std::size_t(std::max(r[1] - r[0] + 1, 0));
  std::vector<unsigned char> out(ranges.size() * 8 + planes * bytes);
  std::size_t at = 0;
  for (const std::array<int, 2>& r : ranges) {
    std::memcpy(&out[at], r.data(), 8);
    at += 8;
  }
  for (const std::array<int, 2>& r : ranges)
    for (int z = r[0]; z <= r[1]; ++z) {
      std::memcpy(&out[at], values + std::size_t(z - values_first) * plane, bytes);
      at += bytes;
    }
  return out;
}

// Calls take(z, values of plane z) for every plane of a planes_message of `count` ranges.
template <typename T, typename Take>
void read_planes(const std::vector<unsigned char>& message, std::size_t count, std::size_t plane,
                 int from, Take&& take) {
  std::vector<std::array<int, 2>> ranges(count);
  std::size_t need = count * 8;
  if (message.size() >= need)
    for (std::size_t i = 0; i < count; ++i) {
      std::memcpy(ranges[i].data(), &message[i * 8], 8);
      if (ranges[i][1] >= ranges[i][0]) need += std::size_t(ranges[i][1] - ranges[i][0] + 1) * plane * sizeof(T);
    }
  if (message.size() != need)
    throw Error(Status::invalid_argument, "domain halo: worker " + std::to_string(from) + " sent " +
                                              std::to_string(message.size()) +
                                              " bytes (do the workers share one scene?)");
  std::size_t at = count * 8;
  std::vector<T> values(plane);
  for (const std::array<int, 2>& r : ranges)
    for (int z = r[0]; z <= r[1]; ++z) {
      std::memcpy(values.data(), &message[at], plane * sizeof(T));
      at += plane * sizeof(T);
      take(z, values);
    }
}

}  // namespace

// The planes layout.data_first … data_last: the slab's own values and, beyond its ends, the
// neighbours' (each worker sends the halo + 1 planes at each end of its slab).
template <typename T>
std::vector<T> with_neighbour_planes(const DomainPart& part, const Slab& slab, const BrickLayout& l,
                                     const std::vector<T>& mine) {
  if (part.ranks == 1) return mine;  // (the whole volume: nothing beyond it)
  const std::size_t plane = std::size_t(l.dims[0]) * l.dims[1];
  const std::vector<std::array<int, 2>> ends = {
      {slab.first, std::min(slab.first + l.halo, slab.last)},
      {std::max(slab.last - l.halo, slab.first), slab.last}};
  const std::vector<std::vector<unsigned char>> all =
      part.all_gather(planes_message(ends, mine.data(), slab.first, plane));
  std::vector<T> out(l.held());
  std::vector<bool> have(std::size_t(l.held_planes()), false);
  std::copy(mine.begin(), mine.end(), out.begin() + std::ptrdiff_t((slab.first - l.data_first) * plane));
  for (int z = slab.first; z <= slab.last; ++z) have[std::size_t(z - l.data_first)] = true;
  for (int w = 0; w < int(all.size()); ++w)
    if (w != part.rank)
      read_planes<T>(all[w], 2, plane, w, [&](int z, const std::vector<T>& values) {
        if (z < l.data_first || z > l.data_last) return;
        std::copy(values.begin(), values.end(), out.begin() + std::ptrdiff_t((z - l.data_first) * plane));
        have[std::size_t(z - l.data_first)] = true;
      });
  for (int z = l.data_first; z <= l.data_last; ++z)
    if (!have[std::size_t(z - l.data_first)])
      throw Error(Status::unsupported,
                  "domain gradient: the " + std::to_string(l.halo) + "-plane halo of worker " +
                      std::to_string(part.rank) + "'s slab (planes " + std::to_string(slab.first) +
                      ".." + std::to_string(slab.last) + ") reaches plane " + std::to_string(z) +
                      ", past its neighbour's slab: use fewer workers or a shorter step");
  return out;
}
template std::vector<float> with_neighbour_planes(const DomainPart&, const Slab&,
                                                  const BrickLayout&, const std::vector<float>&);
template std::vector<double> with_neighbour_planes(const DomainPart&, const Slab&,
                                                   const BrickLayout&, const std::vector<double>&);

// The slab's planes of a gradient over layout.data_first … data_last, with what the other workers'
// halos gathered for its planes added (each plane once, by its owner: a plane neighbours share
// is the lower's, as domain_join() adds the slabs' shared planes).
std::vector<double> return_halo(const DomainPart& part, const Slab& slab, const BrickLayout& l,
                                const std::vector<double>& gradient) {
  if (part.ranks == 1) return gradient;
  const std::size_t plane = std::size_t(l.dims[0]) * l.dims[1];
  const std::vector<std::array<int, 2>> outside = {{l.data_first, slab.first - 1},
                                                   {slab.last + 1, l.data_last}};
  const std::vector<std::vector<unsigned char>> all =
      part.all_gather(planes_message(outside, gradient.data(), l.data_first, plane));
  std::vector<double> out(gradient.begin() + std::ptrdiff_t((slab.first - l.data_first) * plane),
                          gradient.begin() + std::ptrdiff_t((slab.last - l.data_first + 1) * plane));
  const int owned_first = slab.first + (part.rank > 0 ? 1 : 0);
  for (int w = 0; w < int(all.size()); ++w)
    if (w != part.rank)
      read_planes<double>(all[w], 2, plane, w, [&](int z, const std::vector<double>& values) {
        if (z < owned_first || z > slab.last) return;
        double* at = out.data() + std::size_t(z - slab.first) * plane;
        for (std::size_t i = 0; i < plane; ++i) at[i] += values[i];
      });
  return out;
}

std::vector<std::vector<double>> gather_doubles(const DomainPart& part,
                                                const std::vector<double>& mine, const char* what) {
  std::vector<unsigned char> bytes(mine.size() * sizeof(double));
  if (!mine.empty()) std::memcpy(bytes.data(), mine.data(), bytes.size());
  const std::vector<std::vector<unsigned char>> all = part.all_gather(bytes);
  if (int(all.size()) != part.ranks)
    throw Error(Status::invalid_argument, std::string(what) + ": all_gather gave " +
                                              std::to_string(all.size()) + " parts for " +
                                              std::to_string(part.ranks) + " workers");
  std::vector<std::vector<double>> out(all.size());
  for (std::size_t w = 0; w < all.size(); ++w) {
    if (all[w].size() != bytes.size())
      throw Error(Status::invalid_argument, std::string(what) + ": worker " + std::to_string(w) +
                                                " sent " + std::to_string(all[w].size()) +
                                                " bytes, not " + std::to_string(bytes.size()) +
                                                " (do the workers share one scene?)");
    out[w].resize(mine.size());
    if (!mine.empty()) std::memcpy(out[w].data(), all[w].data(), all[w].size());
  }
  return out;
}

std::vector<double> sum_over(const DomainPart& part, const std::vector<double>& mine,
                             const char* what) {
  if (part.ranks == 1) return mine;
  std::vector<double> sum(mine.size(), 0.0);
  for (const std::vector<double>& w : gather_doubles(part, mine, what))
    for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += w[i];
  return sum;
}

AllGather all_gather_by_sum(int rank, int ranks, std::function<void(std::vector<double>&)> sum) {
  if (ranks < 1 || rank < 0 || rank >= ranks || !sum)
    throw Error(Status::invalid_argument, "all_gather_by_sum: worker " + std::to_string(rank) +
                                              " of " + std::to_string(ranks) +
                                              (sum ? "" : " without a sum"));
  return [rank, ranks, sum](const std::vector<unsigned char>& mine) {
    std::vector<double> sizes(std::size_t(ranks), 0.0);
    sizes[std::size_t(rank)] = double(mine.size());
    sum(sizes);
    std::size_t words = 0;  // 4 bytes a word, the longest part's
    for (double n : sizes) words = std::max(words, (std::size_t(n) + 3) / 4);
    std::vector<double> all(words * std::size_t(ranks), 0.0);
    for (std::size_t i = 0; i < mine.size(); ++i)
      all[std::size_t(rank) * words + i / 4] += double(std::uint32_t(mine[i]) << (8 * (i % 4)));
    sum(all);
    std::vector<std::vector<unsigned char>> out;
    out.resize(std::size_t(ranks));
    for (int w = 0; w < ranks; ++w) {
      const std::size_t n = std::size_t(sizes[std::size_t(w)]);
      if (double(n) != sizes[std::size_t(w)] || n > words * 4)
        throw Error(Status::invalid_argument, "all_gather_by_sum: the sum gave worker " +
                                                  std::to_string(w) + " a size of " +
                                                  std::to_string(sizes[std::size_t(w)]));
      out[std::size_t(w)].resize(n);
      for (std::size_t i = 0; i < n; ++i)
        out[std::size_t(w)][i] =
            (unsigned char)(std::uint32_t(all[std::size_t(w) * words + i / 4]) >> (8 * (i % 4)));
    }
    return out;
  };
}

Slab domain_slab(int nz, int rank, int ranks) {
  const int cells = nz - 1;
  if (ranks < 1 || rank < 0 || rank >= ranks)
    throw Error(Status::invalid_argument, "domain: worker " + std::to_string(rank) + " of " +
                                              std::to_string(ranks) + " workers");
  if (ranks > cells)
    throw Error(Status::invalid_argument, "domain: " + std::to_string(ranks) +
                                              " workers for a volume of " + std::to_string(nz) +
                                              " planes: at most one worker per cell (" +
                                              std::to_string(std::max(cells, 0)) + ")");
  return Slab{int(std::int64_t(rank) * cells / ranks), int(std::int64_t(rank + 1) * cells / ranks)};
}

Slab domain_slab(int nz, int rank, int ranks, const std::vector<double>& shares) {
  const Slab equal = domain_slab(nz, rank, ranks);  // (the worker and the cells checked)
  if (shares.empty()) return equal;
  if (shares.size() != std::size_t(ranks))
    throw Error(Status::invalid_argument, "domain: " + std::to_string(shares.size()) +
                                              " shares for " + std::to_string(ranks) + " workers");
  // (each weight checked; at least a cell each, as there are at least as many cells as workers)
  const auto parts = view_shares_each(std::size_t(nz - 1), shares);
  if (std::all_of(shares.begin(), shares.end(), [&](double w) { return w == shares[0]; }))
    return equal;
  const auto [first, cells] = parts[std::size_t(rank)];
  return Slab{int(first), int(first + cells)};
}

Scene domain_share(const Scene& scene, int rank, int ranks) {
  return domain_share(scene, rank, ranks, {});
}

Scene domain_share(const Scene& scene, int rank, int ranks, const std::vector<double>& shares) {
  const Slab slab = domain_slab(scene.volume.nz, rank, ranks, shares);
  if (scene.volume.data.size() != scene.volume.voxel_count())
    throw Error(Status::invalid_argument,
                "volume: holds " + std::to_string(scene.volume.data.size()) +
                    " values but dims need " + std::to_string(scene.volume.voxel_count()));
  Scene part = description_of(scene);
  const std::size_t plane = std::size_t(scene.volume.nx) * scene.volume.ny;
  part.volume.data.assign(scene.volume.data.begin() + plane * slab.first,
                          scene.volume.data.begin() + plane * (slab.last + 1));
  return part;
}

BrickPlan plan_domain(Device& device, const Scene& scene, Precision precision, int forced_edge,
                      bool gradient, const Slab& slab, int halo) {
  Scene part = description_of(scene);
  part.volume.nz = slab.planes();
  BrickPlan plan = plan_render(device, part, precision, forced_edge, gradient, halo);
  if (!plan.layout.edge) {  // the slab fits the device: one brick of it
    const int whole = std::max({scene.volume.nx - 1, scene.volume.ny - 1, slab.planes() - 1, 1});
    plan = plan_render(device, part, precision, whole, gradient, halo);
  }
  plan.layout = brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, plan.layout.edge,
                             slab.first, slab.last, halo);
  plan.layout.data_first = std::max(slab.first - halo, 0);
  plan.layout.data_last = std::min(slab.last + halo, scene.volume.nz - 1);
  return plan;
}

const std::vector<float>& slab_values(const Scene& scene, const Slab& slab) {
  const std::size_t plane = std::size_t(scene.volume.nx) * scene.volume.ny;
  if (scene.volume.data.size() != plane * slab.planes())
    throw Error(Status::invalid_argument,
                "volume: holds " + std::to_string(scene.volume.data.size()) + " values but planes " +
                    std::to_string(slab.first) + ".." + std::to_string(slab.last) + " need " +
                    std::to_string(plane * slab.planes()));
  return scene.volume.data;
}

void attach_exchange(BrickedMarch& march, const DomainPart& part, DomainStats* stats) {
  check_domain_part(part);
  march.workers = part.ranks;
  if (part.ranks == 1) return;  // nothing to exchange
  auto exchange = std::make_shared<StateExchange>(march, part, stats);
  march.before_sweeps = [exchange] { exchange->keep(); };
  march.after_sweep = [exchange] { exchange->exchange(); };
}

Image render_domain(Device& device, const Scene& scene, const DomainPart& part,
                    const RenderOptions& options, RenderStats* stats, DomainStats* domain) {
  check_domain_part(part);
  const Slab slab = part_slab(scene.volume.nz, part);
  if (part.march == SlabMarch::states) {
    const BrickPlan plan =
        plan_domain(device, scene, options.precision, options.volume_brick, false, slab);
    return render_bricked(device, scene, options, plan, stats, &part, domain);
  }
  // Independent segments: the endpoint schemes' first segment in a slab starts at a sample before
  // it, which the bricks' halo holds (fetched from the neighbours' planes).
  const int halo = brick_halo(scene, options.step != 0 ? options.step : scene.integrator.step);
  const BrickPlan plan =
      plan_domain(device, scene, options.precision, options.volume_brick, false, slab, halo);
  Scene held = description_of(scene);
  held.volume.data = halo ? with_neighbour_planes(part, slab, plan.layout, slab_values(scene, slab))
                          : slab_values(scene, slab);
  BrickedMarch march(device, held, options, plan, "render");
  check_brick_halo(held, march.s.integrator().step, plan.layout);
  const SegmentMarch segments(march, held, part, domain);
  bricked_render_stats(march, plan, stats);
  if (stats) stats->samples = segments.samples();
  return segments.image();
}

Gradient gradient_domain(Device& device, const Scene& scene, const Image& target,
                         const DomainPart& part, const GradientOptions& options,
                         DomainStats* domain, const std::vector<std::string>& groups) {
  return gradient_domain_values(device, scene, target, part, options, domain, groups, nullptr);
}

Gradient gradient_domain_values(Device& device, const Scene& scene, const Image& target,
                                const DomainPart& part, const GradientOptions& options,
                                DomainStats* domain, const std::vector<std::string>& groups,
                                const std::vector<double>* densities) {
  check_domain_part(part);
  if (densities && densities->size() != scene.volume.data.size())
    throw Error(Status::invalid_argument, "domain gradient: " + std::to_string(densities->size()) +
                                              " float64 densities for the slab's " +
                                              std::to_string(scene.volume.data.size()));
  const Slab slab = part_slab(scene.volume.nz, part);
  // The endpoint schemes' bricks hold a halo (brick_halo): at the slab's ends, planes of the
  // neighbours' slabs, fetched first; what the halo's voxels gather is sent back after.
  const int halo = brick_halo(scene, options.step != 0 ? options.step : scene.integrator.step,
                              options.deterministic);
  const BrickPlan plan = plan_domain(device, scene, options.precision, 0, true, slab, halo);
  if (!halo)
    return gradient_bricked(device, scene, target, groups, options, plan, &part, domain, densities);
  slab_values(scene, slab);
  Scene held = description_of(scene);
  std::vector<double> held_f64;
  if (densities) {  // (the floats checked and passed along are these, rounded)
    held_f64 = with_neighbour_planes(part, slab, plan.layout, *densities);
    held.volume.data.assign(held_f64.begin(), held_f64.end());
  } else {
    held.volume.data = with_neighbour_planes(part, slab, plan.layout, scene.volume.data);
  }
  Gradient g = gradient_bricked(device, held, target, groups, options, plan, &part, domain,
                                densities ? &held_f64 : nullptr);
  for (GroupGradient& group : g.groups)
    if (group.name == "density") {
      group.values = return_halo(part, slab, plan.layout, group.values);
      group.shape[0] = std::size_t(slab.planes());
    }
  return g;
}

namespace {
// The volume from every worker's slab values: the planes neighbours share summed (a gradient's
// parts) or taken from the lower worker (the same values on both).
std::vector<double> join_slabs(int nx, int ny, int nz,
                               const std::vector<std::vector<double>>& slabs, bool sum,
                               const char* what) {
  const std::size_t plane = std::size_t(nx) * ny;
  if (plane == 0 || nz < 2 || slabs.empty() || int(slabs.size()) > nz - 1)
    throw Error(Status::invalid_argument, std::string(what) + ": " +
                                              std::to_string(slabs.size()) +
                                              " slabs of a volume of " + std::to_string(nx) + "×" +
                                              std::to_string(ny) + "×" + std::to_string(nz));
  std::vector<double> out(plane * nz, 0.0);
  int first = 0;  // each slab's first plane: the one before it ends on (equal or weighted slabs)
  for (int r = 0; r < int(slabs.size()); ++r) {
    const std::size_t planes = slabs[r].size() / plane;
    const bool last = r + 1 == int(slabs.size());
    // (planes from this slab's first on; a slab before the last leaves the next two at least)
    const std::size_t left = std::size_t(nz - first);
    if (slabs[r].size() % plane || planes < 2 || (last ? planes != left : planes + 1 > left))
      throw Error(Status::invalid_argument,
                  std::string(what) + ": worker " + std::to_string(r) + "'s slab has " +
                      std::to_string(slabs[r].size()) + " values; from plane " +
                      std::to_string(first) + " it needs " +
                      (last ? std::to_string(left) + " planes of " + std::to_string(plane) +
                                  " values (to the last, " + std::to_string(nz - 1) + ")"
                            : "2 to " + std::to_string(left - 1) + " whole planes of " +
                                  std::to_string(plane) + " values (the slabs after it 2 at least)"));
    const Slab s{first, first + int(planes) - 1};
    first = s.last;
    double* at = out.data() + plane * s.first;
    const std::size_t from = !sum && r > 0 ? plane : 0;
    for (std::size_t i = from; i < slabs[r].size(); ++i)
      at[i] = sum ? at[i] + slabs[r][i] : slabs[r][i];
  }
  return out;
}
}  // namespace

std::vector<double> domain_join(int nx, int ny, int nz,
                                const std::vector<std::vector<double>>& slabs) {
  return join_slabs(nx, ny, nz, slabs, true, "domain_join");
}

std::vector<double> domain_assemble(int nx, int ny, int nz,
                                    const std::vector<std::vector<double>>& slabs) {
  return join_slabs(nx, ny, nz, slabs, false, "domain_assemble");
}

}  // namespace ivr
