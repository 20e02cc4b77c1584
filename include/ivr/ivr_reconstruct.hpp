// ivr/ivr_reconstruct.hpp — the C++ API's inverse rendering (part of ivr/ivr.hpp, which includes
// it): a reconstruction handle, viewpoint selection, image entropy and PSNR, over the C API.
#pragma once
#include <memory>

#include "ivr/ivr.hpp"

namespace ivr::api {

// What a Reconstruction optimises and how: ivr_reconstruct_options (its fields are documented
// in ivr.h) filled with the library's defaults.
struct ReconstructOptions : ivr_reconstruct_options {
  ReconstructOptions() : ivr_reconstruct_options() {
    detail::check(ivr_reconstruct_options_init(this));
  }
};

// Called after every iteration of Reconstruction::run; return false to stop.
using ReconstructProgress = std::function<bool(const ivr_reconstruct_iteration&)>;
struct ReconstructSummary {
  int iterations = 0;       // completed in total
  int steps = 0;            // run by this call
  std::string stop_reason;  // "done" or "interrupted"
  double loss = 0, seconds = 0;
};

namespace detail {
// Carries a C++ callback through a C one; an exception it throws stops the C call and is
// rethrown once that has returned (none may cross the C boundary).
template <typename Entry>
struct Callback {
  const std::function<bool(const Entry&)>* function;
  std::exception_ptr error;
  static int call(const Entry* entry, void* user) {
    auto* self = static_cast<Callback*>(user);
    try {
      return (*self->function)(*entry) ? 1 : 0;
    } catch (...) {
      self->error = std::current_exception();
      return 0;
    }
  }
};
}  // namespace detail

// Densities, TF or both recovered from images of the scene's cameras, an iteration at a time.
// Keeps its context alive; one thread at a time, as the context.
class Reconstruction : public detail::Handle<ivr_reconstruction, ivr_reconstruction_retain,
                                             ivr_reconstruction_release> {
 public:
  using Handle::Handle;
  // `targets`: the scene's image shape (views, H, W, C) of finite values.
  Reconstruction(const Context& context, const Scene& scene, const std::vector<float>& targets,
                 const ReconstructOptions& options = {}) {
    detail::check(ivr_reconstruction_create(context.get(), scene.get(), targets.data(),
                                            targets.size(), &options, &handle_));
  }
  // Worker workers.rank of workers.ranks (ivr_reconstruction_create_weighted): over views
  // (workers.split IVR_SPLIT_VIEWS) sharing out each batch's views in proportion to
  // workers.shares; over slabs or segments holding its planes of the densities, cut by
  // workers.shares. Every step sums the loss and gradients over the workers through workers.sum,
  // which this object (and its copies) keeps; what the sum throws is rethrown by the step that
  // called it.
  Reconstruction(const Context& context, const Scene& scene, const std::vector<float>& targets,
                 const ReconstructOptions& options, const Workers& workers)
      : sum_(std::make_shared<OwnedSum>(workers.sum)) {
    detail::check(ivr_reconstruction_create_weighted(
        context.get(), scene.get(), targets.data(), targets.size(), &options, workers.split,
        workers.rank, workers.ranks, workers.shares_or_null(),
        workers.sum ? &detail::Sum::call : nullptr, &sum_->state, &handle_));
  }
  // One iteration (throws once done()).
  ivr_reconstruct_iteration step() {
    ivr_reconstruct_iteration it{};
    const ivr_status status = ivr_reconstruction_step(get(), &it);
    rethrow_sum_error();
    detail::check(status);
    return it;
  }
  // Until done or until `progress` returns false.
  ReconstructSummary run(const ReconstructProgress& progress = {}) {
    detail::Callback<ivr_reconstruct_iteration> state{&progress, nullptr};
    ivr_reconstruct_summary s{};
    const ivr_status status = ivr_reconstruction_run(
        get(), progress ? &detail::Callback<ivr_reconstruct_iteration>::call : nullptr, &state, &s);
    if (state.error) std::rethrow_exception(state.error);
    rethrow_sum_error();
    detail::check(status);
    return {s.iterations, s.steps, s.stop_reason, s.loss, s.seconds};
  }
  bool done() const {
    int d = 0;
    detail::check(ivr_reconstruction_done(get(), &d));
    return d != 0;
  }
  // Completed and total iterations, levels, and the optimiser and lr that "automatic" chose.
  ivr_reconstruct_info info() const {
    ivr_reconstruct_info i{};
    detail::check(ivr_reconstruction_info(get(), &i));
    return i;
  }
  // (nz, ny, nx) of a coarse-to-fine level (0 = the coarsest).
  std::vector<int64_t> level_shape(int level) const {
    std::vector<int64_t> shape(3);
    detail::check(ivr_reconstruction_level_shape(get(), level, shape.data()));
    return shape;
  }
  std::vector<ivr_reconstruct_iteration> history() const {
    size_t count = 0;
    detail::check(ivr_reconstruction_history(get(), nullptr, 0, &count));
    std::vector<ivr_reconstruct_iteration> h(count);
    if (count) detail::check(ivr_reconstruction_history(get(), h.data(), h.size(), &count));
    return h;
  }
  // The current densities at the full grid, (nz, ny, nx).
  Array<float> volume() const {
    Array<float> v{std::vector<int64_t>(3), {}};
    detail::check(ivr_reconstruction_volume(get(), nullptr, 0, v.shape.data()));
    v.values.resize(detail::product(v.shape));
    detail::check(ivr_reconstruction_volume(get(), v.values.data(), v.size(), v.shape.data()));
    return v;
  }
  // The current TF's parameters, (rows, columns) as its gradient's layout.
  Array<double> tf() const {
    Array<double> t{std::vector<int64_t>(2), {}};
    detail::check(ivr_reconstruction_tf(get(), nullptr, 0, t.shape.data()));
    t.values.resize(detail::product(t.shape));
    detail::check(ivr_reconstruction_tf(get(), t.values.data(), t.size(), t.shape.data()));
    return t;
  }
  // The estimate as a scene of the same context (render it, or set its volume elsewhere).
  Scene result_scene() const {
    ivr_scene* s = nullptr;
    detail::check(ivr_reconstruction_result_scene(get(), &s));
    return Scene(s);
  }
  void save_checkpoint(const std::string& prefix) const {
    detail::check(ivr_reconstruction_save_checkpoint(get(), prefix.c_str()));
  }
  void resume(const std::string& prefix) {
    detail::check(ivr_reconstruction_resume(get(), prefix.c_str()));
  }

 private:
  // The workers' sum, where they share the views: kept as long as the handle's C++ owners.
  struct OwnedSum {
    explicit OwnedSum(std::function<void(double*, size_t)> f) : function(std::move(f)) {}
    std::function<void(double*, size_t)> function;
    detail::Sum state{&function, nullptr};
  };
  void rethrow_sum_error() {
    if (!sum_ || !sum_->state.error) return;
    const std::exception_ptr e = sum_->state.error;
    sum_->state.error = nullptr;
    std::rethrow_exception(e);
  }
  std::shared_ptr<OwnedSum> sum_;
};

// What select_viewpoint searches: ivr_viewpoint_options (documented in ivr.h) filled with the
// library's defaults.
struct ViewpointOptions : ivr_viewpoint_options {
  ViewpointOptions() : ivr_viewpoint_options() { detail::check(ivr_viewpoint_options_init(this)); }
};
using ViewpointProgress = std::function<bool(const ivr_viewpoint_step&)>;
struct ViewpointResult {
  ivr_camera camera{};  // the best camera seen
  double entropy_start = 0, entropy_best = 0;
  std::vector<ivr_viewpoint_step> history;  // the start, then every iteration
};

// The camera on view `options.view`'s orbit whose image has the highest entropy found.
inline ViewpointResult select_viewpoint(const Context& context, const Scene& scene,
                                        const ViewpointOptions& options = {},
                                        const ViewpointProgress& progress = {}) {
  const ivr_viewpoint_options& o = options;
  ViewpointResult r;
  r.history.resize(size_t(options.iterations >= 0 ? options.iterations + 1 : 1));
  detail::Callback<ivr_viewpoint_step> state{&progress, nullptr};
  ivr_viewpoint_result out{};
  const ivr_status status =
      ivr_select_viewpoint(context.get(), scene.get(), &o,
                           progress ? &detail::Callback<ivr_viewpoint_step>::call : nullptr, &state,
                           r.history.data(), r.history.size(), &out);
  if (state.error) std::rethrow_exception(state.error);
  detail::check(status);
  r.history.resize(size_t(out.iterations) + 1);
  r.camera = out.camera;
  r.entropy_start = out.entropy_start;
  r.entropy_best = out.entropy_best;
  return r;
}

// Normalised entropy in [0, 1] of view 0 of an image (views, H, W, C) (ivr_image_entropy).
inline double image_entropy(const Array<float>& image, double background = 1) {
  if (image.shape.size() != 4 || image.size() != detail::product(image.shape))
    throw Exception(IVR_ERROR_INVALID_ARGUMENT,
                    "image_entropy: the image needs a 4-d shape (views, H, W, C) of its values");
  double h = 0;
  detail::check(ivr_image_entropy(image.values.data(), image.shape.data(), background, &h));
  return h;
}

// 10 log10(1 / mse) of `image` against `reference` (peak 1; +infinity when equal).
inline double psnr(const std::vector<float>& image, const std::vector<float>& reference) {
  if (image.size() != reference.size())
    throw Exception(IVR_ERROR_INVALID_ARGUMENT, "psnr: image has " + std::to_string(image.size()) +
                                                    " values, reference " +
                                                    std::to_string(reference.size()));
  double value = 0;
  detail::check(ivr_psnr(image.data(), reference.data(), image.size(), &value));
  return value;
}

}  // namespace ivr::api
