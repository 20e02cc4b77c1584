// c_api_tomo.cpp — the C API's absorption tomography (include/ivr/ivr.h): project, back-project,
// the solvers with a progress callback, intensities → line integrals, and the phantoms.
#include <algorithm>
#include <cmath>
#include <functional>

#include "capi/c_api_handles.hpp"
#include "capi/options.hpp"
#include "ivr/domain.hpp"

using namespace ivr::capi;

namespace {

// The scene's ray and voxel counts, as the projector counts them.
std::size_t ray_count(const ivr::Scene& s) {
  return ivr::image_extent(s).pixels();
}

// "<what> has 5 floats; the scene has 6144 rays": inputs need exactly, outputs at least `want`.
void check_count(size_t count, size_t want, const char* what, const char* owner, const char* noun) {
  if (count != want)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, std::string(what) + " has " + std::to_string(count) +
                                                 " floats; " + owner + " has " +
                                                 std::to_string(want) + " " + noun};
}

void check_capacity(size_t capacity, size_t want, const char* what, const char* owner,
                    const char* noun) {
  if (capacity < want)
    throw CError{IVR_ERROR_BUFFER_TOO_SMALL, std::string(what) + " holds " +
                                                 std::to_string(capacity) + " floats; " + owner +
                                                 " has " + std::to_string(want) + " " + noun};
}

// Caller floats as doubles; the first non-finite one is named by its index.
std::vector<double> finite_values(const float* p, size_t n, const char* what) {
  std::vector<double> v(p, p + n);
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i]))
      throw CError{IVR_ERROR_INVALID_ARGUMENT, std::string(what) + "[" + std::to_string(i) +
                                                   "] is not finite (" + std::to_string(v[i]) +
                                                   ")"};
  return v;
}

void copy_out(const std::vector<double>& from, float* to) {
  for (size_t i = 0; i < from.size(); ++i) to[i] = float(from[i]);
}

// The library-owned (static) text of a stop reason.
const char* static_reason(const std::string& reason) {
  for (const char* r : {"iterations", "tolerance", "converged", "interrupted"})
    if (reason == r) return r;
  return "unknown";
}

// The scene and context of a tomography call, checked.
const ivr_scene* checked_scene(ivr_context* c, const ivr_scene* s) {
  checked(c, Kind::context, "context");
  with_volume(checked(s, Kind::scene, "scene"));
  same_context(s->context, c, "scene");
  return s;
}

// What every tomography call checks and hands back: the scene, the lines, the options, the
// history's room, the progress callback; finish() copies the result out.
struct TomoCall {
  ivr::TomoOptions options;
  std::vector<double> lines;
  ivr::TomoProgress callback;

  TomoCall(ivr_context* c, const ivr_scene* s, const ivr_tomo_options* o, const float* p,
           size_t count, const float* volume, ivr_tomo_progress progress, void* user,
           const ivr_tomo_iteration* history, size_t history_capacity) {
    checked_scene(c, s);
    not_null(p, "lines");
    not_null(volume, "volume");
    options = core_options(o);  // ranges: checked by the solver
    check_count(count, ray_count(s->scene), "lines", "the scene", "rays");
    // Checked before the solve: a long run must not end in a buffer error.
    if (history && options.iterations > 0 && history_capacity < size_t(options.iterations))
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL,
                   "history holds " + std::to_string(history_capacity) + " entries; options " +
                       "ask for up to " + std::to_string(options.iterations) + " iterations"};
    lines = finite_values(p, count, "lines");
    if (progress)
      callback = [progress, user](const ivr::TomoIteration& it) {
        const ivr_tomo_iteration entry{it.iteration, it.residual, it.seconds};
        return progress(&entry, user) != 0;
      };
  }

  void finish(const ivr::TomoResult& r, float* volume, ivr_tomo_iteration* history,
              size_t history_capacity, ivr_tomo_summary* summary) const {
    std::copy(r.volume.begin(), r.volume.end(), volume);
    if (history)
      for (size_t i = 0; i < r.history.size() && i < history_capacity; ++i)
        history[i] = {r.history[i].iteration, r.history[i].residual, r.history[i].seconds};
    if (summary) {
      summary->iterations = int(r.history.size());
      summary->stop_reason = static_reason(r.stop_reason);
      summary->residual = r.history.empty() ? 0.0 : r.history.back().residual;
      summary->seconds = r.history.empty() ? 0.0 : r.history.back().seconds;
      summary->setup_seconds = r.setup_seconds;
    }
  }
};

