// c_api.cpp — the C API (include/ivr/ivr.h) over the C++ core: status strings, versions, devices,
// contexts, scenes, render, loss, gradients and results (volume and TF handles: c_api_volume.cpp).
#include <nlohmann/json.hpp>

#include "capi/c_api_handles.hpp"
#include "ivr/domain.hpp"
#include "ivr/planner.hpp"
#include "ivr/tolerance.hpp"

using namespace ivr::capi;

extern "C" {

const char* ivr_status_string(ivr_status s) {
  switch (s) {
    case IVR_OK:
      return "IVR_OK";
    case IVR_ERROR_INVALID_ARGUMENT:
      return "IVR_ERROR_INVALID_ARGUMENT";
    case IVR_ERROR_IO:
      return "IVR_ERROR_IO";
    case IVR_ERROR_NO_DEVICE:
      return "IVR_ERROR_NO_DEVICE";
    case IVR_ERROR_OPENCL:
      return "IVR_ERROR_OPENCL";
    case IVR_ERROR_BUILD:
      return "IVR_ERROR_BUILD";
    case IVR_ERROR_OUT_OF_MEMORY:
      return "IVR_ERROR_OUT_OF_MEMORY";
    case IVR_ERROR_UNSUPPORTED:
      return "IVR_ERROR_UNSUPPORTED";
    case IVR_ERROR_NULL_POINTER:
      return "IVR_ERROR_NULL_POINTER";
    case IVR_ERROR_INVALID_HANDLE:
      return "IVR_ERROR_INVALID_HANDLE";
    case IVR_ERROR_WRONG_CONTEXT:
      return "IVR_ERROR_WRONG_CONTEXT";
    case IVR_ERROR_BUFFER_TOO_SMALL:
      return "IVR_ERROR_BUFFER_TOO_SMALL";
    case IVR_ERROR_INTERNAL:
      return "IVR_ERROR_INTERNAL";
    case IVR_STATUS_MAX_ENUM:
      break;
  }
  return "IVR_ERROR_UNKNOWN_STATUS";
}

int ivr_version(void) {
  return IVR_VERSION;
}
const char* ivr_last_error(void) {
  return thread_error.c_str();
}
int ivr_last_opencl_error(void) {
  return thread_opencl_error;
}

ivr_status ivr_devices_json(char* buffer, size_t capacity, size_t* needed) {
  return guarded(nullptr, "ivr_devices_json", [&] {
    const std::string text = ivr::devices_json();
    if (needed) *needed = text.size() + 1;
    if (!buffer && capacity == 0) return;
    not_null(buffer, "buffer");
    if (capacity < text.size() + 1)
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "buffer of " + std::to_string(capacity) +
                                                   " bytes; the text needs " +
                                                   std::to_string(text.size() + 1)};
    std::memcpy(buffer, text.c_str(), text.size() + 1);
  });
}

ivr_status ivr_context_create(const char* selector, ivr_context** out) {
  return guarded(nullptr, "ivr_context_create", [&] {
    not_null(out, "context");
    *out = nullptr;
    auto* c = new ivr_context(selector ? selector : "");
    track(c, Kind::context);
    *out = c;
  });
}

ivr_status ivr_context_retain(ivr_context* c) {
  return retain(c, Kind::context, "ivr_context_retain");
}
ivr_status ivr_context_release(ivr_context* c) {
  return release(c, Kind::context, "ivr_context_release");
}

const char* ivr_context_last_error(const ivr_context* c) {
  if (!c || !is_live(c, Kind::context)) return "ivr_context_last_error: not a live ivr_context";
  return c->last_error.c_str();
}

ivr_status ivr_context_device_name(const ivr_context* c, const char** name) {
  return guarded(context_of(c), "ivr_context_device_name", [&] {
    checked(c, Kind::context, "context");
    *not_null(name, "name") = c->device.info().name.c_str();
  });
}

