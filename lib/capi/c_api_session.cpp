// c_api_session.cpp — the C API's sessions, device arrays and density optimisers: handles over
// ivr::Session, ivr::DeviceArray and ivr::Optimizer, each holding its context.
#include "capi/c_api_handles.hpp"
#include "capi/options.hpp"
#include "ivr/session.hpp"
#include "session/session.hpp"

using namespace ivr::capi;

struct ivr_session {
  std::atomic<int> references{1};
  ivr_context* context;
  std::unique_ptr<ivr::Session> session;
  bool explicit_box = false;  // the scene's JSON gave a box: kept when the volume's shape changes
};

struct ivr_array {
  std::atomic<int> references{1};
  ivr_context* context;
  ivr::DeviceArray array;
  std::string name;  // a gradient's group ("density", "voxels", …); "" otherwise
};

struct ivr_density_optimizer {
  std::atomic<int> references{1};
  ivr_context* context;
  std::unique_ptr<ivr::Optimizer> optimizer;
};

namespace {

// The session's image shape as the C API's four dimensions: a ray list's (rays, channels) as
// (1, 1, rays, channels), as ivr_scene_image_shape gives it.
std::vector<int64_t> image_shape_4d(ivr::Session& session) {
  std::vector<int64_t> shape = session.image_shape();
  if (shape.size() == 2) shape = {1, 1, shape[0], shape[1]};
  return shape;
}


ivr_context* context_of(const ivr_session* s) {
  return s && is_live(s, Kind::session) ? s->context : nullptr;
}
ivr_context* context_of(const ivr_array* a) {
  return a && is_live(a, Kind::array) ? a->context : nullptr;
}

ivr::Session& session_of(ivr_session* s) {
  return *checked(s, Kind::session, "session")->session;
}

// A live array of the session's context (NULL allowed where `optional`).
const ivr::DeviceArray* array_of(const ivr_session* s, const ivr_array* a, const char* what,
                                 bool optional = false) {
  if (!a && optional) return nullptr;
  checked(a, Kind::array, what);
  same_context(a->context, s->context, what);
  return &a->array;
}

ivr_array* new_array(ivr_context* c, ivr::DeviceArray a) {
  auto h = std::make_unique<ivr_array>();
  h->array = std::move(a);
  return publish(std::move(h), c, Kind::array);
}

// New densities for a session made through this API: where the scene's JSON gave no box the box
// follows the grid (as ivr_scene_set_volume's does), taken together with the densities under one
// lock, so that no other thread sees the new grid in the old box.
template <class Upload>
void set_volume_boxed(ivr_session* s, const ivr::Volume& dims, Upload&& upload) {
  ivr::Session::Impl& impl = s->session->impl();
  std::lock_guard<std::mutex> lock(impl.mutex);
  glm::dvec3 box[2] = {impl.scene.box_min, impl.scene.box_max};
  if (!s->explicit_box) {
    ivr::Scene boxed = impl.scene;
    boxed.volume.nx = dims.nx, boxed.volume.ny = dims.ny, boxed.volume.nz = dims.nz;
    ivr::set_default_box(boxed);
    box[0] = boxed.box_min, box[1] = boxed.box_max;
  }
  upload(impl, box);
}

// The grid of a densities' shape (nz, ny, nx), in the core's words where it is bad.
ivr::Volume dims_of(const int64_t shape[3]) {
  const std::string text = ivr::shape_text({shape[0], shape[1], shape[2]});
  for (int i = 0; i < 3; ++i)
    if (shape[i] < 1 || shape[i] > (int64_t(1) << 20))
      throw CError{IVR_ERROR_INVALID_ARGUMENT,
                   "set_volume: shape " + text + " (each dimension 1 .. 2^20)"};
  if (double(shape[0]) * double(shape[1]) * double(shape[2]) > 2147483647.0)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "set_volume: more than 2^31 voxels"};
  ivr::Volume v;
  v.nz = int(shape[0]), v.ny = int(shape[1]), v.nx = int(shape[2]);
  return v;
}

