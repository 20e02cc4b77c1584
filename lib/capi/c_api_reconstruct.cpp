// c_api_reconstruct.cpp — the C API's inverse rendering (include/ivr/ivr.h): reconstruction
// handles over ivr::Reconstruction, viewpoint selection, image entropy and PSNR.
#include <algorithm>
#include <chrono>
#include <climits>
#include <functional>

#include "capi/c_api_handles.hpp"
#include "capi/options.hpp"
#include "ivr/domain.hpp"
#include "reconstruct/reconstruct_params.hpp"

using namespace ivr::capi;

// A reconstruction and the context whose device it runs on (held by reference until release).
struct ivr_reconstruction {
  std::atomic<int> references{1};
  ivr_context* context = nullptr;
  std::unique_ptr<ivr::Reconstruction> reconstruction;
  bool explicit_box = false;  // of the source scene: handed on to result scenes
  ivr::Volume grid;           // the full grid's dims (no data): shapes without a read-back
};

namespace {

template <class R>
R* checked_reconstruction(R* r) {
  return checked(r, Kind::reconstruction, "reconstruction");
}

ivr_context* context_of_reconstruction(const ivr_reconstruction* r) {
  return r && is_live(r, Kind::reconstruction) ? r->context : nullptr;
}

[[noreturn]] void bad(const std::string& message) {
  throw CError{IVR_ERROR_INVALID_ARGUMENT, message};
}

ivr_optimizer optimizer_enum(ivr::OptimizerKind k) {
  return k == ivr::OptimizerKind::sgd     ? IVR_OPTIMIZER_SGD
         : k == ivr::OptimizerKind::lbfgs ? IVR_OPTIMIZER_LBFGS
                                          : IVR_OPTIMIZER_ADAM;
}

ivr_reconstruct_iteration record_of(const ivr::IterationRecord& r) {
  return {r.iteration, r.level, r.loss, r.prior, r.lr, r.seconds, r.views};
}

ivr_camera camera_of(const ivr::Camera& c) {
  ivr_camera out;
  for (int i = 0; i < 3; ++i) {
    out.eye[i] = c.eye[i];
    out.target[i] = c.target[i];
    out.up[i] = c.up[i];
  }
  out.fov_y = c.fov_y;
  out.orthographic = c.projection == ivr::Projection::orthographic ? 1 : 0;
  out.ortho_height = c.ortho_height;
  out.width = c.width;
  out.height = c.height;
  return out;
}

// The reconstruction of `s` from `targets` with options `o` (its workers set).
ivr_reconstruction* create_reconstruction(ivr_context* c, const ivr_scene* s, const float* targets,
                                          size_t count, const ivr::ReconstructOptions& o) {
  checked(c, Kind::context, "context");
  with_volume(checked(s, Kind::scene, "scene"), o.slabs);
  same_context(s->context, c, "scene");
  not_null(targets, "targets");
  // Over slabs this worker's planes of the densities (the grid its volume calls return).
  const ivr::Scene scene = o.slabs ? split_scene(s, o.worker, o.workers, o.shares) : s->scene;
  const ivr::ImageExtent cam = ivr::image_extent(scene);
  ivr::Image t{cam.views, cam.height, cam.width, scene.channels(), {}};
  const size_t want = size_t(t.views) * size_t(t.height) * size_t(t.width) * size_t(t.channels);
  if (count != want)
    bad("targets has " + std::to_string(count) + " floats; the scene renders " +
        std::to_string(want) + " (" + std::to_string(t.views) + " views of " +
        std::to_string(t.height) + " x " + std::to_string(t.width) + " x " +
        std::to_string(t.channels) + ")");
  t.pixels.assign(targets, targets + count);
  auto r = std::make_unique<ivr_reconstruction>();
  r->reconstruction = std::make_unique<ivr::Reconstruction>(c->device, scene, t, o);
  r->explicit_box = s->explicit_box;
  r->grid.nx = scene.volume.nx;
  r->grid.ny = scene.volume.ny;
  r->grid.nz = scene.volume.nz;
  return publish(std::move(r), c, Kind::reconstruction);
}

// A reconstruction as worker `worker` of `workers` (the shared, split and weighted entry points;
// `name` the one called, for its errors).
ivr_status create_workers(const char* name, ivr_context* c, const ivr_scene* s,
                          const float* targets, size_t count,
                          const ivr_reconstruct_options* options, ivr_split split, int worker,
                          int workers, const double* shares, ivr_sum_fn sum, void* sum_user,
                          ivr_reconstruction** out) {
  return guarded(c, name, [&] {
    not_null(out, "reconstruction");
    *out = nullptr;
    if (!sum) throw CError{IVR_ERROR_NULL_POINTER, "sum is NULL"};
    if (split != IVR_SPLIT_VIEWS && split != IVR_SPLIT_SLABS && split != IVR_SPLIT_SEGMENTS)
      bad("split " + std::to_string(int(split)) +
          " (IVR_SPLIT_VIEWS, IVR_SPLIT_SLABS or IVR_SPLIT_SEGMENTS)");
    ivr::ReconstructOptions o = core_options(options);
    o.worker = worker, o.workers = workers;  // (their range: checked by the core, named)
    o.sum = sum_of(sum, sum_user);
    o.slabs = split != IVR_SPLIT_VIEWS;
    if (split == IVR_SPLIT_SEGMENTS) o.slab_march = ivr::SlabMarch::segments;
    // (checked by the core; over slabs they cut the slabs, over views the batches)
    if (shares && workers > 0) o.shares.assign(shares, shares + workers);
    *out = create_reconstruction(c, s, targets, count, o);
  });
}
}  // namespace

