// c_api_handles.hpp — the C API's handle types and the machinery every entry point shares: the
// registry of live handles, the guarded wrapper that turns exceptions into a status and a message
// (per thread and per context), argument checks. Internal to lib/c_api*.cpp.
#pragma once
#include <atomic>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "ivr/core.hpp"
#include "ivr/domain.hpp"
#include "ivr/ivr.h"

// The handle types: each holds its reference count; all but contexts hold their context.
struct ivr_context {
  std::atomic<int> references{1};
  ivr::Device device;
  std::mutex error_mutex;  // sessions of one context may fail on several threads at once
  std::string last_error;
  explicit ivr_context(const std::string& selector) : device(selector) {}
};

struct ivr_scene {
  std::atomic<int> references{1};
  ivr_context* context;
  ivr::Scene scene;
  bool explicit_box = false;  // the JSON gave a box: kept when the volume is replaced
  bool has_volume = true;     // false until ivr_scene_set_volume for JSON without "volume"
  // ivr_scene_set_volume_slab(_weighted): the volume holds only worker slab_rank of slab_ranks'
  // planes, cut by the weights slab_shares (empty: equal slabs; slab_ranks 0: the whole volume).
  int slab_rank = 0, slab_ranks = 0;
  std::vector<double> slab_shares;
};

// A volume or transfer function of its own, copied into the scenes it is set on.
struct ivr_volume {
  std::atomic<int> references{1};
  ivr_context* context;
  ivr::Volume volume;
};

struct ivr_transfer_function {
  std::atomic<int> references{1};
  ivr_context* context;
  ivr::TransferFunction tf;
};

struct ivr_result {
  std::atomic<int> references{1};
  ivr_context* context;
  double loss = 0, seconds = 0;
  ivr_mode mode = IVR_MODE_ADJOINT;
  struct Array {
    std::string name;
    std::vector<int64_t> shape;
    std::vector<double> values;
  };
  std::vector<Array> arrays;
};

namespace ivr::capi {

enum class Kind { context, scene, result, volume, tf, reconstruction, session, array, optimizer };

// Live handles and their types: a released or foreign pointer is found out before use.
inline std::mutex registry_mutex;
inline std::unordered_map<const void*, Kind>& registry() {
  static std::unordered_map<const void*, Kind> live;
  return live;
}

inline void track(const void* p, Kind k) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry()[p] = k;
}
inline void untrack(const void* p) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry().erase(p);
}
inline bool is_live(const void* p, Kind k) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  const auto it = registry().find(p);
  return it != registry().end() && it->second == k;
}

inline thread_local std::string thread_error;
inline thread_local int thread_opencl_error = 0;

// An error of the C layer itself (bad handle, null pointer, …).
struct CError {
  ivr_status status;
  std::string message;
};

// Worker `rank` of `ranks` of a split operation must exist.
inline void check_worker(int rank, int ranks) {
  if (ranks < 1 || rank < 0 || rank >= ranks)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "worker " + std::to_string(rank) + " of " + std::to_string(ranks) + " workers"};
}

// The caller's sum of a split operation (ivr_sum_fn) as the C++ API takes it; its failure is an
// error naming it.
inline std::function<void(std::vector<double>&)> sum_of(ivr_sum_fn sum, void* user) {
  return [sum, user](std::vector<double>& v) {
    if (!sum(v.data(), v.size(), user))
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "the workers' sum (ivr_sum_fn) failed"};
  };
}

inline const char* kind_name(Kind k) {
  switch (k) {
    case Kind::context:
      return "context";
    case Kind::scene:
      return "scene";
    case Kind::result:
      return "result";
    case Kind::volume:
      return "volume";
    case Kind::tf:
      return "transfer_function";
    case Kind::reconstruction:
      return "reconstruction";
    case Kind::session:
      return "session";
    case Kind::array:
      return "array";
    case Kind::optimizer:
      return "density_optimizer";
  }
  return "handle";
}

template <class T>
inline T* checked(T* p, Kind k, const char* what) {
  if (!p) throw CError{IVR_ERROR_NULL_POINTER, std::string(what) + " is NULL"};
  if (!is_live(p, k))
    throw CError{IVR_ERROR_INVALID_HANDLE,
                 std::string(what) + " is not a live ivr_" + kind_name(k) + " (released?)"};
  return p;
}

template <class T>
inline T* not_null(T* p, const char* what) {
  if (!p) throw CError{IVR_ERROR_NULL_POINTER, std::string(what) + " is NULL"};
  return p;
}

inline void same_context(const ivr_context* a, const ivr_context* b, const char* what) {
  if (a != b)
    throw CError{IVR_ERROR_WRONG_CONTEXT, std::string(what) + " belongs to another context"};
}

inline ivr_status status_of(ivr::Status s) {
  return static_cast<ivr_status>(static_cast<int>(s));  // the same numbers 0..7
}