ivr::DType dtype_of(ivr_dtype d, const char* what) {
  if (d == IVR_FLOAT32) return ivr::DType::f32;
  if (d == IVR_FLOAT64) return ivr::DType::f64;
  throw CError{IVR_ERROR_INVALID_ARGUMENT, std::string(what) + ": dtype " + std::to_string(int(d)) +
                                               " (device arrays hold IVR_FLOAT32 or IVR_FLOAT64)"};
}

template <class Out>
Out* out_handle(Out** out, const char* what) {
  not_null(out, what);
  *out = nullptr;
  return nullptr;
}

}  // namespace

extern "C" {

// --- arrays --------------------------------------------------------------------------------------

// The shape of a new array from its rank (1 .. 8) and dimensions.
std::vector<int64_t> array_shape(int rank, const int64_t* shape) {
  if (rank < 1 || rank > 8)
    throw CError{IVR_ERROR_INVALID_ARGUMENT, "rank " + std::to_string(rank) + " (1 .. 8)"};
  not_null(shape, "shape");
  return std::vector<int64_t>(shape, shape + rank);
}

ivr_status ivr_array_create(ivr_context* c, int rank, const int64_t* shape, ivr_dtype dtype,
                            ivr_array** out) {
  return guarded(c, "ivr_array_create", [&] {
    checked(c, Kind::context, "context");
    out_handle(out, "array");
    *out = new_array(c, ivr::DeviceArray(c->device, array_shape(rank, shape),
                                         dtype_of(dtype, "ivr_array_create")));
  });
}

ivr_status ivr_array_wrap(ivr_context* c, void* data, int rank, const int64_t* shape,
                          ivr_dtype dtype, int* borrowed, ivr_array** out) {
  return guarded(c, "ivr_array_wrap", [&] {
    checked(c, Kind::context, "context");
    out_handle(out, "array");
    std::vector<int64_t> dims = array_shape(rank, shape);
    not_null(data, "data");
    ivr::DeviceArray a = ivr::DeviceArray::wrap(c->device, data, std::move(dims),
                                                dtype_of(dtype, "ivr_array_wrap"));
    if (borrowed) *borrowed = a.borrowed() ? 1 : 0;
    *out = new_array(c, std::move(a));
  });
}

ivr_status ivr_array_map(const ivr_array* a, void** data) {
  return guarded(context_of(a), "ivr_array_map", [&] {
    checked(a, Kind::array, "array");
    *not_null(data, "data") = a->array.map();
  });
}

ivr_status ivr_array_unmap(const ivr_array* a) {
  return guarded(context_of(a), "ivr_array_unmap", [&] { checked(a, Kind::array, "array")->array.unmap(); });
}

ivr_status ivr_array_retain(ivr_array* a) {
  return retain(a, Kind::array, "ivr_array_retain");
}
ivr_status ivr_array_release(ivr_array* a) {
  return release(a, Kind::array, "ivr_array_release");
}

ivr_status ivr_array_info(const ivr_array* a, int* rank, int64_t shape[8], ivr_dtype* dtype) {
  return guarded(context_of(a), "ivr_array_info", [&] {
    checked(a, Kind::array, "array");
    const std::vector<int64_t>& s = a->array.shape();
    if (rank) *rank = int(s.size());
    if (shape)
      for (size_t i = 0; i < 8; ++i) shape[i] = i < s.size() ? s[i] : 1;
    if (dtype) *dtype = a->array.dtype() == ivr::DType::f64 ? IVR_FLOAT64 : IVR_FLOAT32;
  });
}

ivr_status ivr_array_name(const ivr_array* a, const char** name) {
  return guarded(context_of(a), "ivr_array_name", [&] {
    checked(a, Kind::array, "array");
    *not_null(name, "name") = a->name.c_str();
  });
}

ivr_status ivr_array_upload(ivr_array* a, const void* values, ivr_dtype dtype, size_t count) {
  return guarded(context_of(a), "ivr_array_upload", [&] {
    checked(a, Kind::array, "array");
    not_null(values, "values");
    if (dtype_of(dtype, "ivr_array_upload") == ivr::DType::f64)
      a->array.upload(static_cast<const double*>(values), count);
    else
      a->array.upload(static_cast<const float*>(values), count);
  });
}

ivr_status ivr_array_download(const ivr_array* a, void* values, ivr_dtype dtype,
                              size_t capacity) {
  return guarded(context_of(a), "ivr_array_download", [&] {
    checked(a, Kind::array, "array");
    not_null(values, "values");
    const ivr::DType d = dtype_of(dtype, "ivr_array_download");
    if (capacity < a->array.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "values hold " + std::to_string(capacity) +
                                                   "; the array has " +
                                                   std::to_string(a->array.size())};
    if (d == ivr::DType::f64)
      a->array.download(static_cast<double*>(values), capacity);
    else
      a->array.download(static_cast<float*>(values), capacity);
  });
}

ivr_status ivr_array_wait(const ivr_array* a) {
  return guarded(context_of(a), "ivr_array_wait", [&] { checked(a, Kind::array, "array")->array.wait(); });
}

// --- sessions ------------------------------------------------------------------------------------

ivr_status ivr_session_options_init(ivr_session_options* o) {
  return guarded(nullptr, "ivr_session_options_init", [&] {
    *not_null(o, "options") = c_options(ivr::SessionOptions{});
  });
}

ivr_status ivr_session_create(ivr_context* c, const ivr_scene* s, const ivr_session_options* o,
                              ivr_session** out) {
  return guarded(c, "ivr_session_create", [&] {
    checked(c, Kind::context, "context");
    checked(s, Kind::scene, "scene");
    if (s->has_volume) with_volume(s);  // (a slab's scene refused by name)
    same_context(s->context, c, "scene");
    out_handle(out, "session");
    const ivr::SessionOptions so = core_options(o);
    auto h = std::make_unique<ivr_session>();
    h->explicit_box = s->explicit_box;
    if (s->has_volume) {
      h->session = std::make_unique<ivr::Session>(c->device, s->scene, so);
    } else {  // dims only (the JSON's placeholder): no densities until set_volume
      ivr::Scene dims_only = s->scene;
      dims_only.volume.data.clear();
      h->session = std::make_unique<ivr::Session>(c->device, dims_only, so);
    }
    *out = publish(std::move(h), c, Kind::session);
  });
}

ivr_status ivr_session_retain(ivr_session* s) {
  return retain(s, Kind::session, "ivr_session_retain");
}
ivr_status ivr_session_release(ivr_session* s) {
  return release(s, Kind::session, "ivr_session_release");
}

ivr_status ivr_session_set_volume(ivr_session* s, const void* data, ivr_dtype dtype,
                                  const int64_t shape[3]) {
  return guarded(context_of(s), "ivr_session_set_volume", [&] {
    checked(s, Kind::session, "session");
    not_null(data, "data");
    const ivr::Volume dims = dims_of(not_null(shape, "shape"));
    if (dtype == IVR_FLOAT32 || dtype == IVR_FLOAT64) {
      set_volume_boxed(s, dims, [&](ivr::Session::Impl& impl, const glm::dvec3* box) {
        if (dtype == IVR_FLOAT32)
          impl.upload_volume(static_cast<const float*>(data), nullptr, dims, box);
        else
          impl.upload_volume(nullptr, static_cast<const double*>(data), dims, box);
      });
    } else {  // integers: mapped to [0, 1] as a scene's volume would be
      const ivr::Volume v = volume_from_memory(data, dtype, shape);
      set_volume_boxed(s, dims, [&](ivr::Session::Impl& impl, const glm::dvec3* box) {
        impl.upload_volume(v.data.data(), nullptr, dims, box);
      });
    }
  });
}

ivr_status ivr_session_set_volume_array(ivr_session* s, const ivr_array* a) {
  return guarded(context_of(s), "ivr_session_set_volume_array", [&] {
    checked(s, Kind::session, "session");
    const ivr::DeviceArray& densities = *array_of(s, a, "densities");
    const std::vector<int64_t>& shape = densities.shape();
    if (shape.size() != 3)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "set_volume: the array has shape " +
                                                   ivr::shape_text(shape) +
                                                   "; densities are (nz, ny, nx)"};
    set_volume_boxed(s, dims_of(shape.data()),
                     [&](ivr::Session::Impl& impl, const glm::dvec3* box) {
                       impl.copy_volume(densities, box);
                     });
  });
}