// ivr_tomo_split(_weighted): worker `rank` of `ranks` over views or over slabs cut by `shares`.
void tomo_split(ivr_context* c, const ivr_scene* s, const ivr_tomo_options* options,
                ivr_split split, int rank, int ranks, const double* shares, ivr_sum_fn sum,
                void* sum_user, const float* lines, size_t count, float* volume, size_t capacity,
                ivr_tomo_progress progress, void* user, ivr_tomo_iteration* history,
                size_t history_capacity, ivr_tomo_summary* summary) {
  if (!sum) throw CError{IVR_ERROR_NULL_POINTER, "sum is NULL"};
  if (split != IVR_SPLIT_VIEWS && split != IVR_SPLIT_SLABS)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "split " + std::to_string(int(split)) +
                     " (IVR_SPLIT_VIEWS or IVR_SPLIT_SLABS; a line integral's slab parts add "
                     "in one sum already, so tomography has no IVR_SPLIT_SEGMENTS)"};
  check_worker(rank, ranks);
  if (split == IVR_SPLIT_VIEWS && shares)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "shares: over views each worker passes its own views (ivr_view_shares cuts "
                 "them); pass NULL"};
  const TomoCall call(c, s, options, lines, count, volume, progress, user, history,
                      history_capacity);
  const ivr::Scene& scene = s->scene;
  if (split == IVR_SPLIT_VIEWS) {
    check_capacity(capacity, scene.volume.voxel_count(), "volume", "the scene's grid", "voxels");
    call.finish(ivr::tomo_shared(c->device, scene, call.lines, call.options,
                                 sum_of(sum, sum_user), call.callback),
                volume, history, history_capacity, summary);
    return;
  }
  const ivr::DomainPart part = slab_part(IVR_SPLIT_SLABS, rank, ranks, shares, sum, sum_user);
  const ivr::Slab slab = ivr::domain_slab(scene.volume.nz, rank, ranks, part.shares);
  check_capacity(capacity, std::size_t(scene.volume.nx) * scene.volume.ny * slab.planes(),
                 "volume", "this worker's slab", "voxels");
  call.finish(ivr::tomo_domain(c->device, scene, call.lines, part, call.options, call.callback),
              volume, history, history_capacity, summary);
}

}  // namespace

