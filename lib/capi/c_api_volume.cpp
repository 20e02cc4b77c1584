// c_api_volume.cpp — the C API's volumes and transfer functions: handles made from caller memory
// or docs/design.md's JSON objects, read back, and copied into scenes.
#include "capi/c_api_handles.hpp"

using namespace ivr::capi;

namespace {

// The scene's new volume; the box follows it unless the scene's JSON gave one.
void replace_volume(ivr_scene* s, ivr::Volume v) {
  s->scene.volume = std::move(v);
  s->has_volume = true;
  s->slab_rank = s->slab_ranks = 0;
  s->slab_shares.clear();
  if (!s->explicit_box) ivr::set_default_box(s->scene);
}

// Worker `rank` of `ranks`' planes of a volume of nz planes (cut by `shares`; NULL: equal) as
// the scene's volume.
void set_volume_slab(ivr_scene* s, const void* data, ivr_dtype dtype, const int64_t shape[3],
                     int64_t nz, int rank, int ranks, const double* shares) {
  checked(s, Kind::scene, "scene");
  if (nz < 2 || nz > INT32_MAX)
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "nz " + std::to_string(nz) + " (the whole volume's planes: 2 or more)"};
  std::vector<double> weights = slab_weights(shares, ranks);
  // (names a bad worker or weight)
  const ivr::Slab slab = ivr::domain_slab(int(nz), rank, ranks, weights);
  ivr::Volume v = volume_from_memory(data, dtype, shape);
  if (v.nz != slab.planes())
    throw CError{IVR_ERROR_INVALID_ARGUMENT,
                 "shape has " + std::to_string(v.nz) + " planes; worker " +
                     std::to_string(rank) + " of " + std::to_string(ranks) + "'s slab of " +
                     std::to_string(nz) + " is planes " + std::to_string(slab.first) + ".." +
                     std::to_string(slab.last) + " (" + std::to_string(slab.planes()) + ")"};
  v.nz = int(nz);  // the whole volume's dims (and box), the slab's values alone
  v.spacing = s->scene.volume.spacing;
  replace_volume(s, std::move(v));
  s->slab_rank = rank, s->slab_ranks = ranks;
  s->slab_shares = std::move(weights);
}

}  // namespace