ivr_status ivr_session_set_tf(ivr_session* s, const ivr_transfer_function* tf) {
  return guarded(context_of(s), "ivr_session_set_tf", [&] {
    ivr::Session& session = session_of(s);
    checked(tf, Kind::tf, "tf");
    same_context(tf->context, s->context, "tf");
    session.set_tf(tf->tf);
  });
}

ivr_status ivr_session_set_cameras_json(ivr_session* s, const char* json) {
  return guarded(context_of(s), "ivr_session_set_cameras_json", [&] {
    ivr::Session& session = session_of(s);
    session.set_cameras(ivr::parse_cameras(not_null(json, "json")));
  });
}

ivr_status ivr_session_set_rays(ivr_session* s, const double* values, size_t rows, int columns) {
  return guarded(context_of(s), "ivr_session_set_rays", [&] {
    ivr::Session& session = session_of(s);
    session.set_rays(ivr::make_ray_list(not_null(values, "values"), rows, columns));
  });
}

ivr_status ivr_session_set_cameras(ivr_session* s, const ivr_camera* cameras, size_t count) {
  return guarded(context_of(s), "ivr_session_set_cameras", [&] {
    ivr::Session& session = session_of(s);
    not_null(cameras, "cameras");
    if (count == 0) throw CError{IVR_ERROR_INVALID_ARGUMENT, "count is 0 (a session needs a camera)"};
    std::vector<ivr::Camera> out(count);
    for (size_t i = 0; i < count; ++i) {
      const ivr_camera& c = cameras[i];
      out[i].eye = {c.eye[0], c.eye[1], c.eye[2]};
      out[i].target = {c.target[0], c.target[1], c.target[2]};
      out[i].up = {c.up[0], c.up[1], c.up[2]};
      out[i].fov_y = c.fov_y;
      out[i].projection =
          c.orthographic ? ivr::Projection::orthographic : ivr::Projection::perspective;
      out[i].ortho_height = c.ortho_height;
      out[i].width = c.width;
      out[i].height = c.height;
    }
    session.set_cameras(out);
  });
}

