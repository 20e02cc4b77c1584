// ivr/scene.hpp — the host-side scene: volume, box, optical model, transfer function, cameras,
// integrator and background, with the exact conventions of docs/design.md.
#pragma once
#include <cstdint>
#include <functional>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "ivr/export.h"

namespace ivr {

// Densities of shape (nz, ny, nx), x fastest; values sit at cell centres.
struct Volume {
  int nx = 0, ny = 0, nz = 0;
  std::vector<float> data;
  glm::dvec3 spacing{1.0, 1.0, 1.0};  // physical voxel size; only shapes the default box
  std::size_t voxel_count() const { return std::size_t(nx) * ny * nz; }
  float at(int x, int y, int z) const { return data[(std::size_t(z) * ny + y) * nx + x]; }
};

enum class Model { absorption, emission_absorption };
enum class TfKind { identity, piecewise_linear, table, gaussian };

struct TfPoint {
  double density = 0;
  glm::dvec3 color{0.0};
  double extinction = 0;
};

struct TfGaussian {
  double mean = 0, width = 1;
  glm::dvec3 color{1.0};
  double extinction = 0;
};

// sigma(d) and colour(d); which fields are used depends on kind (see docs/design.md).
struct TransferFunction {
  TfKind kind = TfKind::identity;
  double extinction_scale = 1.0, color_scale = 1.0;  // identity
  std::vector<TfPoint> points;                       // piecewise_linear, sorted by density
  glm::dvec2 range{0.0, 1.0};                        // table
  std::vector<glm::dvec4> entries;                   // table rows [r, g, b, sigma]
  std::vector<TfGaussian> gaussians;                 // gaussian
};

enum class Projection { perspective, orthographic };

struct Camera {
  glm::dvec3 eye{0.0, 0.0, 2.0}, target{0.0}, up{0.0, 1.0, 0.0};
  double fov_y = 40.0;  // full vertical angle in degrees (perspective)
  Projection projection = Projection::perspective;
  double ortho_height = 1.0;  // world units (orthographic)
  int width = 256, height = 256;
};

// A list of rays, each with its own origin, direction and interval (docs/design.md, "Ray lists"):
// the geometry of a scene beside cameras — sightlines to stars, sensor lines, detector pairs. Row i
// of `values` is ray i: origin (x, y, z), unit direction (x, y, z), t_start, t_end, in world units
// along the direction (t_start may be −∞: from the box entry; t_end +∞: to the box exit). Make
// one with make_ray_list(), which checks and normalises; what a scene with rays renders is one
// value (absorption) or four (emission–absorption) per ray, shape (rays, channels).
struct RayList {
  static constexpr int kColumns = 8;
  std::vector<double> values;  // (count, 8), row-major
  std::size_t count() const { return values.size() / kColumns; }
  bool empty() const { return values.empty(); }
};

// The ray list of `rows` rows of `columns` values, row-major: 8 (ox oy oz dx dy dz t_start t_end)
// or 6 (start and end points: origin = start, t in [0, |end − start|]; start = end is a ray of
// length 0, which adds nothing). Directions are normalised unless their length is within 1e-6 of
// 1 (then kept as given, so that rays built in float32 stay those bits). Throws
// Error(invalid_argument) naming the first bad ray and field (`where`[i].field): a zero or
// non-finite direction, NaN anywhere, an infinite origin or point, t_end < t_start, t_start = +∞
// or t_end = −∞, no rows, more than 2^31 − 1 rows, another column count.
IVR_API RayList make_ray_list(const double* values, std::size_t rows, int columns,
                              const std::string& where = "rays");
// The rays of every pixel of `camera`, row by row (pixel (x, y) is row y·width + x), from t = 0 to
// the box exit: computed in float32 (or float64 where `f64`) exactly as the kernels compute the
// camera's own rays, so that rendering the list gives the camera's image bit for bit.
IVR_API RayList ray_list_of_camera(const Camera& camera, bool f64 = false);

// How each ray's integral is evaluated (docs/design.md, docs/integrators.md):
//   midpoint       n = ceil(L/step) equal segments, one sample at each segment's midpoint
//   trapezoid      the same segments, samples at their ends: the trapezoid rule for the optical
//                  depth, the segment's emission from its two ends' average
//   exact          absorption only: the ray is split where it crosses the planes through voxel
//                  centres and where the density crosses a TF control point; the integral of
//                  each piece is exact (no step; TFs piecewise linear in density)
//   preintegrated  the midpoint's segments with samples at their ends, the density linear in
//                  between, integrated exactly through the TF (TFs piecewise linear in density)
enum class Scheme { midpoint, trapezoid, exact, preintegrated };

struct Integrator {
  Scheme scheme = Scheme::midpoint;
  double step = 0.5;                // in units of the smallest voxel edge
  double min_transmittance = 1e-4;  // early ray termination threshold; 0 turns it off
  // > 0: the step is chosen from an a-priori estimate so that the image's error stays below this
  // (absolute, per pixel channel; see ivr::choose_step); `step` is then ignored.
  double tolerance = 0;
};

IVR_API const char* scheme_name(Scheme scheme);
// The scheme named `name`; throws ivr::Error(invalid_argument) naming `where` and the known ones.
IVR_API Scheme parse_scheme(const std::string& name,
                            const std::string& where = "integrator.scheme");

struct Scene {
  Volume volume;
  glm::dvec3 box_min{-0.5}, box_max{0.5};
  Model model = Model::emission_absorption;
  TransferFunction tf;
  std::optional<glm::dvec3> background;  // unset: 1 (absorption I_in) or black (emission)
  std::vector<Camera> cameras;
  RayList rays;  // non-empty: the scene's rays are these (and it has no cameras)
  Integrator integrator;

