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
// Every worker's doubles, in rank order (one worker: its own).
std::vector<std::vector<double>> gathered(const DomainPart* domain,
                                          const std::vector<double>& mine) {
  if (!domain || domain->ranks <= 1) return {mine};
  return gather_doubles(*domain, mine, "the fixed-point density gradient's scale");
}

// The most segments one ray can have: the bricks it may cross along each axis (a line meets at
// most count_x + count_y + count_z − 2 cells of a grid), over slabs every worker's bricks along z.
std::size_t segments_per_ray(const BrickLayout& l, const DomainPart* domain) {
  const int ranks = domain ? domain->ranks : 1;
  const std::size_t z_bricks = std::size_t((std::max(l.dims[2] - 1, 1) + l.edge - 1) / l.edge) +
                               std::size_t(ranks);
  return std::size_t(l.count[0]) + std::size_t(l.count[1]) + z_bricks;
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
  // (A share: the batch's rays, the cap every share's segments must keep to.)
  const std::size_t rays = share ? share->rays : e.pixels();
  cap_exponent_ = fixed_cap_exponent(rays * segments_per_ray(layout, domain));
  if (exponent) {
    exponent_ = *exponent;
  } else {
    // The bound on one ray's Σ |contribution| from this worker's densities (its slab: its
    // segments' bound), the largest over the workers.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo, target_max = 0;
    if (densities)
      for (double v : *densities) lo = std::min(lo, v), hi = std::max(hi, v);
    else
      for (float v : scene.volume.data) lo = std::min(lo, double(v)), hi = std::max(hi, double(v));
    if (!(lo <= hi)) lo = hi = 0;
    for (float v : target.pixels) target_max = std::max(target_max, std::abs(double(v)));
    for (double v : target.pixels_f64) target_max = std::max(target_max, std::abs(v));
    // (A share: the batch's target and mean, every share the same bound.)
    if (share) target_max = share->target_max;
    const double mine = std::ldexp(
        ray_gradient_bound(scene, tf_extremes(scene.tf, lo, hi), target_max, loss,
                           share ? share->elements : rays * std::size_t(scene.channels())),
        fixed_bound_shift());
    double bound = 0;
    for (const std::vector<double>& b : gathered(domain, {mine})) bound = std::max(bound, b[0]);
    exponent_ = fixed_exponent_from_bound(bound, cap_exponent_);
  }
  header_ = {cl_long(exponent_), cl_long(1) << cap_exponent_, 0, 0, 0};
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
      for (int x = 0; x < ext[0]; ++x, ++at) row[x] += values[at];  // (bounded: the cap's rule)
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

std::vector<double> BrickedFixed::values(bool f64) const {
  std::vector<std::int64_t> sums = sums_;
  if (share_) share_->add(sums);  // (exact: the batch's integers, whatever the shares)
  std::vector<double> out(sums.size());
  for (std::size_t i = 0; i < sums.size(); ++i)
    out[i] = f64 ? std::ldexp(double(sums[i]), -exponent_)
                 : double(std::ldexp(float(sums[i]), -exponent_));
  return out;
}

}  // namespace ivr