ivr_status ivr_session_set_integrator_json(ivr_session* s, const char* json) {
  return guarded(context_of(s), "ivr_session_set_integrator_json", [&] {
    ivr::Session& session = session_of(s);
    session.set_integrator(ivr::parse_integrator(not_null(json, "json")));
  });
}

ivr_status ivr_session_set_background(ivr_session* s, const double background[3]) {
  return guarded(context_of(s), "ivr_session_set_background", [&] {
    ivr::Session& session = session_of(s);
    not_null(background, "background");
    session.set_background({background[0], background[1], background[2]});
  });
}

ivr_status ivr_session_set_target(ivr_session* s, const float* target, size_t count) {
  return guarded(context_of(s), "ivr_session_set_target", [&] {
    ivr::Session& session = session_of(s);
    not_null(target, "target");
    const std::vector<int64_t> shape = image_shape_4d(session);
    const size_t want = size_t(shape[0] * shape[1] * shape[2] * shape[3]);
    if (count != want)
      throw CError{IVR_ERROR_INVALID_ARGUMENT, "target has " + std::to_string(count) +
                                                   " floats; the session renders " +
                                                   std::to_string(want)};
    session.set_target(ivr::Image{int(shape[0]), int(shape[1]), int(shape[2]), int(shape[3]),
                                  std::vector<float>(target, target + count)});
  });
}

ivr_status ivr_session_set_target_array(ivr_session* s, const ivr_array* a) {
  return guarded(context_of(s), "ivr_session_set_target_array", [&] {
    ivr::Session& session = session_of(s);
    session.set_target(*array_of(s, a, "target"));
  });
}