ivr_status ivr_scene_from_json(ivr_context* c, const char* json, const char* base_dir,
                               ivr_scene** out) {
  return guarded(c, "ivr_scene_from_json", [&] {
    checked(c, Kind::context, "context");
    not_null(json, "json");
    not_null(out, "scene");
    *out = nullptr;
    auto s = std::make_unique<ivr_scene>();
    s->context = c;
    // Without "volume" the scene parses with a placeholder until ivr_scene_set_volume.
    nlohmann::json j = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
    std::string text = json;
    if (j.is_object()) {
      s->explicit_box = j.contains("box");
      if (!j.contains("volume")) {
        s->has_volume = false;
        j["volume"] = {{"synthetic", "sphere"}, {"dims", {2, 2, 2}}};
        text = j.dump();
      }
    }
    s->scene = ivr::parse_scene(text, base_dir ? base_dir : ".");
    c->references.fetch_add(1);
    track(s.get(), Kind::scene);
    *out = s.release();
  });
}

ivr_status ivr_scene_load(ivr_context* c, const char* path, ivr_scene** out) {
  return guarded(c, "ivr_scene_load", [&] {
    checked(c, Kind::context, "context");
    not_null(path, "path");
    not_null(out, "scene");
    *out = nullptr;
    auto s = std::make_unique<ivr_scene>();
    s->context = c;
    s->scene = ivr::load_scene(path);
    s->explicit_box = true;
    c->references.fetch_add(1);
    track(s.get(), Kind::scene);
    *out = s.release();
  });
}

ivr_status ivr_scene_retain(ivr_scene* s) {
  return retain(s, Kind::scene, "ivr_scene_retain");
}
ivr_status ivr_scene_release(ivr_scene* s) {
  return release(s, Kind::scene, "ivr_scene_release");
}

ivr_status ivr_scene_image_shape(const ivr_scene* s, int64_t shape[4]) {
  return guarded(context_of(s), "ivr_scene_image_shape", [&] {
    checked(s, Kind::scene, "scene");
    not_null(shape, "shape");
    const ivr::ImageExtent c = ivr::image_extent(s->scene);
    shape[0] = c.views;
    shape[1] = c.height;
    shape[2] = c.width;
    shape[3] = s->scene.channels();
  });
}

ivr_status ivr_scene_volume_shape(const ivr_scene* s, int64_t shape[3]) {
  return guarded(context_of(s), "ivr_scene_volume_shape", [&] {
    checked(s, Kind::scene, "scene");
    write_shape(s->scene.volume, not_null(shape, "shape"));
  });
}

ivr_status ivr_scene_step(ivr_context* c, const ivr_scene* s, ivr_precision precision,
                          double* step, double* estimated_error) {
  return guarded(c, "ivr_scene_step", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(step, "step");
    ivr::StepChoice choice;
    ivr::integrator_for(c->device, s->scene, 0, precision_of(precision),
                        ivr::EmptySpace::automatic, &choice);
    *step = choice.step;
    if (estimated_error) *estimated_error = choice.estimated_error;
  });
}

ivr_status ivr_render(ivr_context* c, const ivr_scene* s, ivr_precision precision, double step,
                      float* image, size_t capacity) {
  return guarded(c, "ivr_render", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(image, "image");
    const ivr::Precision p = precision_of(precision);
    const ivr::Image out = ivr::render(c->device, s->scene, ivr::RenderOptions{p, step});
    if (capacity < out.pixels.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "image holds " + std::to_string(capacity) +
                                                   " floats; the render has " +
                                                   std::to_string(out.pixels.size())};
    std::memcpy(image, out.pixels.data(), out.pixels.size() * sizeof(float));
  });
}

}  // extern "C"