extern "C" {

ivr_status ivr_scene_set_volume(ivr_scene* s, const void* data, ivr_dtype dtype,
                                const int64_t shape[3]) {
  return guarded(context_of(s), "ivr_scene_set_volume", [&] {
    checked(s, Kind::scene, "scene");
    ivr::Volume v = volume_from_memory(data, dtype, shape);
    v.spacing = s->scene.volume.spacing;
    replace_volume(s, std::move(v));
  });
}


ivr_status ivr_scene_set_volume_slab(ivr_scene* s, const void* data, ivr_dtype dtype,
                                     const int64_t shape[3], int64_t nz, int rank, int ranks) {
  return guarded(context_of(s), "ivr_scene_set_volume_slab",
                 [&] { set_volume_slab(s, data, dtype, shape, nz, rank, ranks, nullptr); });
}

ivr_status ivr_scene_set_volume_slab_weighted(ivr_scene* s, const void* data, ivr_dtype dtype,
                                              const int64_t shape[3], int64_t nz, int rank,
                                              int ranks, const double* shares) {
  return guarded(context_of(s), "ivr_scene_set_volume_slab_weighted",
                 [&] { set_volume_slab(s, data, dtype, shape, nz, rank, ranks, shares); });
}

ivr_status ivr_volume_create(ivr_context* c, const void* data, ivr_dtype dtype,
                             const int64_t shape[3], ivr_volume** out) {
  return guarded(c, "ivr_volume_create", [&] {
    checked(c, Kind::context, "context");
    not_null(out, "volume");
    *out = nullptr;
    auto v = std::make_unique<ivr_volume>();
    v->volume = volume_from_memory(data, dtype, shape);
    *out = publish(std::move(v), c, Kind::volume);
  });
}

ivr_status ivr_volume_from_json(ivr_context* c, const char* json, const char* base_dir,
                                ivr_volume** out) {
  return guarded(c, "ivr_volume_from_json", [&] {
    checked(c, Kind::context, "context");
    not_null(json, "json");
    not_null(out, "volume");
    *out = nullptr;
    auto v = std::make_unique<ivr_volume>();
    v->volume = ivr::parse_volume(json, base_dir ? base_dir : ".");
    *out = publish(std::move(v), c, Kind::volume);
  });
}

ivr_status ivr_volume_retain(ivr_volume* v) {
  return retain(v, Kind::volume, "ivr_volume_retain");
}
ivr_status ivr_volume_release(ivr_volume* v) {
  return release(v, Kind::volume, "ivr_volume_release");
}

ivr_status ivr_volume_shape(const ivr_volume* v, int64_t shape[3]) {
  return guarded(context_of(v), "ivr_volume_shape", [&] {
    checked(v, Kind::volume, "volume");
    write_shape(v->volume, not_null(shape, "shape"));
  });
}

ivr_status ivr_volume_data(const ivr_volume* v, float* values, size_t capacity) {
  return guarded(context_of(v), "ivr_volume_data", [&] {
    checked(v, Kind::volume, "volume");
    not_null(values, "values");
    const std::vector<float>& d = v->volume.data;
    if (capacity < d.size())
      throw CError{IVR_ERROR_BUFFER_TOO_SMALL, "values hold " + std::to_string(capacity) +
                                                   "; the volume has " + std::to_string(d.size())};
    std::memcpy(values, d.data(), d.size() * sizeof(float));
  });
}

ivr_status ivr_scene_set_volume_handle(ivr_scene* s, const ivr_volume* v) {
  return guarded(context_of(s), "ivr_scene_set_volume_handle", [&] {
    checked(s, Kind::scene, "scene");
    checked(v, Kind::volume, "volume");
    same_context(v->context, s->context, "volume");
    replace_volume(s, v->volume);
  });
}

ivr_status ivr_tf_from_json(ivr_context* c, const char* json, ivr_transfer_function** out) {
  return guarded(c, "ivr_tf_from_json", [&] {
    checked(c, Kind::context, "context");
    not_null(json, "json");
    not_null(out, "tf");
    *out = nullptr;
    auto t = std::make_unique<ivr_transfer_function>();
    t->tf = ivr::parse_tf(json);
    *out = publish(std::move(t), c, Kind::tf);
  });
}

ivr_status ivr_tf_retain(ivr_transfer_function* t) {
  return retain(t, Kind::tf, "ivr_tf_retain");
}
ivr_status ivr_tf_release(ivr_transfer_function* t) {
  return release(t, Kind::tf, "ivr_tf_release");
}

ivr_status ivr_scene_set_tf(ivr_scene* s, const ivr_transfer_function* t) {
  return guarded(context_of(s), "ivr_scene_set_tf", [&] {
    checked(s, Kind::scene, "scene");
    checked(t, Kind::tf, "tf");
    same_context(t->context, s->context, "tf");
    s->scene.tf = t->tf;
  });
}

ivr_status ivr_scene_set_rays(ivr_scene* s, const double* values, size_t rows, int columns) {
  return guarded(context_of(s), "ivr_scene_set_rays", [&] {
    checked(s, Kind::scene, "scene");
    not_null(values, "values");
    ivr::RayList rays = ivr::make_ray_list(values, rows, columns);
    s->scene.cameras.clear();
    s->scene.rays = std::move(rays);
  });
}

ivr_status ivr_scene_ray_count(const ivr_scene* s, size_t* rays) {
  return guarded(context_of(s), "ivr_scene_ray_count", [&] {
    checked(s, Kind::scene, "scene");
    *not_null(rays, "rays") = s->scene.rays.count();
  });
}

}  // extern "C"