extern "C" {

ivr_status ivr_reconstruct_options_init(ivr_reconstruct_options* o) {
  return guarded(nullptr, "ivr_reconstruct_options_init",
                 [&] { *not_null(o, "options") = c_options(ivr::ReconstructOptions{}); });
}

ivr_status ivr_reconstruction_create(ivr_context* c, const ivr_scene* s, const float* targets,
                                     size_t count, const ivr_reconstruct_options* options,
                                     ivr_reconstruction** out) {
  return guarded(c, "ivr_reconstruction_create", [&] {
    not_null(out, "reconstruction");
    *out = nullptr;
    // Ranges: checked by ivr::validate_reconstruct, which names them.
    *out = create_reconstruction(c, s, targets, count, core_options(options));
  });
}

ivr_status ivr_reconstruction_create_shared(ivr_context* c, const ivr_scene* s,
                                            const float* targets, size_t count,
                                            const ivr_reconstruct_options* options, int worker,
                                            int workers, ivr_sum_fn sum, void* sum_user,
                                            ivr_reconstruction** out) {
  return create_workers("ivr_reconstruction_create_shared", c, s, targets, count, options,
                        IVR_SPLIT_VIEWS, worker, workers, nullptr, sum, sum_user, out);
}

ivr_status ivr_reconstruction_create_split(ivr_context* c, const ivr_scene* s,
                                           const float* targets, size_t count,
                                           const ivr_reconstruct_options* options, ivr_split split,
                                           int worker, int workers, ivr_sum_fn sum, void* sum_user,
                                           ivr_reconstruction** out) {
  return create_workers(split != IVR_SPLIT_VIEWS ? "ivr_reconstruction_create_split"
                                                 : "ivr_reconstruction_create_shared",
                        c, s, targets, count, options, split, worker, workers, nullptr, sum,
                        sum_user, out);
}

ivr_status ivr_reconstruction_create_weighted(ivr_context* c, const ivr_scene* s,
                                              const float* targets, size_t count,
                                              const ivr_reconstruct_options* options,
                                              ivr_split split, int worker, int workers,
                                              const double* shares, ivr_sum_fn sum,
                                              void* sum_user, ivr_reconstruction** out) {
  return create_workers("ivr_reconstruction_create_weighted", c, s, targets, count, options,
                        split, worker, workers, shares, sum, sum_user, out);
}

ivr_status ivr_reconstruction_retain(ivr_reconstruction* r) {
  return retain(r, Kind::reconstruction, "ivr_reconstruction_retain");
}

ivr_status ivr_reconstruction_release(ivr_reconstruction* r) {
  return release(r, Kind::reconstruction, "ivr_reconstruction_release");
}

ivr_status ivr_reconstruction_step(ivr_reconstruction* r, ivr_reconstruct_iteration* iteration) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_step", [&] {
    const ivr::IterationRecord& rec = checked_reconstruction(r)->reconstruction->step();
    if (iteration) *iteration = record_of(rec);
  });
}

ivr_status ivr_reconstruction_run(ivr_reconstruction* r, ivr_reconstruct_progress progress,
                                  void* user, ivr_reconstruct_summary* summary) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_run", [&] {
    ivr::Reconstruction& rec = *checked_reconstruction(r)->reconstruction;
    const auto start = std::chrono::steady_clock::now();
    int steps = 0;
    bool interrupted = false;
    double loss = rec.history().empty() ? 0.0 : rec.history().back().loss;
    while (!rec.done()) {
      const ivr_reconstruct_iteration entry = record_of(rec.step());
      ++steps;
      loss = entry.loss;
      if (progress && progress(&entry, user) == 0) {
        interrupted = !rec.done();
        break;
      }
    }
    if (summary) {
      summary->iterations = rec.iteration();
      summary->steps = steps;
      summary->stop_reason = interrupted ? "interrupted" : "done";
      summary->loss = steps > 0 ? loss : 0.0;
      summary->seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
  });
}