ivr_status ivr_session_image_shape(const ivr_session* s, int64_t shape[4]) {
  return guarded(context_of(s), "ivr_session_image_shape", [&] {
    checked(s, Kind::session, "session");
    not_null(shape, "shape");
    const std::vector<int64_t> v = image_shape_4d(*s->session);
    std::copy(v.begin(), v.end(), shape);
  });
}

ivr_status ivr_session_volume_shape(const ivr_session* s, int64_t shape[3]) {
  return guarded(context_of(s), "ivr_session_volume_shape", [&] {
    checked(s, Kind::session, "session");
    not_null(shape, "shape");
    const std::vector<int64_t> v = s->session->has_volume() ? s->session->volume_shape()
                                                            : std::vector<int64_t>{0, 0, 0};
    std::copy(v.begin(), v.end(), shape);
  });
}

ivr_status ivr_session_volume(ivr_session* s, ivr_array** out) {
  return guarded(context_of(s), "ivr_session_volume", [&] {
    ivr::Session& session = session_of(s);
    out_handle(out, "densities");
    *out = new_array(s->context, session.volume());
  });
}

ivr_status ivr_session_render(ivr_session* s, ivr_array** out) {
  return guarded(context_of(s), "ivr_session_render", [&] {
    ivr::Session& session = session_of(s);
    out_handle(out, "image");
    *out = new_array(s->context, session.render());
  });
}

ivr_status ivr_session_gradient(ivr_session* s, const ivr_array* target, const char* wrt,
                                ivr_mode mode, ivr_loss loss, int deterministic,
                                ivr_array** loss_value, ivr_array** groups, size_t capacity,
                                size_t* count, ivr_mode* ran) {
  return guarded(context_of(s), "ivr_session_gradient", [&] {
    ivr::Session& session = session_of(s);
    const ivr::DeviceArray* t = array_of(s, target, "target", true);
    not_null(wrt, "wrt");
    out_handle(loss_value, "loss");
    not_null(groups, "groups");
    ivr::GradientRequest request;
    request.wrt = ivr::parse_groups(wrt);
    request.mode = mode_of(mode);
    request.loss = loss_of(loss);
    request.deterministic = deterministic != 0;
    if (capacity < request.wrt.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "groups hold " + std::to_string(capacity) +
                                                   "; wrt names " +
                                                   std::to_string(request.wrt.size())};
    const ivr::SessionGradient g = t ? session.gradient(*t, request) : session.gradient(request);
    // Publish every handle only once all exist, so a failure hands out none.
    std::vector<std::unique_ptr<ivr_array>> made;
    for (const auto& group : g.groups) {
      made.push_back(std::make_unique<ivr_array>());
      made.back()->array = group.second;
    }
    for (size_t i = 0; i < made.size(); ++i) made[i]->name = g.groups[i].first;
    *loss_value = new_array(s->context, g.loss);
    for (size_t i = 0; i < made.size(); ++i)
      groups[i] = publish(std::move(made[i]), s->context, Kind::array);
    if (count) *count = g.groups.size();
    if (ran) *ran = g.plan.mode == ivr::Mode::forward ? IVR_MODE_FORWARD : IVR_MODE_ADJOINT;
  });
}

ivr_status ivr_session_jacobian(ivr_session* s, const char* wrt, ivr_array** out) {
  return guarded(context_of(s), "ivr_session_jacobian", [&] {
    ivr::Session& session = session_of(s);
    not_null(wrt, "wrt");
    out_handle(out, "jacobian");
    *out = new_array(s->context, session.jacobian(ivr::parse_groups(wrt)));
  });
}

ivr_status ivr_session_project(ivr_session* s, const ivr_array* volume, ivr_array** out) {
  return guarded(context_of(s), "ivr_session_project", [&] {
    ivr::Session& session = session_of(s);
    const ivr::DeviceArray* v = array_of(s, volume, "volume", true);
    out_handle(out, "lines");
    *out = new_array(s->context, v ? session.project(*v) : session.project());
  });
}

