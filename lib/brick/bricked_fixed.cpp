// bricked_fixed.cpp — the out-of-core adjoint's fixed-point density gradient: its scale, the
// bricks' integer sums and their one conversion (lib/brick/bricked_fixed.hpp).
#include "brick/bricked_fixed.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "adjoint/adjoint_bound.hpp"
#include "brick/domain.hpp"
#include "ivr/error.hpp"

namespace ivr {

namespace {
// Two's complement addition without signed overflow: a pass over the cap (rerun, its sums
// dropped) may wrap.
std::int64_t wrapping_add(std::int64_t a, std::int64_t b) {
  return std::int64_t(std::uint64_t(a) + std::uint64_t(b));
}

// Every worker's doubles, in rank order (one worker: its own).
std::vector<std::vector<double>> gathered(const DomainPart* domain,
                                          const std::vector<double>& mine) {
  if (!domain || domain->ranks <= 1) return {mine};
  return gather_doubles(*domain, mine, "the fixed-point density gradient's scale");
}

// The parts a ray's Σ |contribution| is checked in: 1 where its march state carries the sum from
// brick to brick and slab to slab (kernels/bricked_adjoint.cl checks it at the ray's end, as in
// core); over independent segments each slab's segment is checked alone, and a ray has at most
// one a worker.
std::size_t checked_parts(const DomainPart* domain) {
  return domain && domain->march == SlabMarch::segments ? std::size_t(domain->ranks) : 1;
}

// Every worker's planes (BrickedFixed::WorkerPlanes), in rank order: its slab (domain_slab) and
// that slab with the layout's halo, as plan_domain holds it (every worker's layout has the halo).
std::vector<BrickedFixed::WorkerPlanes> worker_planes(const DomainPart& domain,
                                                      const BrickLayout& l) {
  std::vector<BrickedFixed::WorkerPlanes> out;
  const int nz = l.dims[2];
  for (int w = 0; w < domain.ranks; ++w) {
    const Slab s = domain_slab(nz, w, domain.ranks, domain.shares);
    out.push_back(
        {s.first, s.last, std::max(s.first - l.halo, 0), std::min(s.last + l.halo, nz - 1)});
  }
  return out;
}
}  // namespace

bool BrickedFixed::everywhere(const DomainPart* domain, bool mine) {
  bool all = true;
  for (const std::vector<double>& w : gathered(domain, {mine ? 1.0 : 0.0})) all = all && w[0] != 0;
  return all;
}

BrickedFixed::BrickedFixed(const Scene& scene, const BrickLayout& layout, const Image& target,
                           Loss loss, const std::vector<double>* densities,
                           const DomainPart* domain, const FixedShare* share,
                           const int* exponent)
    : domain_(domain), share_(share), sums_(layout.held(), 0) {
  const ImageExtent e = image_extent(scene);
  // The in-core cap (a share: the batch's rays, the cap every share's rays must keep to).
  const std::size_t rays = share ? share->rays : e.pixels();
  cap_exponent_ = fixed_cap_exponent(rays * checked_parts(domain));
  if (exponent) {
    exponent_ = *exponent;
  } else {
    // The in-core bound on one ray's Σ |contribution|: from the whole volume's range of
    // densities, gathered over the workers' slabs.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo, target_max = 0;
    if (densities)
      for (double v : *densities) lo = std::min(lo, v), hi = std::max(hi, v);
    else
      for (float v : scene.volume.data) lo = std::min(lo, double(v)), hi = std::max(hi, double(v));
    for (const std::vector<double>& w : gathered(domain, {lo, hi}))
      lo = std::min(lo, w[0]), hi = std::max(hi, w[1]);
    if (!(lo <= hi)) lo = hi = 0;
    for (float v : target.pixels) target_max = std::max(target_max, std::abs(double(v)));
    for (double v : target.pixels_f64) target_max = std::max(target_max, std::abs(v));
    // (A share: the batch's target and mean, every share the same bound.)
    if (share) target_max = share->target_max;
    const double bound = std::ldexp(
        ray_gradient_bound(scene, tf_extremes(scene.tf, lo, hi), target_max, loss,
                           share ? share->elements : rays * std::size_t(scene.channels())),
        fixed_bound_shift());
    exponent_ = fixed_exponent_from_bound(bound, cap_exponent_);
  }
  header_ = {cl_long(exponent_), cl_long(1) << cap_exponent_, 0, 0, 0};
  if (domain && domain->ranks > 1) planes_ = worker_planes(*domain, layout), layout_ = layout;
}

void BrickedFixed::add(const std::vector<unsigned char>& slot, const BrickLayout& l, int b) {
  const std::size_t voxels = l.voxels(b);
  if (slot.size() < (kHeader + voxels) * sizeof(std::int64_t))
    throw Error(Status::opencl, "a brick's fixed-point slot was read back short");
  std::int64_t header[kHeader];
  std::memcpy(header, slot.data(), sizeof header);
  float largest = 0, largest_ray = 0;  // (float bits in the longs' first 4 bytes: fixed_max)
  std::memcpy(&largest, &header[3], sizeof largest);
  std::memcpy(&largest_ray, &header[4], sizeof largest_ray);
  over_cap_ += header[2];
  nonfinite_ = nonfinite_ || !std::isfinite(largest) || !std::isfinite(largest_ray);
  largest_ = std::max(largest_, largest);
  largest_ray_ = std::max(largest_ray_, largest_ray);
  const std::int64_t* values =
      reinterpret_cast<const std::int64_t*>(slot.data()) + std::ptrdiff_t(kHeader);
  const std::array<int, 3> o = l.origin(b), ext = l.extent(b);
  std::size_t at = 0;
  for (int z = 0; z < ext[2]; ++z)
    for (int y = 0; y < ext[1]; ++y) {
      std::int64_t* row =
          sums_.data() +
          (std::size_t(o[2] - l.data_first + z) * std::size_t(l.dims[1]) + std::size_t(o[1] + y)) *
              std::size_t(l.dims[0]) +
          std::size_t(o[0]);
      for (int x = 0; x < ext[0]; ++x, ++at) row[x] = wrapping_add(row[x], values[at]);
    }
}

int BrickedFixed::next() const {
  // The counters and maxima of every worker: their total and largest, the same on each.
  std::int64_t over = 0;
  double largest = 0, largest_ray = 0;
  bool nonfinite = false;
  for (const std::vector<double>& w : gathered(domain_, {double(over_cap_), double(largest_),
                                                         double(largest_ray_),
                                                         nonfinite_ ? 1.0 : 0.0})) {
    over += std::int64_t(w[0]);
    largest = std::max(largest, w[1]);
    largest_ray = std::max(largest_ray, w[2]);
    nonfinite = nonfinite || w[3] != 0;
  }
  if (share_) {  // the batch's counters and maxima (a non-finite one travels as +inf)
    float big = nonfinite ? INFINITY : float(largest), big_ray = float(largest_ray);
    share_->agree(over, big, big_ray);
    nonfinite = !std::isfinite(big) || !std::isfinite(big_ray);
    largest = big, largest_ray = big_ray;
  }
  if (nonfinite)
    throw Error(Status::opencl,
                "the out-of-core fixed-point density gradient met a contribution that is not "
                "finite");
  return fixed_exponent_after(exponent_, over, largest, largest_ray, cap_exponent_);
}

std::vector<std::int64_t> BrickedFixed::owned_sums() const {
  std::vector<std::int64_t> sums = sums_;
  if (planes_.empty()) return sums;
  const BrickLayout& l = layout_;
  const std::size_t plane = std::size_t(l.dims[0]) * std::size_t(l.dims[1]);
  const int me = domain_->rank;
  auto holds = [&](int w, int z) {
    return planes_[w].data_first <= z && z <= planes_[w].data_last;
  };
  auto owner = [&](int z) {  // the highest worker whose slab has plane z
    for (int w = int(planes_.size()) - 1; w >= 0; --w)
      if (planes_[w].first <= z && z <= planes_[w].last) return w;
    return -1;
  };
  // The planes another worker holds too: their sums to everyone (each plane its z, then its sums).
  std::vector<unsigned char> mine;
  for (int z = l.data_first; z <= l.data_last; ++z) {
    bool shared = false;
    for (int w = 0; w < int(planes_.size()); ++w) shared = shared || (w != me && holds(w, z));
    if (!shared) continue;
    const std::int64_t head = z;
    const std::size_t at = mine.size();
    mine.resize(at + sizeof head + plane * sizeof(std::int64_t));
    std::memcpy(&mine[at], &head, sizeof head);
    std::memcpy(&mine[at + sizeof head], &sums_[std::size_t(z - l.data_first) * plane],
                plane * sizeof(std::int64_t));
  }
  const std::vector<std::vector<unsigned char>> all = domain_->all_gather(mine);
  if (int(all.size()) != domain_->ranks)
    throw Error(Status::invalid_argument,
                "the fixed-point density gradient's shared planes: all_gather gave " +
                    std::to_string(all.size()) + " parts for " + std::to_string(domain_->ranks) +
                    " workers");
  // A plane's owner takes every worker's integers for it (a shared plane's: the upper worker,
  // whose first plane it is, as the reconstruction's priors have it); the others give it 0 — so the
  // slabs' values, added where they overlap (domain_join, the halo sent back), are the one integer
  // sum converted once, as in core.
  for (int z = l.data_first; z <= l.data_last; ++z)
    if (owner(z) != me)
      std::fill_n(sums.begin() + std::ptrdiff_t(std::size_t(z - l.data_first) * plane), plane, 0);
  const std::size_t record = sizeof(std::int64_t) + plane * sizeof(std::int64_t);
  for (int w = 0; w < int(all.size()); ++w) {
    if (w == me) continue;
    if (all[w].size() % record != 0)
      throw Error(Status::invalid_argument,
                  "the fixed-point density gradient's shared planes: worker " + std::to_string(w) +
                      " sent " + std::to_string(all[w].size()) +
                      " bytes (do the workers share one scene?)");
    for (std::size_t at = 0; at < all[w].size(); at += record) {
      std::int64_t z = 0;
      std::memcpy(&z, &all[w][at], sizeof z);
      if (z < l.data_first || z > l.data_last || owner(int(z)) != me) continue;
      std::int64_t* row = &sums[std::size_t(z - l.data_first) * plane];
      for (std::size_t i = 0; i < plane; ++i) {
        std::int64_t v = 0;
        std::memcpy(&v, &all[w][at + sizeof z + i * sizeof v], sizeof v);
        row[i] = wrapping_add(row[i], v);
      }
    }
  }
  return sums;
}

std::vector<double> BrickedFixed::values(bool f64) const {
  std::vector<std::int64_t> sums = owned_sums();
  if (share_) share_->add(sums);  // (exact: the batch's integers, whatever the shares)
  std::vector<double> out(sums.size());
  for (std::size_t i = 0; i < sums.size(); ++i)
    out[i] = f64 ? std::ldexp(double(sums[i]), -exponent_)
                 : double(std::ldexp(float(sums[i]), -exponent_));
  return out;
}

}  // namespace ivr