// Records an error for this thread and, when known, for the context.
inline ivr_status fail(ivr_context* context, ivr_status status, const std::string& message,
                       int opencl = 0) {
  thread_error = message;
  thread_opencl_error = opencl;
  if (context && is_live(context, Kind::context)) {
    std::lock_guard<std::mutex> lock(context->error_mutex);
    context->last_error = message;
  }
  return status;
}

template <class F>
inline ivr_status guarded(ivr_context* context, const char* function, F&& body) {
  try {
    thread_error.clear();
    thread_opencl_error = 0;
    body();
    return IVR_OK;
  } catch (const CError& e) {
    return fail(context, e.status, std::string(function) + ": " + e.message);
  } catch (const ivr::Error& e) {
    return fail(context, status_of(e.status()), std::string(function) + ": " + e.what(),
                e.opencl_code());
  } catch (const std::bad_alloc&) {
    return fail(context, IVR_ERROR_OUT_OF_MEMORY, std::string(function) + ": out of host memory");
  } catch (const std::exception& e) {
    return fail(context, IVR_ERROR_INTERNAL, std::string(function) + ": " + e.what());
  } catch (...) {
    return fail(context, IVR_ERROR_INTERNAL, std::string(function) + ": unknown exception");
  }
}

// The context of a handle, for error reporting, without trusting the handle.
inline ivr_context* context_of(const ivr_scene* s) {
  return s && is_live(s, Kind::scene) ? s->context : nullptr;
}
inline ivr_context* context_of(const ivr_volume* v) {
  return v && is_live(v, Kind::volume) ? v->context : nullptr;
}
inline ivr_context* context_of(const ivr_transfer_function* t) {
  return t && is_live(t, Kind::tf) ? t->context : nullptr;
}
inline ivr_context* context_of(const ivr_result* r) {
  return r && is_live(r, Kind::result) ? r->context : nullptr;
}
inline ivr_context* context_of(
    const ivr_context* c) {  // the error record is not the context's state
  return c && is_live(c, Kind::context) ? const_cast<ivr_context*>(c) : nullptr;
}

inline ivr::Precision precision_of(ivr_precision p) {
  if (p != IVR_PRECISION_F32 && p != IVR_PRECISION_F64)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown precision " + std::to_string(int(p))};
  return p == IVR_PRECISION_F64 ? ivr::Precision::f64 : ivr::Precision::f32;
}

inline ivr::Mode mode_of(ivr_mode m) {
  if (m != IVR_MODE_AUTO && m != IVR_MODE_FORWARD && m != IVR_MODE_ADJOINT)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown mode " + std::to_string(int(m))};
  return m == IVR_MODE_FORWARD ? ivr::Mode::forward
         : m == IVR_MODE_ADJOINT ? ivr::Mode::adjoint
                                 : ivr::Mode::automatic;
}

inline ivr::Loss loss_of(ivr_loss l) {
  if (l != IVR_LOSS_MSE && l != IVR_LOSS_L1 && l != IVR_LOSS_DOT)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown loss " + std::to_string(int(l))};
  return ivr::Loss(int(l));  // the same numbers (ivr::Loss's order: mse, l1, dot)
}

template <class Handle>
inline ivr_status release(Handle* h, Kind k, const char* function) {
  return guarded(nullptr, function, [&] {
    checked(h, k, "the handle");
    if (h->references.fetch_sub(1) == 1) {
      untrack(h);
      // The handle first: what it owns (device buffers) must go before its device does.
      if constexpr (!std::is_same_v<Handle, ivr_context>) {
        ivr_context* context = h->context;
        delete h;
        ivr_context_release(context);
      } else {
        delete h;
      }
    }
  });
}

template <class Handle>
inline ivr_status retain(Handle* h, Kind k, const char* function) {
  return guarded(nullptr, function, [&] { checked(h, k, "the handle")->references.fetch_add(1); });
}

// A copy of caller memory as densities: floats as they are, integers mapped to [0, 1].
inline ivr::Volume volume_from_memory(const void* data, ivr_dtype dtype, const int64_t shape[3]) {
  not_null(data, "data");
  not_null(shape, "shape");
  for (int i = 0; i < 3; ++i)
    if (shape[i] < 1 || shape[i] > (int64_t(1) << 20))
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "shape[" + std::to_string(i) +
                                                   "] = " + std::to_string(shape[i]) +
                                                   " (each dimension 1 .. 2^20)"};
  ivr::Volume v;
  v.nz = int(shape[0]);
  v.ny = int(shape[1]);
  v.nx = int(shape[2]);
  const size_t n = v.voxel_count();
  v.data.resize(n);
  switch (dtype) {
    case IVR_FLOAT32:
      std::memcpy(v.data.data(), data, n * sizeof(float));
      break;
    case IVR_FLOAT64:
      for (size_t i = 0; i < n; ++i) v.data[i] = float(static_cast<const double*>(data)[i]);
      break;
    case IVR_UINT8:
      for (size_t i = 0; i < n; ++i)
        v.data[i] = float(static_cast<const uint8_t*>(data)[i] / 255.0);
      break;
    case IVR_UINT16:
      for (size_t i = 0; i < n; ++i)
        v.data[i] = float(static_cast<const uint16_t*>(data)[i] / 65535.0);
      break;
    default:
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "unknown dtype " + std::to_string(int(dtype)) +
                                                   " (IVR_FLOAT32, IVR_FLOAT64, IVR_UINT8, "
                                                   "IVR_UINT16)"};
  }
  return v;
}