namespace {
// The caller's target (count floats) in the scene's image shape.
ivr::Image target_image(const ivr::Scene& scene, const float* target, size_t count) {
  const ivr::ImageExtent cam = ivr::image_extent(scene);
  ivr::Image t{cam.views, cam.height, cam.width, scene.channels(), {}};
  const size_t want = size_t(t.views) * t.height * t.width * t.channels;
  if (count != want)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "target has " + std::to_string(count) +
                                                 " floats; the scene renders " +
                                                 std::to_string(want)};
  t.pixels.assign(target, target + count);
  return t;
}

// A gradient as a result handle: its loss, seconds, mode and one array per group.
ivr_result* gradient_result(ivr_context* c, const ivr::Gradient& d) {
  ivr_result* r = new_result(c);
  r->loss = d.loss;
  r->seconds = d.kernel_seconds;
  r->mode = d.plan.mode == ivr::Mode::forward ? IVR_MODE_FORWARD : IVR_MODE_ADJOINT;
  for (const ivr::GroupGradient& g : d.groups)
    r->arrays.push_back({g.name, std::vector<int64_t>(g.shape.begin(), g.shape.end()), g.values});
  return r;
}

// The checks every gradient call makes of its handles and pointers; the target as an Image.
ivr::Image checked_gradient_call(ivr_context* c, const ivr_scene* s, const float* target,
                                 size_t count, const char* wrt, ivr_result** out,
                                 bool slab_allowed = false) {
  checked(c, Kind::context, "context");
  with_volume(checked(s, Kind::scene, "scene"), slab_allowed);
  same_context(s->context, c, "scene");
  not_null(target, "target");
  not_null(wrt, "wrt");
  not_null(out, "result");
  *out = nullptr;
  return target_image(s->scene, target, count);
}

// ivr_gradient and ivr_gradient_shared: worker `rank` of `ranks` (1: the whole gradient alone).
void gradient_call(ivr_context* c, const ivr_scene* s, const float* target, size_t count,
                   const char* wrt, ivr_mode mode, ivr_loss loss, ivr_precision precision,
                   double step, bool deterministic, int rank, int ranks, ivr_sum_fn sum,
                   void* sum_user, ivr_result** out, const double* shares = nullptr) {
  const ivr::Image t = checked_gradient_call(c, s, target, count, wrt, out);
  check_worker(rank, ranks);
  if (ranks > 1 && !sum) throw CError{IVR_ERROR_NULL_POINTER, "sum is NULL"};
  ivr::GradientOptions o;
  o.mode = mode_of(mode);
  o.loss = loss_of(loss);
  o.precision = precision_of(precision);
  o.step = step;
  o.deterministic = deterministic;
  if (ranks > 1) o.worker = rank, o.workers = ranks, o.sum = sum_of(sum, sum_user);
  if (shares) o.shares.assign(shares, shares + ranks);  // (each weight checked by the core)
  *out = gradient_result(c, ivr::gradient(c->device, s->scene, t, ivr::parse_groups(wrt), o));
}
}  // namespace