ivr_status ivr_reconstruction_done(const ivr_reconstruction* r, int* done) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_done", [&] {
    *not_null(done, "done") = checked_reconstruction(r)->reconstruction->done() ? 1 : 0;
  });
}

ivr_status ivr_reconstruction_info(const ivr_reconstruction* r, ivr_reconstruct_info* info) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_info", [&] {
    const ivr::Reconstruction& rec = *checked_reconstruction(r)->reconstruction;
    not_null(info, "info");
    const ivr::ReconstructOptions& o = rec.options();
    info->iteration = rec.iteration();
    info->iterations = o.iterations;
    info->levels = rec.levels();
    info->optimizer = optimizer_enum(o.optimizer.kind);
    info->lr = o.optimizer.lr;
  });
}

ivr_status ivr_reconstruction_level_shape(const ivr_reconstruction* r, int level,
                                          int64_t shape[3]) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_level_shape", [&] {
    const ivr::Reconstruction& rec = *checked_reconstruction(r)->reconstruction;
    not_null(shape, "shape");
    if (level < 0 || level >= rec.levels())
      bad("level " + std::to_string(level) + " does not exist (the reconstruction has " +
          std::to_string(rec.levels()) + ")");
    const std::vector<int> d = rec.level_dims(level);  // (nx, ny, nz)
    shape[0] = d[2];
    shape[1] = d[1];
    shape[2] = d[0];
  });
}

ivr_status ivr_reconstruction_history(const ivr_reconstruction* r,
                                      ivr_reconstruct_iteration* history, size_t capacity,
                                      size_t* count) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_history", [&] {
    const std::vector<ivr::IterationRecord>& h =
        checked_reconstruction(r)->reconstruction->history();
    if (count) *count = h.size();
    if (!history && capacity == 0) return;
    not_null(history, "history");
    for (size_t i = 0; i < h.size() && i < capacity; ++i) history[i] = record_of(h[i]);
  });
}

ivr_status ivr_reconstruction_volume(const ivr_reconstruction* r, float* volume, size_t capacity,
                                     int64_t shape[3]) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_volume", [&] {
    const ivr::Reconstruction& rec = *checked_reconstruction(r)->reconstruction;
    const bool slabs = rec.options().slabs;
    if (!volume && capacity == 0 && !slabs) {  // the shape only: no read-back from the device
      write_shape(r->grid, not_null(shape, "shape"));
      return;
    }
    ivr::Volume v = rec.result().volume;
    if (slabs) v.nz = int(v.data.size() / (size_t(v.nx) * size_t(v.ny)));  // (the level's planes)
    if (!volume && capacity == 0) return write_shape(v, not_null(shape, "shape"));
    not_null(volume, "volume");
    if (capacity < v.data.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "volume holds " + std::to_string(capacity) +
                                                   " floats; the grid has " +
                                                   std::to_string(v.data.size()) + " voxels"};
    std::copy(v.data.begin(), v.data.end(), volume);
    if (shape) write_shape(v, shape);
  });
}

ivr_status ivr_reconstruction_tf(const ivr_reconstruction* r, double* values, size_t capacity,
                                 int64_t shape[2]) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_tf", [&] {
    const ivr::Reconstruction& rec = *checked_reconstruction(r)->reconstruction;
    const ivr::TransferFunction tf = rec.result().tf;
    const std::vector<std::size_t> dims = ivr::tf_gradient_shape(tf);
    const std::vector<double> v = ivr::tf_parameters(tf);
    if (shape) {
      shape[0] = int64_t(dims[0]);
      shape[1] = int64_t(dims[1]);
    }
    if (!values && capacity == 0) {
      not_null(shape, "shape");
      return;
    }
    not_null(values, "values");
    if (capacity < v.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "values hold " + std::to_string(capacity) +
                                                   " doubles; the TF has " +
                                                   std::to_string(v.size()) + " parameters"};
    std::copy(v.begin(), v.end(), values);
  });
}

