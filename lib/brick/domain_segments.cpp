// domain_segments.cpp — domain-parallel over independent segments: each worker's segments of the
// rays, exchanged once and composited in order along each ray; the adjoint's starts from them.
#include "brick/domain_segments.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

#include "brick/domain.hpp"
#include "ivr/error.hpp"
#include "runtime/real_args.hpp"

namespace ivr {

namespace {
// kernels/bricked_state.cl's places.
constexpr int kT = 0, kC = 1, kK = 4, kTau = 7, kKTau = 8, kTNext = 14, kTEnd = 24;
// The adjoint's carried sums (kernels/bricked_adjoint.cl, BS_ADJ_FLUSHED … BS_ADJ_GD).
constexpr int kAdjointFirst = 8, kAdjointLast = 13;
constexpr int kUSamples = 0, kUEnd = 1, kUNext = 2, kUFlags = 3;
constexpr std::uint32_t kDone = 1;
static_assert(kTEnd + 1 == kBrickStateReals, "the state's last real");

// A segment as sent: the ray, its samples, where its window starts, and its (T, r, g, b) or
// (τ, 0, 0, 0) — its radiance with the compensation the march carried folded in —, then its
// tangents where forward lanes are marched.
struct Entry {
  std::uint32_t ray, samples;
  double start, v[4];
};
constexpr std::size_t kEntryBytes = 8 + 5 * 8;

struct Piece {
  double start;
  int worker;
  double v[4];
  const unsigned char* tangents;  // (in the gathered bytes)
};
}  // namespace

SegmentMarch::SegmentMarch(BrickedMarch& march, const Scene& scene, const DomainPart& part,
                           DomainStats* stats, const SegmentTangents* tangents)
    : march_(march),
      scene_(scene),
      emission_(scene.model == Model::emission_absorption),
      rays_(march.rays()),
      tangents_(tangents) {
  check_domain_part(part);
  march_.segments = true;
  if (tangents_) {  // the render's BEGIN, then the tangent kernel's sweeps
    march_.begin();
    start_ = read();
    tangents_->sweep();
    tangent_end_ = download_reals(march_.s.dev, march_.s.f64, *tangents_->buffer,
                                  rays_ * std::size_t(tangents_->lanes * tangents_->sums));
  } else {
    march_.before_sweeps = [this] { start_ = read(); };
    march_.render();
    march_.before_sweeps = nullptr;
  }
  end_ = read();
  composite(part, stats);
}

SegmentMarch::States SegmentMarch::read() const {
  States out;
  Device::Impl& dev = march_.s.dev;
  out.reals = download_reals(dev, march_.s.f64, march_.state(), rays_ * kBrickStateReals);
  out.uints.resize(rays_ * kBrickStateUints);
  cl_call("reading the segments' states", [&] {
    dev.queue.enqueueReadBuffer(march_.state_u(), CL_TRUE, 0, out.uints.size() * 4,
                                out.uints.data());
  });
  return out;
}

void SegmentMarch::write(const States& states) {
  Device::Impl& dev = march_.s.dev;
  write_reals(dev, march_.s.f64, march_.state(), states.reals);
  cl_call("writing the segments' states", [&] {
    dev.queue.enqueueWriteBuffer(march_.state_u(), CL_TRUE, 0, states.uints.size() * 4,
                                 states.uints.data());
  });
}

void SegmentMarch::composite(const DomainPart& part, DomainStats* stats) {
  // Per ray the tangents' stride in the buffer, and what is sent of them (the used lanes').
  const std::size_t stride = tangents_ ? std::size_t(tangents_->lanes * tangents_->sums) : 0;
  const std::size_t extra = tangents_ ? std::size_t(tangents_->used * tangents_->sums) : 0;
  const std::size_t entry_bytes = kEntryBytes + extra * 8;
  // This worker's segments: the rays with a window in its slab.
  std::vector<unsigned char> mine;
  for (std::size_t i = 0; i < rays_; ++i) {
    if (start_.uints[i * kBrickStateUints + kUFlags] & kDone) continue;
    const double* s = &end_.reals[i * kBrickStateReals];
    Entry e{std::uint32_t(i), end_.uints[i * kBrickStateUints + kUSamples],
            start_.reals[i * kBrickStateReals + kTNext], {0, 0, 0, 0}};
    if (emission_) {
      e.v[0] = s[kT];
      for (int c = 0; c < 3; ++c) e.v[1 + c] = s[kC + c] - s[kK + c];  // (accumulate: sum − error)
    } else {
      e.v[0] = s[kTau] - s[kKTau];
    }
    const std::size_t at = mine.size();
    mine.resize(at + entry_bytes);
    std::memcpy(&mine[at], &e.ray, 4);
    std::memcpy(&mine[at + 4], &e.samples, 4);
    std::memcpy(&mine[at + 8], &e.start, 8);
    std::memcpy(&mine[at + 16], e.v, 32);
    if (extra) std::memcpy(&mine[at + kEntryBytes], &tangent_end_[i * stride], extra * 8);
  }
  const std::vector<std::vector<unsigned char>> all =
      part.ranks == 1 ? std::vector<std::vector<unsigned char>>{mine} : part.all_gather(mine);
  if (int(all.size()) != part.ranks)
    throw Error(Status::invalid_argument, "domain segments: all_gather gave " +
                                              std::to_string(all.size()) + " parts for " +
                                              std::to_string(part.ranks) + " workers");
  // Every worker's segments by ray (counted, then placed), each ray's in the order it meets them.
  std::vector<std::size_t> first(rays_ + 1, 0);
  for (int w = 0; w < part.ranks; ++w) {
    if (all[w].size() % entry_bytes)
      throw Error(Status::invalid_argument, "domain segments: worker " + std::to_string(w) +
                                                " sent " + std::to_string(all[w].size()) +
                                                " bytes, not whole segments");
    for (std::size_t at = 0; at < all[w].size(); at += entry_bytes) {
      std::uint32_t ray = 0;
      std::memcpy(&ray, &all[w][at], 4);
      if (ray >= rays_)
        throw Error(Status::invalid_argument,
                    "domain segments: worker " + std::to_string(w) + " sent ray " +
                        std::to_string(ray) + " of " + std::to_string(rays_) +
                        " (do the workers share one scene?)");
      ++first[ray + 1];
    }
    if (stats && w != part.rank) stats->received_bytes += all[w].size();
  }
  std::partial_sum(first.begin(), first.end(), first.begin());
  std::vector<Piece> pieces(first[rays_]);
  std::vector<std::size_t> fill(first.begin(), first.end() - 1);
  samples_ = 0;
  for (int w = 0; w < part.ranks; ++w)
    for (std::size_t at = 0; at < all[w].size(); at += entry_bytes) {
      std::uint32_t ray = 0, samples = 0;
      std::memcpy(&ray, &all[w][at], 4);
      std::memcpy(&samples, &all[w][at + 4], 4);
      Piece& p = pieces[fill[ray]++];
      p.worker = w;
      std::memcpy(&p.start, &all[w][at + 8], 8);
      std::memcpy(p.v, &all[w][at + 16], 32);
      p.tangents = &all[w][at + kEntryBytes];
      samples_ += samples;
    }
  total_.assign(rays_ * 4, 0.0);
  front_.assign(rays_ * 4, 0.0);
  tangent_total_.assign(rays_ * stride, 0.0);
  std::vector<double> segment(extra);
  for (std::size_t i = 0; i < rays_; ++i) {
    std::sort(pieces.begin() + std::ptrdiff_t(first[i]), pieces.begin() + std::ptrdiff_t(first[i + 1]),
              [](const Piece& a, const Piece& b) {
                return a.start < b.start || (a.start == b.start && a.worker < b.worker);
              });
    // Front to back: C = C₁ + T₁·C₂ + T₁T₂·C₃ + …, T = ΠTₖ (absorption: the depths add).
    double v[4] = {emission_ ? 1.0 : 0.0, 0, 0, 0};
    for (std::size_t k = first[i]; k < first[i + 1]; ++k) {
      const Piece& p = pieces[k];
      if (k > first[i] && p.start == pieces[k - 1].start)
        throw Error(Status::invalid_argument,
                    "domain segments: ray " + std::to_string(i) + " has segments from workers " +
                        std::to_string(pieces[k - 1].worker) + " and " + std::to_string(p.worker) +
                        " that start alike (do the workers share one scene?)");
      if (p.worker == part.rank) std::copy(v, v + 4, &front_[i * 4]);
      if (extra) {  // the tangents first: they take the front's T and C as they were
        std::memcpy(segment.data(), p.tangents, extra * 8);
        double* d = &tangent_total_[i * stride];
        if (emission_) {
          for (int l = 0; l < tangents_->used; ++l) {
            double* q = d + l * 4;  // (dT, dr, dg, db) in front; the segment's after it
            const double* g = &segment[std::size_t(l) * 4];
            for (int c = 1; c < 4; ++c) q[c] += q[0] * p.v[c] + v[0] * g[c];
            q[0] = q[0] * p.v[0] + v[0] * g[0];
          }
        } else {
          for (std::size_t k2 = 0; k2 < extra; ++k2) d[k2] += segment[k2];  // (dτ)
        }
      }
      if (emission_) {
        for (int c = 1; c < 4; ++c) v[c] += v[0] * p.v[c];
        v[0] *= p.v[0];
      } else {
        v[0] += p.v[0];
      }
    }
    std::copy(v, v + 4, &total_[i * 4]);
  }
  if (stats && part.ranks > 1) ++stats->exchanges, stats->sent_bytes += mine.size();
}

Image SegmentMarch::image() const {
  const std::vector<std::int64_t> shape = march_.image.shape();
  // (A ray list's (rays, channels) is one view of one row, as image_of() has it.)
  Image out = shape.size() == 2
                  ? Image{1, 1, int(shape[0]), int(shape[1])}
                  : Image{int(shape[0]), int(shape[1]), int(shape[2]), int(shape[3])};
  const glm::dvec3 bg = scene_.effective_background();
  std::vector<double> values(rays_ * (emission_ ? 4 : 1));
  for (std::size_t i = 0; i < rays_; ++i) {
    const double* v = &total_[i * 4];
    if (emission_) {
      for (int c = 0; c < 3; ++c) values[i * 4 + c] = v[1 + c] + v[0] * bg[c];
      values[i * 4 + 3] = 1 - v[0];
    } else {
      values[i] = bg.x * std::exp(-v[0]);
    }
  }
  out.pixels.assign(values.begin(), values.end());
  if (march_.s.f64) out.pixels_f64 = std::move(values);
  return out;
}

void SegmentMarch::write_totals() {
  States s = end_;
  for (std::size_t i = 0; i < rays_; ++i) {
    double* r = &s.reals[i * kBrickStateReals];
    const double* v = &total_[i * 4];
    for (int c = 0; c < 3; ++c) r[kK + c] = 0;
    r[kKTau] = 0;
    if (emission_) {
      r[kT] = v[0];
      for (int c = 0; c < 3; ++c) r[kC + c] = v[1 + c];
    } else {
      r[kTau] = v[0];
    }
  }
  write(s);
}

void SegmentMarch::write_tangents() {
  if (!tangents_) return;
  write_reals(march_.s.dev, march_.s.f64, *tangents_->buffer, tangent_total_);
}

void SegmentMarch::seed_adjoint() {
  // The adjoint's BEGIN left each ray's pixel adjoint (from the totals) and restarted its march
  // at the ray's start; it starts at this worker's window instead, as SEGMENT_BEGIN left it.
  States s = start_;
  for (std::size_t i = 0; i < rays_; ++i) {
    double* r = &s.reals[i * kBrickStateReals];
    std::uint32_t* u = &s.uints[i * kBrickStateUints];
    const double* f = &front_[i * 4];
    // (the snapshot holds the forward march's values there: a segment's sums start at 0)
    for (int k = kAdjointFirst; k <= kAdjointLast; ++k) r[k] = 0;
    if (emission_) {
      r[kT] = f[0];
      for (int c = 0; c < 3; ++c) r[kC + c] = f[1 + c];
    } else {
      r[kTau] = f[0];
      r[kT] = std::exp(-f[0]);
    }
    const std::uint32_t end = end_.uints[i * kBrickStateUints + kUEnd];
    u[kUSamples] = end;  // the adjoint march's end: where the forward segment ended
    if (!(u[kUFlags] & kDone) && !(end > u[kUNext])) u[kUFlags] |= kDone;
  }
  write(s);
}

}  // namespace ivr