extern "C" {

ivr_status ivr_gradient(ivr_context* c, const ivr_scene* s, const float* target, size_t count,
                        const char* wrt, ivr_mode mode, ivr_loss loss, ivr_precision precision,
                        double step, ivr_result** out) {
  return guarded(c, "ivr_gradient", [&] {
    gradient_call(c, s, target, count, wrt, mode, loss, precision, step, false, 0, 1, nullptr,
                  nullptr, out);
  });
}

ivr_status ivr_gradient_shared(ivr_context* c, const ivr_scene* s, const float* target,
                               size_t count, const char* wrt, ivr_mode mode, ivr_loss loss,
                               ivr_precision precision, double step, int deterministic, int rank,
                               int ranks, ivr_sum_fn sum, void* sum_user, ivr_result** out) {
  return guarded(c, "ivr_gradient_shared", [&] {
    gradient_call(c, s, target, count, wrt, mode, loss, precision, step, deterministic != 0, rank,
                  ranks, sum, sum_user, out);
  });
}

ivr_status ivr_gradient_shared_weighted(ivr_context* c, const ivr_scene* s, const float* target,
                                        size_t count, const char* wrt, ivr_mode mode,
                                        ivr_loss loss, ivr_precision precision, double step,
                                        int deterministic, int rank, int ranks,
                                        const double* shares, ivr_sum_fn sum, void* sum_user,
                                        ivr_result** out) {
  return guarded(c, "ivr_gradient_shared_weighted", [&] {
    gradient_call(c, s, target, count, wrt, mode, loss, precision, step, deterministic != 0, rank,
                  ranks, sum, sum_user, out, shares);
  });
}

ivr_status ivr_view_shares(size_t n, const double* weights, size_t parts, int each,
                           size_t* counts) {
  return guarded(nullptr, "ivr_view_shares", [&] {
    not_null(counts, "counts");
    if (parts == 0) throw CError{IVR_ERROR_INVALID_ARGUMENT, "parts is 0"};
    const std::vector<double> w =
        weights ? std::vector<double>(weights, weights + parts) : std::vector<double>(parts, 1.0);
    const auto split = each ? ivr::view_shares_each(n, w) : ivr::view_shares(n, w);
    for (size_t i = 0; i < parts; ++i) counts[i] = split[i].second;
  });
}

ivr_status ivr_context_samples_per_second(const ivr_context* c, double* speed) {
  return guarded(context_of(c), "ivr_context_samples_per_second", [&] {
    checked(c, Kind::context, "context");
    *not_null(speed, "speed") = ivr::samples_per_second(c->device.info());
  });
}

}  // extern "C"

namespace {

void render_split(ivr_context* c, const ivr_scene* s, ivr_precision precision, double step,
                  ivr_split split, int rank, int ranks, const double* shares, ivr_sum_fn sum,
                  void* sum_user, float* image, size_t capacity) {
  checked(c, Kind::context, "context");
  with_volume(checked(s, Kind::scene, "scene"), true);
  same_context(s->context, c, "scene");
  not_null(image, "image");
  const ivr::DomainPart part = slab_part(split, rank, ranks, shares, sum, sum_user);
  const ivr::ImageExtent e = ivr::image_extent(s->scene);
  const size_t want = e.pixels() * size_t(s->scene.channels());
  if (capacity < want)
    throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "image holds " + std::to_string(capacity) +
                                                 " floats; the render has " +
                                                 std::to_string(want)};
  const ivr::Image out = ivr::render_domain(c->device, split_scene(s, rank, ranks, part.shares), part,
                                            ivr::RenderOptions{precision_of(precision), step});
  std::memcpy(image, out.pixels.data(), out.pixels.size() * sizeof(float));
}

void gradient_split(ivr_context* c, const ivr_scene* s, const float* target, size_t count,
                    const char* wrt, ivr_loss loss, ivr_precision precision, double step,
                    ivr_split split, int rank, int ranks, const double* shares, ivr_sum_fn sum,
                    void* sum_user, ivr_result** out, bool deterministic = false) {
  const ivr::Image t = checked_gradient_call(c, s, target, count, wrt, out, true);
  const ivr::DomainPart part = slab_part(split, rank, ranks, shares, sum, sum_user);
  ivr::GradientOptions o;  // (automatic: density, tf, background by the adjoint, others forward)
  o.loss = loss_of(loss);
  o.precision = precision_of(precision);
  o.step = step;
  o.deterministic = deterministic;
  const ivr::Gradient d =
      ivr::gradient_domain(c->device, split_scene(s, rank, ranks, part.shares), t, part, o,
                           nullptr, ivr::parse_groups(wrt));
  *out = gradient_result(c, d);
}
}  // namespace