// The scene must have its volume before any march.
// The scene's volume whole (a slab's scene is refused: only its worker's split operations take it,
// through split_scene).
inline const ivr_scene* with_volume(const ivr_scene* s, bool slab_allowed = false) {
  if (!s->has_volume)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "the scene has no volume: its JSON has none and ivr_scene_set_volume was not "
                 "called"};
  if (s->slab_ranks > 0 && !slab_allowed)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "the scene holds only worker " + std::to_string(s->slab_rank) + " of " +
                     std::to_string(s->slab_ranks) +
                     "'s slab of its volume (ivr_scene_set_volume_slab): only that worker's "
                     "operations over slabs take it (ivr_render_split, ivr_gradient_split, "
                     "ivr_reconstruction_create_split)"};
  return s;
}

// The C API's slab weights (`ranks` of them, or none for NULL: equal slabs; each checked by the
// core).
inline std::vector<double> slab_weights(const double* shares, int ranks) {
  return shares && ranks > 0 ? std::vector<double>(shares, shares + ranks) : std::vector<double>{};
}

// Worker `rank` of `ranks` over slabs cut by `shares` (NULL: equal), marching as `split` says
// (states passed or independent segments), its collectives through the caller's sum.
inline ivr::DomainPart slab_part(ivr_split split, int rank, int ranks, const double* shares,
                                 ivr_sum_fn sum, void* user) {
  if (split != IVR_SPLIT_SLABS && split != IVR_SPLIT_SEGMENTS)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "split " + std::to_string(int(split)) +
                     " (IVR_SPLIT_SLABS or IVR_SPLIT_SEGMENTS; over views each worker renders its "
                     "own views: ivr_render, ivr_gradient_shared)"};
  if (!sum) throw CError{IVR_ERROR_NULL_POINTER, "sum is NULL"};
  check_worker(rank, ranks);
  ivr::DomainPart part;
  part.rank = rank, part.ranks = ranks;
  part.all_gather = ivr::all_gather_by_sum(rank, ranks, sum_of(sum, user));
  part.march = split == IVR_SPLIT_SEGMENTS ? ivr::SlabMarch::segments : ivr::SlabMarch::states;
  part.shares = slab_weights(shares, ranks);
  return part;
}

// Worker `rank` of `ranks`' part of the scene over slabs cut by `shares`: its planes cut from the
// whole volume, or the slab the scene holds (which must be this worker's, by the same shares).
inline ivr::Scene split_scene(const ivr_scene* s, int rank, int ranks,
                              const std::vector<double>& shares = {}) {
  with_volume(s, true);
  if (s->slab_ranks == 0) return ivr::domain_share(s->scene, rank, ranks, shares);
  if (s->slab_rank != rank || s->slab_ranks != ranks)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "the scene holds worker " + std::to_string(s->slab_rank) + " of " +
                     std::to_string(s->slab_ranks) + "'s slab, not worker " +
                     std::to_string(rank) + " of " + std::to_string(ranks) + "'s"};
  // Planes, not weights, must agree: weights in proportion cut the same slabs.
  const int nz = s->scene.volume.nz;
  const ivr::Slab held = ivr::domain_slab(nz, rank, ranks, s->slab_shares);
  const ivr::Slab wanted = ivr::domain_slab(nz, rank, ranks, shares);
  if (held.first != wanted.first || held.last != wanted.last)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "shares: worker " + std::to_string(rank) + "'s slab by these shares is planes " +
                     std::to_string(wanted.first) + ".." + std::to_string(wanted.last) +
                     "; the scene holds planes " + std::to_string(held.first) + ".." +
                     std::to_string(held.last) +
                     " (ivr_scene_set_volume_slab_weighted: pass the same shares)"};
  return s->scene;
}

// A volume's shape as the C API gives it: (nz, ny, nx).
inline void write_shape(const ivr::Volume& v, int64_t shape[3]) {
  shape[0] = v.nz;
  shape[1] = v.ny;
  shape[2] = v.nx;
}

// Hands a new handle to the caller: it holds a reference to its context and is live.
template <class Handle>
Handle* publish(std::unique_ptr<Handle> h, ivr_context* context, Kind k) {
  h->context = context;
  context->references.fetch_add(1);
  track(h.get(), k);
  return h.release();
}

inline ivr_result* new_result(ivr_context* context) {
  return publish(std::make_unique<ivr_result>(), context, Kind::result);
}

}  // namespace ivr::capi