extern "C" {

ivr_status ivr_project(ivr_context* c, const ivr_scene* s, ivr_precision precision,
                       const float* volume, size_t count, float* lines, size_t capacity) {
  return guarded(c, "ivr_project", [&] {
    checked_scene(c, s);
    not_null(lines, "lines");
    const ivr::Scene& scene = s->scene;
    check_capacity(capacity, ray_count(scene), "lines", "the scene", "rays");
    std::vector<double> v;
    if (volume) {
      check_count(count, scene.volume.voxel_count(), "volume", "the scene's grid", "voxels");
      v = finite_values(volume, count, "volume");
    } else {
      v.assign(scene.volume.data.begin(), scene.volume.data.end());
    }
    const ivr::Projector projector(c->device, scene, precision_of(precision));
    copy_out(projector.project(v), lines);
  });
}

ivr_status ivr_backproject(ivr_context* c, const ivr_scene* s, ivr_precision precision,
                           const float* lines, size_t count, float* volume, size_t capacity) {
  return guarded(c, "ivr_backproject", [&] {
    checked_scene(c, s);
    not_null(lines, "lines");
    not_null(volume, "volume");
    const ivr::Scene& scene = s->scene;
    check_count(count, ray_count(scene), "lines", "the scene", "rays");
    check_capacity(capacity, scene.volume.voxel_count(), "volume", "the scene's grid", "voxels");
    const std::vector<double> p = finite_values(lines, count, "lines");
    const ivr::Projector projector(c->device, scene, precision_of(precision));
    copy_out(projector.backproject(p), volume);
  });
}

ivr_status ivr_tomo_options_init(ivr_tomo_options* o) {
  return guarded(nullptr, "ivr_tomo_options_init",
                 [&] { *not_null(o, "options") = c_options(ivr::TomoOptions{}); });
}

ivr_status ivr_tomo(ivr_context* c, const ivr_scene* s, const ivr_tomo_options* options,
                    const float* lines, size_t count, float* volume, size_t capacity,
                    ivr_tomo_progress progress, void* user, ivr_tomo_iteration* history,
                    size_t history_capacity, ivr_tomo_summary* summary) {
  return guarded(c, "ivr_tomo", [&] {
    const TomoCall call(c, s, options, lines, count, volume, progress, user, history,
                        history_capacity);
    check_capacity(capacity, s->scene.volume.voxel_count(), "volume", "the scene's grid", "voxels");
    call.finish(ivr::tomo(c->device, s->scene, call.lines, call.options, call.callback), volume,
                history, history_capacity, summary);
  });
}

ivr_status ivr_tomo_split(ivr_context* c, const ivr_scene* s, const ivr_tomo_options* options,
                          ivr_split split, int rank, int ranks, ivr_sum_fn sum, void* sum_user,
                          const float* lines, size_t count, float* volume, size_t capacity,
                          ivr_tomo_progress progress, void* user, ivr_tomo_iteration* history,
                          size_t history_capacity, ivr_tomo_summary* summary) {
  return guarded(c, "ivr_tomo_split", [&] {
    tomo_split(c, s, options, split, rank, ranks, nullptr, sum, sum_user, lines, count, volume,
               capacity, progress, user, history, history_capacity, summary);
  });
}

ivr_status ivr_tomo_split_weighted(ivr_context* c, const ivr_scene* s,
                                   const ivr_tomo_options* options, ivr_split split, int rank,
                                   int ranks, const double* shares, ivr_sum_fn sum,
                                   void* sum_user, const float* lines, size_t count,
                                   float* volume, size_t capacity, ivr_tomo_progress progress,
                                   void* user, ivr_tomo_iteration* history,
                                   size_t history_capacity, ivr_tomo_summary* summary) {
  return guarded(c, "ivr_tomo_split_weighted", [&] {
    tomo_split(c, s, options, split, rank, ranks, shares, sum, sum_user, lines, count, volume,
               capacity, progress, user, history, history_capacity, summary);
  });
}

ivr_status ivr_domain_slab(int nz, int rank, int ranks, int* first, int* last) {
  return guarded(nullptr, "ivr_domain_slab", [&] {
    not_null(first, "first");
    not_null(last, "last");
    const ivr::Slab slab = ivr::domain_slab(nz, rank, ranks);
    *first = slab.first, *last = slab.last;
  });
}

ivr_status ivr_domain_slab_weighted(int nz, int rank, int ranks, const double* shares,
                                    int* first, int* last) {
  return guarded(nullptr, "ivr_domain_slab_weighted", [&] {
    not_null(first, "first");
    not_null(last, "last");
    const ivr::Slab slab = ivr::domain_slab(nz, rank, ranks, slab_weights(shares, ranks));
    *first = slab.first, *last = slab.last;
  });
}

ivr_status ivr_lines_from_intensities(const ivr_scene* s, const float* intensities, size_t count,
                                      double clamp, float* lines, size_t capacity) {
  return guarded(context_of(s), "ivr_lines_from_intensities", [&] {
    checked(s, Kind::scene, "scene");
    not_null(intensities, "intensities");
    not_null(lines, "lines");
    check_count(count, ray_count(s->scene), "intensities", "the scene", "rays");
    check_capacity(capacity, count, "lines", "the scene", "rays");
    copy_out(ivr::lines_from_intensities(
                 s->scene, std::vector<double>(intensities, intensities + count), clamp),
             lines);
  });
}

ivr_status ivr_phantom(const char* name, int n, uint64_t seed, int supersample, float* volume,
                       size_t capacity) {
  return guarded(nullptr, "ivr_phantom", [&] {
    not_null(name, "name");
    not_null(volume, "volume");
    if (n < 1 || n > 1024)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "n = " + std::to_string(n) + " (1 .. 1024)"};
    check_capacity(capacity, size_t(n) * size_t(n) * size_t(n), "volume", "the phantom", "voxels");
    const ivr::Volume v = ivr::phantom(name, n, seed, supersample);
    std::copy(v.data.begin(), v.data.end(), volume);
  });
}

}  // extern "C"