extern "C" {

ivr_status ivr_render_slabs(ivr_context* c, const ivr_scene* s, ivr_precision precision,
                            double step, int rank, int ranks, ivr_sum_fn sum, void* sum_user,
                            float* image, size_t capacity) {
  return guarded(c, "ivr_render_slabs", [&] {
    render_split(c, s, precision, step, IVR_SPLIT_SLABS, rank, ranks, nullptr, sum, sum_user,
                 image, capacity);
  });
}

ivr_status ivr_render_split(ivr_context* c, const ivr_scene* s, ivr_precision precision,
                            double step, ivr_split split, int rank, int ranks, ivr_sum_fn sum,
                            void* sum_user, float* image, size_t capacity) {
  return guarded(c, "ivr_render_split", [&] {
    render_split(c, s, precision, step, split, rank, ranks, nullptr, sum, sum_user, image,
                 capacity);
  });
}

ivr_status ivr_render_split_weighted(ivr_context* c, const ivr_scene* s, ivr_precision precision,
                                     double step, ivr_split split, int rank, int ranks,
                                     const double* shares, ivr_sum_fn sum, void* sum_user,
                                     float* image, size_t capacity) {
  return guarded(c, "ivr_render_split_weighted", [&] {
    render_split(c, s, precision, step, split, rank, ranks, shares, sum, sum_user, image,
                 capacity);
  });
}

ivr_status ivr_gradient_slabs(ivr_context* c, const ivr_scene* s, const float* target,
                              size_t count, const char* wrt, ivr_loss loss,
                              ivr_precision precision, double step, int rank, int ranks,
                              ivr_sum_fn sum, void* sum_user, ivr_result** out) {
  return guarded(c, "ivr_gradient_slabs", [&] {
    gradient_split(c, s, target, count, wrt, loss, precision, step, IVR_SPLIT_SLABS, rank, ranks,
                   nullptr, sum, sum_user, out);
  });
}

ivr_status ivr_gradient_split(ivr_context* c, const ivr_scene* s, const float* target,
                              size_t count, const char* wrt, ivr_loss loss,
                              ivr_precision precision, double step, ivr_split split, int rank,
                              int ranks, ivr_sum_fn sum, void* sum_user, ivr_result** out) {
  return guarded(c, "ivr_gradient_split", [&] {
    gradient_split(c, s, target, count, wrt, loss, precision, step, split, rank, ranks, nullptr,
                   sum, sum_user, out);
  });
}

ivr_status ivr_gradient_split_weighted(ivr_context* c, const ivr_scene* s, const float* target,
                                       size_t count, const char* wrt, ivr_loss loss,
                                       ivr_precision precision, double step, ivr_split split,
                                       int rank, int ranks, const double* shares, ivr_sum_fn sum,
                                       void* sum_user, ivr_result** out) {
  return guarded(c, "ivr_gradient_split_weighted", [&] {
    gradient_split(c, s, target, count, wrt, loss, precision, step, split, rank, ranks, shares,
                   sum, sum_user, out);
  });
}

ivr_status ivr_gradient_split_deterministic(ivr_context* c, const ivr_scene* s, const float* target,
                                            size_t count, const char* wrt, ivr_loss loss,
                                            ivr_precision precision, double step, ivr_split split,
                                            int deterministic, int rank, int ranks,
                                            const double* shares, ivr_sum_fn sum, void* sum_user,
                                            ivr_result** out) {
  return guarded(c, "ivr_gradient_split_deterministic", [&] {
    gradient_split(c, s, target, count, wrt, loss, precision, step, split, rank, ranks, shares, sum,
                   sum_user, out, deterministic != 0);
  });
}

ivr_status ivr_image_loss(const float* image, const float* target, size_t count, ivr_loss loss,
                          double* value) {
  return guarded(nullptr, "ivr_image_loss", [&] {
    not_null(image, "image");
    not_null(target, "target");
    not_null(value, "value");
    if (count == 0) throw CError{IVR_ERROR_INVALID_ARGUMENT, "count is 0 (no pixels to compare)"};
    const ivr::Loss l = loss_of(loss);
    ivr::Image a{1, 1, int(count), 1, std::vector<float>(image, image + count)};
    ivr::Image b{1, 1, int(count), 1, std::vector<float>(target, target + count)};
    *value = ivr::image_loss(a, b, l);
  });
}

ivr_status ivr_jacobian(ivr_context* c, const ivr_scene* s, const char* wrt,
                        ivr_precision precision, double step, ivr_result** out) {
  return guarded(c, "ivr_jacobian", [&] {
    checked(c, Kind::context, "context");
    with_volume(checked(s, Kind::scene, "scene"));
    same_context(s->context, c, "scene");
    not_null(wrt, "wrt");
    not_null(out, "result");
    *out = nullptr;
    std::vector<ivr::Parameter> params;
    for (const std::string& g : ivr::parse_groups(wrt))
      for (const ivr::Parameter& p : ivr::parameters_of(s->scene, g)) params.push_back(p);
    ivr::JacobianOptions o;
    o.precision = precision_of(precision);
    o.step = step;
    o.jacobian = true;
    const ivr::Jacobian t = ivr::jacobian(c->device, s->scene, params, nullptr, o);
    ivr_result* r = new_result(c);
    r->seconds = t.kernel_seconds;
    r->mode = IVR_MODE_FORWARD;
    const ivr::Image& im = t.image;
    r->arrays.push_back({"jacobian",
                         {im.views, im.height, im.width, im.channels, int64_t(params.size())},
                         t.jacobian_f64.empty()
                             ? std::vector<double>(t.jacobian.begin(), t.jacobian.end())
                             : t.jacobian_f64});  // a float64 run's, unrounded
    *out = r;
  });
}

ivr_status ivr_result_retain(ivr_result* r) {
  return retain(r, Kind::result, "ivr_result_retain");
}
ivr_status ivr_result_release(ivr_result* r) {
  return release(r, Kind::result, "ivr_result_release");
}

ivr_status ivr_result_info(const ivr_result* r, double* loss, ivr_mode* mode, double* seconds) {
  return guarded(context_of(r), "ivr_result_info", [&] {
    checked(r, Kind::result, "result");
    if (loss) *loss = r->loss;
    if (mode) *mode = r->mode;
    if (seconds) *seconds = r->seconds;
  });
}

ivr_status ivr_result_array_count(const ivr_result* r, size_t* count) {
  return guarded(context_of(r), "ivr_result_array_count", [&] {
    checked(r, Kind::result, "result");
    *not_null(count, "count") = r->arrays.size();
  });
}

}  // extern "C"

