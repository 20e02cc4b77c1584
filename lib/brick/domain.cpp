// domain.cpp — domain-parallel render and density gradient: slabs, their plans, and the exchange
// of the rays' march states between workers.
#include "brick/domain.hpp"

#include <algorithm>
#include <cstring>
#include <memory>

#include "brick/bricked_gradient.hpp"
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

namespace {

// The exchange itself (attach_exchange): host copies of the states as the last exchange left them.
class StateExchange {
 public:
  StateExchange(BrickedMarch& march, const DomainPart& part, DomainStats* stats)
      : march_(march), part_(part), stats_(stats), rays_(march.rays()) {
    reals_bytes_ = march.state().getInfo<CL_MEM_SIZE>() / rays_;
    uints_bytes_ = march.state_u().getInfo<CL_MEM_SIZE>() / rays_;
    entry_ = 4 + reals_bytes_ + uints_bytes_;
  }

  void keep() { read(kept_reals_, kept_uints_); }

  void exchange() {
    std::vector<unsigned char> reals, uints;
    read(reals, uints);
    // The rays this worker moved, as (ray, reals, uints) entries.
    std::vector<unsigned char> mine;
    std::vector<int> mover(rays_, -1);
    for (std::size_t i = 0; i < rays_; ++i) {
      const std::size_t r = i * reals_bytes_, u = i * uints_bytes_;
      if (!std::memcmp(&reals[r], &kept_reals_[r], reals_bytes_) &&
          !std::memcmp(&uints[u], &kept_uints_[u], uints_bytes_))
        continue;
      mover[i] = part_.rank;
      const std::uint32_t ray = std::uint32_t(i);
      const std::size_t at = mine.size();
      mine.resize(at + entry_);
      std::memcpy(&mine[at], &ray, 4);
      std::memcpy(&mine[at + 4], &reals[r], reals_bytes_);
      std::memcpy(&mine[at + 4 + reals_bytes_], &uints[u], uints_bytes_);
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
        std::memcpy(&reals[ray * reals_bytes_], &from[at + 4], reals_bytes_);
        std::memcpy(&uints[ray * uints_bytes_], &from[at + 4 + reals_bytes_], uints_bytes_);
        others = true;
      }
      if (stats_) stats_->received_bytes += from.size();
    }
    if (others) write(reals, uints);
    kept_reals_.swap(reals);
    kept_uints_.swap(uints);
    if (stats_) ++stats_->exchanges, stats_->sent_bytes += mine.size();
  }

 private:
  void read(std::vector<unsigned char>& reals, std::vector<unsigned char>& uints) {
    reals.resize(rays_ * reals_bytes_);
    uints.resize(rays_ * uints_bytes_);
    cl::CommandQueue& q = march_.s.dev.queue;
    q.enqueueReadBuffer(march_.state(), CL_FALSE, 0, reals.size(), reals.data());
    q.enqueueReadBuffer(march_.state_u(), CL_TRUE, 0, uints.size(), uints.data());
  }
  void write(const std::vector<unsigned char>& reals, const std::vector<unsigned char>& uints) {
    cl::CommandQueue& q = march_.s.dev.queue;
    q.enqueueWriteBuffer(march_.state(), CL_FALSE, 0, reals.size(), reals.data());
    q.enqueueWriteBuffer(march_.state_u(), CL_TRUE, 0, uints.size(), uints.data());
  }

  BrickedMarch& march_;
  DomainPart part_;
  DomainStats* stats_;
  std::size_t rays_, reals_bytes_ = 0, uints_bytes_ = 0, entry_ = 0;
  std::vector<unsigned char> kept_reals_, kept_uints_;
};

}  // namespace

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

Scene domain_share(const Scene& scene, int rank, int ranks) {
  const Slab slab = domain_slab(scene.volume.nz, rank, ranks);
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
                      bool gradient, const Slab& slab) {
  Scene part = description_of(scene);
  part.volume.nz = slab.planes();
  BrickPlan plan = plan_render(device, part, precision, forced_edge, gradient);
  if (!plan.layout.edge) {  // the slab fits the device: one brick of it
    const int whole = std::max({scene.volume.nx - 1, scene.volume.ny - 1, slab.planes() - 1, 1});
    plan = plan_render(device, part, precision, whole, gradient);
  }
  plan.layout = brick_layout(scene.volume.nx, scene.volume.ny, scene.volume.nz, plan.layout.edge,
                             slab.first, slab.last);
  return plan;
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
  const Slab slab = domain_slab(scene.volume.nz, part.rank, part.ranks);
  const BrickPlan plan =
      plan_domain(device, scene, options.precision, options.volume_brick, false, slab);
  return render_bricked(device, scene, options, plan, stats, &part, domain);
}

Gradient gradient_domain(Device& device, const Scene& scene, const Image& target,
                         const DomainPart& part, const GradientOptions& options,
                         DomainStats* domain, const std::vector<std::string>& groups) {
  check_domain_part(part);
  const Slab slab = domain_slab(scene.volume.nz, part.rank, part.ranks);
  const BrickPlan plan = plan_domain(device, scene, options.precision, 0, true, slab);
  return gradient_bricked(device, scene, target, groups, options, plan, &part, domain);
}

namespace {
// The volume from every worker's slab values: the planes neighbours share summed (a gradient's
// parts) or taken from the lower worker (the same values on both).
std::vector<double> join_slabs(int nx, int ny, int nz,
                               const std::vector<std::vector<double>>& slabs, bool sum,
                               const char* what) {
  const std::size_t plane = std::size_t(nx) * ny;
  std::vector<double> out(plane * nz, 0.0);
  for (int r = 0; r < int(slabs.size()); ++r) {
    const Slab s = domain_slab(nz, r, int(slabs.size()));
    if (slabs[r].size() != plane * s.planes())
      throw Error(Status::invalid_argument, std::string(what) + ": worker " + std::to_string(r) +
                                                "'s slab has " + std::to_string(slabs[r].size()) +
                                                " values, planes " + std::to_string(s.first) +
                                                ".." + std::to_string(s.last) + " need " +
                                                std::to_string(plane * s.planes()));
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