  glm::dvec3 effective_background() const {
    return background ? *background : glm::dvec3(model == Model::absorption ? 1.0 : 0.0);
  }
  // h = (box_max - box_min) / (nx, ny, nz)
  glm::dvec3 voxel_size() const {
    return (box_max - box_min) / glm::dvec3(volume.nx, volume.ny, volume.nz);
  }
  int channels() const { return model == Model::absorption ? 1 : 4; }
  bool has_ray_list() const { return !rays.empty(); }
};

// What a scene renders, as views × rows × columns of pixels: its cameras', or for a ray list one
// view of one row of its rays (the layout sessions and kernels use; images of ray lists are shaped
// (rays, channels) where users see them).
struct ImageExtent {
  int views = 0, height = 0, width = 0;
  std::size_t pixels() const { return std::size_t(views) * std::size_t(height) * std::size_t(width); }
};
IVR_API ImageExtent image_extent(const Scene& scene);

// Data parallelism over views (several devices, MPI ranks; docs/scaling.md): contiguous shares
// (first, count) of n views or rays over `parts` workers, as equal as can be, empty ones dropped;
// and the scene of views (a ray list: rays) [first, first + count).
IVR_API std::vector<std::pair<std::size_t, std::size_t>> view_shares(std::size_t n,
                                                                     std::size_t parts);
// The same in proportion to `weights` (each > 0 and finite, else Error(invalid_argument)): one
// share per weight, in order, empty ones kept (count 0) — share i holds n·wᵢ / Σw views, the
// remainders going to the largest fractions (ties to the lower index), so that equal weights give
// view_shares(n, parts)'s counts. The split depends on the weights alone, never on timing.
IVR_API std::vector<std::pair<std::size_t, std::size_t>> view_shares(
    std::size_t n, const std::vector<double>& weights);
// The same where every share must hold a view (MPI ranks: each rank takes part in every
// collective of the operation): view_shares(n, weights), or where that leaves a share empty and
// n >= weights.size(), one view each and the other n - weights.size() in proportion to the
// weights. n < weights.size(): one view each to the first n, the others empty (the equal split's).
IVR_API std::vector<std::pair<std::size_t, std::size_t>> view_shares_each(
    std::size_t n, const std::vector<double>& weights);
IVR_API Scene scene_share(const Scene& scene, std::size_t first, std::size_t count);
// The views of a scene, or a ray list's rays: what view_shares() splits.
IVR_API std::size_t share_items(const Scene& scene);

// Box centred at the origin, longest side 1, proportional to dims x spacing.
IVR_API void set_default_box(Scene& scene);

// Built-in test volumes of any size, sampled at cell centres over [-1, 1] on each axis: "sphere"
// (a smooth ball with a soft shell), "marschner_lobb" (the classic band-limited test signal,
// f_M = 6, alpha = 0.25), both in [0, 1]; "shepp_logan" (ivr/phantom.hpp's 3D Shepp–Logan,
// skull 2.0, brain 1.02; non-cubic dims stretch it) and "zeros" (for scenes that need only the
// grid's shape, e.g. tomography).
IVR_API Volume synthetic_volume(const std::string& name, int nx, int ny, int nz);

// Throws ivr::Error(invalid_argument) naming the first problem: sizes, cameras, TF, step, data.
IVR_API void validate(const Scene& scene);
IVR_API void validate_tf(const TransferFunction& tf);

// Reads a scene file (docs/design.md's JSON); relative volume paths resolve against its folder.
IVR_API Scene load_scene(const std::string& path);
// The same with only planes [first, last] of the volume, chosen from its nz (a domain worker's
// slab, e.g. domain_slab): volume keeps its dims and data holds those planes — domain_share()'s
// convention, what render_domain() and gradient_domain() take. .npy and raw volume files read
// only those planes (VolumeSource::planes); other formats and synthetic volumes are cut.
IVR_API Scene load_scene(const std::string& path,
                         const std::function<std::pair<int, int>(int nz)>& planes);
// Parses scene JSON text; `base_dir` resolves relative paths; `where` names the source in errors.
IVR_API Scene parse_scene(const std::string& json_text, const std::string& base_dir,
                          const std::string& where = "scene");
// A scene's "volume" or "tf" object on its own (the C API's volume and TF handles).
IVR_API Volume parse_volume(const std::string& json_text, const std::string& base_dir,
                            const std::string& where = "volume");
IVR_API TransferFunction parse_tf(const std::string& json_text, const std::string& where = "tf");
// A "cameras" array (cameras and orbits) and an "integrator" object on their own (sessions'
// setters from bindings); checked as far as they go alone (a session checks them with its scene).
IVR_API std::vector<Camera> parse_cameras(const std::string& json_text,
                                          const std::string& where = "cameras");
IVR_API Integrator parse_integrator(const std::string& json_text,
                                    const std::string& where = "integrator");

// A TF or a camera as the scene file's JSON object (parse_tf / a "cameras" entry read them back
// exactly): what reconstructions and `ivr viewpoint` write.
IVR_API std::string tf_json(const TransferFunction& tf);
IVR_API std::string camera_json(const Camera& camera);

}  // namespace ivr