namespace {
const ivr_result::Array& array_at(const ivr_result* r, size_t i) {
  checked(r, Kind::result, "result");
  if (i >= r->arrays.size())
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "array " + std::to_string(i) + " of " + std::to_string(r->arrays.size())};
  return r->arrays[i];
}
}  // namespace

extern "C" {

ivr_status ivr_result_array_shape(const ivr_result* r, size_t i, const char** name, int* rank,
                                  int64_t shape[5]) {
  return guarded(context_of(r), "ivr_result_array_shape", [&] {
    const ivr_result::Array& a = array_at(r, i);
    if (name) *name = a.name.c_str();
    if (rank) *rank = int(a.shape.size());
    not_null(shape, "shape");
    for (size_t k = 0; k < 5; ++k) shape[k] = k < a.shape.size() ? a.shape[k] : 1;
  });
}

ivr_status ivr_result_array_data(const ivr_result* r, size_t i, double* values, size_t capacity) {
  return guarded(context_of(r), "ivr_result_array_data", [&] {
    const ivr_result::Array& a = array_at(r, i);
    not_null(values, "values");
    if (capacity < a.values.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "values hold " + std::to_string(capacity) +
                                                   "; array '" + a.name + "' has " +
                                                   std::to_string(a.values.size())};
    std::memcpy(values, a.values.data(), a.values.size() * sizeof(double));
  });
}

}  // extern "C"