ivr_status ivr_reconstruction_result_scene(const ivr_reconstruction* r, ivr_scene** out) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_result_scene", [&] {
    checked_reconstruction(r);
    not_null(out, "scene");
    *out = nullptr;
    auto s = std::make_unique<ivr_scene>();
    if (r->reconstruction->options().slabs)
      bad("over slabs the result scene would hold one slab: read ivr_reconstruction_volume and "
          "join the workers' planes");
    s->scene = r->reconstruction->result();
    s->explicit_box = r->explicit_box;
    *out = publish(std::move(s), r->context, Kind::scene);
  });
}

ivr_status ivr_reconstruction_save_checkpoint(const ivr_reconstruction* r, const char* prefix) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_save_checkpoint", [&] {
    checked_reconstruction(r);
    r->reconstruction->save_checkpoint(not_null(prefix, "prefix"));
  });
}

ivr_status ivr_reconstruction_resume(ivr_reconstruction* r, const char* prefix) {
  return guarded(context_of_reconstruction(r), "ivr_reconstruction_resume", [&] {
    checked_reconstruction(r);
    r->reconstruction->resume(not_null(prefix, "prefix"));
  });
}

ivr_status ivr_viewpoint_options_init(ivr_viewpoint_options* o) {
  return guarded(nullptr, "ivr_viewpoint_options_init",
                 [&] { *not_null(o, "options") = c_options(ivr::ViewpointOptions{}); });
}

ivr_status ivr_select_viewpoint(ivr_context* c, const ivr_scene* s,
                                const ivr_viewpoint_options* options,
                                ivr_viewpoint_progress progress, void* user,
                                ivr_viewpoint_step* history, size_t history_capacity,
                                ivr_viewpoint_result* result) {
  return guarded(c, "ivr_select_viewpoint", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(result, "result");
    const ivr::ViewpointOptions o = core_options(options);  // ranges: checked by the core
    // Checked before the search: a long run must not end in a buffer error.
    if (history && o.iterations >= 0 && history_capacity < size_t(o.iterations) + 1)
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "history holds " + std::to_string(history_capacity) +
                                                   " entries; options ask for up to " +
                                                   std::to_string(o.iterations + 1) +
                                                   " (the start and every iteration)"};
    std::function<bool(const ivr::ViewpointStep&)> callback;
    if (progress)
      callback = [&](const ivr::ViewpointStep& st) {
        const ivr_viewpoint_step entry{st.iteration, st.entropy, st.azimuth, st.elevation};
        return progress(&entry, user) != 0;
      };
    const ivr::Viewpoint v = ivr::select_viewpoint(c->device, s->scene, o, callback);
    if (history)
      for (size_t i = 0; i < v.history.size() && i < history_capacity; ++i) {
        const ivr::ViewpointStep& st = v.history[i];
        history[i] = {st.iteration, st.entropy, st.azimuth, st.elevation};
      }
    result->camera = camera_of(v.camera);
    result->entropy_start = v.history.empty() ? v.entropy : v.history.front().entropy;
    result->entropy_best = v.entropy;
    result->iterations = v.history.empty() ? 0 : int(v.history.size()) - 1;
  });
}

ivr_status ivr_image_entropy(const float* image, const int64_t shape[4], double background,
                             double* entropy) {
  return guarded(nullptr, "ivr_image_entropy", [&] {
    not_null(image, "image");
    not_null(shape, "shape");
    not_null(entropy, "entropy");
    for (int i = 0; i < 4; ++i)
      if (shape[i] < 1 || shape[i] > (int64_t(1) << 24))
        bad("shape[" + std::to_string(i) + "] = " + std::to_string(shape[i]) +
            " (each dimension 1 .. 2^24)");
    ivr::Image im{int(shape[0]), int(shape[1]), int(shape[2]), int(shape[3]), {}};
    im.pixels.assign(
        image, image + size_t(shape[0]) * size_t(shape[1]) * size_t(shape[2]) * size_t(shape[3]));
    *entropy = ivr::image_entropy(im, nullptr, background);
  });
}

ivr_status ivr_psnr(const float* image, const float* reference, size_t count, double* value) {
  return guarded(nullptr, "ivr_psnr", [&] {
    not_null(image, "image");
    not_null(reference, "reference");
    not_null(value, "value");
    if (count == 0 || count > size_t(INT_MAX))
      bad("count is " + std::to_string(count) + " (1 .. 2^31 - 1 values to compare)");
    const ivr::Image a{1, 1, int(count), 1, std::vector<float>(image, image + count)};
    const ivr::Image b{1, 1, int(count), 1, std::vector<float>(reference, reference + count)};
    *value = ivr::psnr(a, b);
  });
}

}  // extern "C"