ivr_status ivr_session_backproject(ivr_session* s, const ivr_array* lines, ivr_array** out) {
  return guarded(context_of(s), "ivr_session_backproject", [&] {
    ivr::Session& session = session_of(s);
    const ivr::DeviceArray* p = array_of(s, lines, "lines");
    out_handle(out, "volume");
    *out = new_array(s->context, session.backproject(*p));
  });
}

ivr_status ivr_session_loss(ivr_session* s, const ivr_array* image, const ivr_array* target,
                            ivr_loss loss, ivr_array** out) {
  return guarded(context_of(s), "ivr_session_loss", [&] {
    ivr::Session& session = session_of(s);
    const ivr::DeviceArray* a = array_of(s, image, "image");
    const ivr::DeviceArray* b = array_of(s, target, "target");
    out_handle(out, "value");
    *out = new_array(s->context, session.loss(*a, *b, loss_of(loss)));
  });
}

ivr_status ivr_density_optimizer_create(ivr_session* s, ivr_optimizer kind, double lr,
                                        ivr_density_optimizer** out) {
  return guarded(context_of(s), "ivr_density_optimizer_create", [&] {
    ivr::Session& session = session_of(s);
    out_handle(out, "optimizer");
    if (kind != IVR_OPTIMIZER_ADAM && kind != IVR_OPTIMIZER_SGD && kind != IVR_OPTIMIZER_AUTO)
      throw CError{IVR_ERROR_INVALID_ARGUMENT,
                   "kind " + std::to_string(int(kind)) +
                       " (densities take IVR_OPTIMIZER_ADAM or IVR_OPTIMIZER_SGD)"};
    if (!session.has_volume())
      throw CError{IVR_ERROR_INVALID_ARGUMENT,
                   "the session has no densities yet (ivr_session_set_volume first)"};
    ivr::OptimizerOptions o;
    o.kind = kind == IVR_OPTIMIZER_SGD ? ivr::OptimizerKind::sgd : ivr::OptimizerKind::adam;
    o.lr = lr;
    o.lower = 0;
    const std::vector<int64_t> shape = session.volume_shape();
    auto h = std::make_unique<ivr_density_optimizer>();
    h->optimizer = std::make_unique<ivr::Optimizer>(
        s->context->device, size_t(shape[0] * shape[1] * shape[2]), o,
        session.options().precision);
    *out = publish(std::move(h), s->context, Kind::optimizer);
  });
}

ivr_status ivr_density_optimizer_retain(ivr_density_optimizer* o) {
  return retain(o, Kind::optimizer, "ivr_density_optimizer_retain");
}
ivr_status ivr_density_optimizer_release(ivr_density_optimizer* o) {
  return release(o, Kind::optimizer, "ivr_density_optimizer_release");
}

ivr_status ivr_session_step(ivr_session* s, ivr_density_optimizer* o, const ivr_array* gradient) {
  return guarded(context_of(s), "ivr_session_step", [&] {
    ivr::Session& session = session_of(s);
    checked(o, Kind::optimizer, "optimizer");
    same_context(o->context, s->context, "optimizer");
    session.step(*o->optimizer, *array_of(s, gradient, "gradient"));
  });
}

ivr_status ivr_session_last_stats(ivr_session* s, ivr_operation_stats* out) {
  return guarded(context_of(s), "ivr_session_last_stats", [&] {
    ivr::Session& session = session_of(s);
    not_null(out, "stats");
    const ivr::OperationStats st = session.last_stats();
    out->kernel_seconds = st.kernel_seconds;
    out->build_seconds = st.build_seconds;
    out->samples = st.samples;
    out->device_bytes = st.device_bytes;
    out->step = st.step;
    out->skipped_empty = st.skipped_empty ? 1 : 0;
    out->empty_fraction = st.empty_fraction;
  });
}

ivr_status ivr_session_finish(ivr_session* s) {
  return guarded(context_of(s), "ivr_session_finish", [&] { session_of(s).finish(); });
}

}  // extern "C"
