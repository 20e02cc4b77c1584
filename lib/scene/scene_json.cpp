// scene_json.cpp — scene files: docs/design.md's JSON, exact field names, unknown keys and values
// rejected with the path of the offending field.
#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <set>

#include "io/files.hpp"
#include "io/npy.hpp"
#include "ivr/error.hpp"
#include "ivr/scene.hpp"
#include "ivr/volume_io.hpp"

using nlohmann::json;
namespace fs = std::filesystem;
#include "scene/scene.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr {

namespace {

// Reads fields with the JSON path in every error, e.g. "cameras[0].fov_y: expected a number".
class Reader {
 public:
  explicit Reader(std::string where) : where_(std::move(where)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw Error(Status::invalid_argument, where_ + ": " + path + ": " + what);
  }

  void only_keys(const json& obj, const std::string& path,
                 std::initializer_list<const char*> keys) const {
    if (!obj.is_object()) fail(path, "expected an object");
    const std::set<std::string> known(keys.begin(), keys.end());
    for (const auto& item : obj.items())
      if (!known.count(item.key())) {
        std::string list;
        for (const char* k : keys) list += (list.empty() ? "" : ", ") + std::string(k);
        fail(path.empty() ? item.key() : path + "." + item.key(),
             "unknown key (known: " + list + ")");
      }
  }

  double number(const json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, "expected a number");
    return j.get<double>();
  }

  int integer(const json& j, const std::string& path) const {
    if (!j.is_number_integer() &&
        !(j.is_number() && j.get<double>() == std::floor(j.get<double>())))
      fail(path, "expected an integer");
    const double v = j.get<double>();
    if (v < -2147483648.0 || v > 2147483647.0) fail(path, "integer out of range");
    return int(v);
  }

  std::string string(const json& j, const std::string& path) const {
    if (!j.is_string()) fail(path, "expected a string");
    return j.get<std::string>();
  }

  std::vector<double> numbers(const json& j, const std::string& path, std::size_t n) const {
    if (!j.is_array() || j.size() != n)
      fail(path, "expected an array of " + std::to_string(n) + " numbers");
    std::vector<double> out;
    for (std::size_t i = 0; i < n; ++i)
      out.push_back(number(j[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }

  glm::dvec3 vec3(const json& j, const std::string& path) const {
    const auto v = numbers(j, path, 3);
    return {v[0], v[1], v[2]};
  }

  const json& array(const json& j, const std::string& path) const {
    if (!j.is_array()) fail(path, "expected an array");
    return j;
  }

 private:
  std::string where_;
};

// `planes` (where given) chooses the z planes to keep (VolumeSource::planes).
Volume read_volume(const Reader& r, const json& j, const std::string& base_dir,
                   const std::function<std::pair<int, int>(int nz)>& planes = {}) {
  r.only_keys(j, "volume",
              {"file", "format", "dims", "type", "endian", "range", "spacing", "synthetic"});
  if (j.contains("synthetic")) {
    if (j.contains("file")) r.fail("volume", "give either 'file' or 'synthetic', not both");
    const json dims = j.contains("dims") ? j["dims"] : json::array({64, 64, 64});
    const auto d = r.numbers(dims, "volume.dims", 3);
    for (int i = 0; i < 3; ++i)
      if (d[i] < 1 || d[i] > 4096 || d[i] != std::floor(d[i]))
        r.fail("volume.dims", "each dim must be an integer in 1..4096");
    Volume v = synthetic_volume(r.string(j["synthetic"], "volume.synthetic"), int(d[0]), int(d[1]),
                                int(d[2]));
    if (j.contains("spacing")) v.spacing = r.vec3(j["spacing"], "volume.spacing");
    if (planes) {  // (generated whole, then cut)
      const auto [first, last] = planes(v.nz);
      if (first < 0 || last < first || last >= v.nz)
        r.fail("volume", "planes " + std::to_string(first) + ".." + std::to_string(last) + " of " +
                             std::to_string(v.nz));
      const std::size_t plane = std::size_t(v.nx) * v.ny;
      v.data = std::vector<float>(v.data.begin() + std::ptrdiff_t(plane * first),
                                  v.data.begin() + std::ptrdiff_t(plane * (last + 1)));
    }
    return v;
  }
  if (!j.contains("file")) r.fail("volume", "needs 'file' (or 'synthetic')");
  VolumeSource src;
  const fs::path file = r.string(j["file"], "volume.file");
  src.path = file.is_absolute() ? file.string() : (fs::path(base_dir) / file).string();
  if (j.contains("format")) src.format = r.string(j["format"], "volume.format");
  if (j.contains("dims")) {
    const auto d = r.numbers(j["dims"], "volume.dims", 3);
    for (int i = 0; i < 3; ++i)
      if (d[i] < 1 || d[i] != std::floor(d[i]) || d[i] > 1e6)
        r.fail("volume.dims", "each dim must be a positive integer");
    src.dims = glm::ivec3(int(d[0]), int(d[1]), int(d[2]));
  }
  if (j.contains("type")) src.type = r.string(j["type"], "volume.type");
  if (j.contains("endian")) src.endian = r.string(j["endian"], "volume.endian");
  if (j.contains("range")) {
    const auto v = r.numbers(j["range"], "volume.range", 2);
    src.range = glm::dvec2(v[0], v[1]);
  }
  if (j.contains("spacing")) src.spacing = r.vec3(j["spacing"], "volume.spacing");
  src.planes = planes;
  return load_volume(src);
}

TransferFunction read_tf(const Reader& r, const json& j) {
  TransferFunction tf;
  if (!j.is_object() || !j.contains("type")) r.fail("tf", "needs a 'type'");
  const std::string type = r.string(j["type"], "tf.type");
  const TfKindInfo* kind = find_tf_kind(type);
  if (!kind)
    r.fail("tf.type",
           "unknown transfer function type '" + type + "' (known: " + tf_kind_names() + ")");
  tf.kind = kind->kind;
  if (tf.kind == TfKind::identity) {
    r.only_keys(j, "tf", {"type", "extinction_scale", "color_scale"});
    if (j.contains("extinction_scale"))
      tf.extinction_scale = r.number(j["extinction_scale"], "tf.extinction_scale");
    if (j.contains("color_scale")) tf.color_scale = r.number(j["color_scale"], "tf.color_scale");
  } else if (tf.kind == TfKind::piecewise_linear) {
    r.only_keys(j, "tf", {"type", "points"});
    if (!j.contains("points")) r.fail("tf", "piecewise_linear needs 'points'");
    const json& pts = r.array(j["points"], "tf.points");
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const std::string p = "tf.points[" + std::to_string(i) + "]";
      r.only_keys(pts[i], p, {"density", "color", "extinction"});
      for (const char* k : {"density", "color", "extinction"})
        if (!pts[i].contains(k)) r.fail(p, std::string("missing '") + k + "'");
      tf.points.push_back({r.number(pts[i]["density"], p + ".density"),
                           r.vec3(pts[i]["color"], p + ".color"),
                           r.number(pts[i]["extinction"], p + ".extinction")});
    }
  } else if (tf.kind == TfKind::table) {
    r.only_keys(j, "tf", {"type", "range", "entries"});
    if (!j.contains("entries")) r.fail("tf", "table needs 'entries'");
    if (j.contains("range")) {
      const auto v = r.numbers(j["range"], "tf.range", 2);
      tf.range = {v[0], v[1]};
    }
    const json& rows = r.array(j["entries"], "tf.entries");
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto v = r.numbers(rows[i], "tf.entries[" + std::to_string(i) + "]", 4);
      tf.entries.emplace_back(v[0], v[1], v[2], v[3]);
    }
  } else {  // gaussian
    r.only_keys(j, "tf", {"type", "gaussians"});
    if (!j.contains("gaussians")) r.fail("tf", "gaussian needs 'gaussians'");
    const json& gs = r.array(j["gaussians"], "tf.gaussians");
    for (std::size_t i = 0; i < gs.size(); ++i) {
      const std::string p = "tf.gaussians[" + std::to_string(i) + "]";
      r.only_keys(gs[i], p, {"mean", "width", "color", "extinction"});
      for (const char* k : {"mean", "width", "color", "extinction"})
        if (!gs[i].contains(k)) r.fail(p, std::string("missing '") + k + "'");
      tf.gaussians.push_back(
          {r.number(gs[i]["mean"], p + ".mean"), r.number(gs[i]["width"], p + ".width"),
           r.vec3(gs[i]["color"], p + ".color"), r.number(gs[i]["extinction"], p + ".extinction")});
    }
  }
  return tf;
}

// The keys a camera and an orbit share: projection and image size.
void read_lens(const Reader& r, const json& j, const std::string& p, Camera& c) {
  if (j.contains("fov_y")) c.fov_y = r.number(j["fov_y"], p + ".fov_y");
  if (j.contains("ortho_height")) c.ortho_height = r.number(j["ortho_height"], p + ".ortho_height");
  if (j.contains("width")) c.width = r.integer(j["width"], p + ".width");
  if (j.contains("height")) c.height = r.integer(j["height"], p + ".height");
  if (j.contains("projection")) {
    const std::string proj = r.string(j["projection"], p + ".projection");
    if (proj == "perspective")
      c.projection = Projection::perspective;
    else if (proj == "orthographic")
      c.projection = Projection::orthographic;
    else
      r.fail(p + ".projection",
             "unknown projection '" + proj + "' (known: perspective, orthographic)");
  }
}

Camera read_camera(const Reader& r, const json& j, const std::string& p) {
  r.only_keys(j, p,
              {"eye", "target", "up", "fov_y", "projection", "ortho_height", "width", "height"});
  Camera c;
  if (j.contains("eye")) c.eye = r.vec3(j["eye"], p + ".eye");
  if (j.contains("target")) c.target = r.vec3(j["target"], p + ".target");
  if (j.contains("up")) c.up = r.vec3(j["up"], p + ".up");
  read_lens(r, j, p, c);
  return c;
}

// {"orbit": {...}}: `views` cameras on a circle of `radius` about `axis` through `target`, camera
// k at angle start + k·arc/views (degrees), counter-clockwise seen from the axis's tip, each
// looking at the target with up = axis. Angle 0 is e1 = the unit part of +x orthogonal to the
// axis (of +y when the axis is within ~26° of x), e2 = axis × e1: for axis z, e1 = +x, e2 = +y.
void read_orbit(const Reader& r, const json& j, const std::string& where,
                std::vector<Camera>& out) {
  r.only_keys(j, where, {"orbit"});
  const std::string p = where + ".orbit";
  const json& o = j["orbit"];
  r.only_keys(o, p,
              {"views", "radius", "target", "axis", "start", "arc", "projection", "ortho_height",
               "fov_y", "width", "height"});
  if (!o.contains("views")) r.fail(p, "needs 'views' (the number of cameras)");
  const json& vj = o["views"];
  if (!vj.is_number() || vj.get<double>() < 1 || vj.get<double>() != std::floor(vj.get<double>()))
    r.fail(p + ".views", "expected an integer >= 1");
  if (vj.get<double>() > 100000) r.fail(p + ".views", "at most 100000 views");
  const int views = int(vj.get<double>());
  const double radius = o.contains("radius") ? r.number(o["radius"], p + ".radius") : 2.0;
  if (!(radius > 0) || !std::isfinite(radius)) r.fail(p + ".radius", "must be > 0 and finite");
  const glm::dvec3 target =
      o.contains("target") ? r.vec3(o["target"], p + ".target") : glm::dvec3(0);
  glm::dvec3 axis = o.contains("axis") ? r.vec3(o["axis"], p + ".axis") : glm::dvec3(0, 0, 1);
  const double len = glm::length(axis);
  if (!(len > 0) || !std::isfinite(len)) r.fail(p + ".axis", "must be a non-zero finite vector");
  axis /= len;
  const double start = o.contains("start") ? r.number(o["start"], p + ".start") : 0.0;
  const double arc = o.contains("arc") ? r.number(o["arc"], p + ".arc") : 360.0;
  if (!std::isfinite(start)) r.fail(p + ".start", "must be finite");
  if (!std::isfinite(arc)) r.fail(p + ".arc", "must be finite");
  const glm::dvec3 helper = std::abs(axis.x) > 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 e1 = glm::normalize(helper - glm::dot(helper, axis) * axis);
  const glm::dvec3 e2 = glm::cross(axis, e1);
  Camera lens;
  read_lens(r, o, p, lens);
  constexpr double kPi = 3.14159265358979323846;
  for (int k = 0; k < views; ++k) {
    const double theta = (start + k * arc / views) * kPi / 180.0;
    Camera c = lens;
    c.target = target;
    c.eye = target + radius * (std::cos(theta) * e1 + std::sin(theta) * e2);
    c.up = axis;
    out.push_back(c);
  }
}

// A "cameras" array: cameras and orbits, in order.
std::vector<Camera> read_cameras(const Reader& r, const json& j) {
  std::vector<Camera> out;
  const json& cams = r.array(j, "cameras");
  for (std::size_t i = 0; i < cams.size(); ++i) {
    const std::string p = "cameras[" + std::to_string(i) + "]";
    if (cams[i].is_object() && cams[i].contains("orbit"))
      read_orbit(r, cams[i], p, out);
    else
      out.push_back(read_camera(r, cams[i], p));
  }
  return out;
}

Integrator read_integrator(const Reader& r, const json& it, const std::string& where) {
  Integrator out;
  r.only_keys(it, "integrator", {"scheme", "step", "min_transmittance", "tolerance"});
  if (it.contains("scheme")) {
    const std::string name = r.string(it["scheme"], "integrator.scheme");
    try {
      out.scheme = parse_scheme(name);
    } catch (const Error& e) {
      throw Error(e.status(), where + ": " + e.what());
    }
  }
  if (it.contains("tolerance")) out.tolerance = r.number(it["tolerance"], "integrator.tolerance");
  if (it.contains("step")) out.step = r.number(it["step"], "integrator.step");
  if (it.contains("min_transmittance"))
    out.min_transmittance = r.number(it["min_transmittance"], "integrator.min_transmittance");
  return out;
}

json parse_json(const std::string& text, const std::string& where) {
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    // e.what() reads "[json.exception.parse_error.101] parse error at line 3, column 5: ..." —
    // or, for a number too large for a double ("1e999"), out_of_range.406 "number overflow
    // parsing '1e999'" (found by fuzzing: tests/fuzz/regressions/).
    std::string what = e.what();
    const std::size_t cut = what.find("] ");
    throw Error(Status::io, where + ": malformed JSON: " +
                                (cut == std::string::npos ? what : what.substr(cut + 2)));
  }
}

}  // namespace

Volume parse_volume(const std::string& text, const std::string& base_dir,
                    const std::string& where) {
  const Reader r(where);
  return read_volume(r, parse_json(text, where), base_dir);
}

TransferFunction parse_tf(const std::string& text, const std::string& where) {
  const Reader r(where);
  TransferFunction tf = read_tf(r, parse_json(text, where));
  try {
    validate_tf(tf);
  } catch (const Error& e) {
    throw Error(e.status(), where + ": " + e.what());
  }
  return tf;
}

std::vector<Camera> parse_cameras(const std::string& text, const std::string& where) {
  const Reader r(where);
  return read_cameras(r, parse_json(text, where));
}

Integrator parse_integrator(const std::string& text, const std::string& where) {
  const Reader r(where);
  return read_integrator(r, parse_json(text, where), where);
}

// A "rays" entry: {"file": "rays.npy"} holding an (R, 8) or (R, 6) array of any real or integer
// dtype, or the rows inline ([[ox, oy, oz, dx, dy, dz, t0, t1], …], "inf"/"-inf" as strings
// where an end is infinite).
RayList read_rays(const Reader& r, const json& j, const std::string& base_dir,
                  const std::string& where) {
  std::vector<double> values;
  std::size_t rows = 0;
  int columns = 0;
  if (j.is_object()) {
    r.only_keys(j, "rays", {"file"});
    if (!j.contains("file")) r.fail("rays", "needs 'file' (an .npy of shape (rays, 8) or (rays, 6))");
    if (!j["file"].is_string()) r.fail("rays.file", "expected a string");
    const fs::path file(j["file"].get<std::string>());
    const std::string path = file.is_absolute() ? file.string() : (fs::path(base_dir) / file).string();
    const volfile::TypedArray a = volfile::read_npy(path);
    if (a.shape.size() != 2 || (a.shape[1] != 8 && a.shape[1] != 6))
      r.fail("rays.file", path + " holds an array of " + std::to_string(a.shape.size()) +
                              " dimensions " + (a.shape.size() == 2 ? "with " + std::to_string(a.shape[1]) + " columns" : "") +
                              "; rays are (rays, 8) or (rays, 6)");
    rows = a.shape[0];
    columns = int(a.shape[1]);
    values.resize(rows * std::size_t(columns));
    volfile::for_each_value(a, values.size(), [&](std::size_t i, double v) { values[i] = v; });
  } else if (j.is_array()) {
    rows = j.size();
    for (std::size_t i = 0; i < rows; ++i) {
      const std::string at = "rays[" + std::to_string(i) + "]";
      if (!j[i].is_array() || (j[i].size() != 8 && j[i].size() != 6))
        r.fail(at, "expected 8 numbers (ox oy oz dx dy dz t_start t_end) or 6 (start, end)");
      if (i == 0) columns = int(j[i].size());
      if (int(j[i].size()) != columns)
        r.fail(at, "has " + std::to_string(j[i].size()) + " numbers; rays[0] has " +
                       std::to_string(columns));
      for (std::size_t k = 0; k < j[i].size(); ++k) {
        const json& v = j[i][k];
        if (v.is_string() && (v == "inf" || v == "-inf"))
          values.push_back(v == "inf" ? INFINITY : -INFINITY);
        else
          values.push_back(r.number(v, at + "[" + std::to_string(k) + "]"));
      }
    }
  } else {
    r.fail("rays", "expected {\"file\": \"rays.npy\"} or an array of rays");
  }
  return make_ray_list(values.data(), rows, columns, where + ": rays");
}

Scene parse_scene(const std::string& text, const std::string& base_dir, const std::string& where,
                  const std::function<std::pair<int, int>(int nz)>& planes) {
  const json j = parse_json(text, where);
  const Reader r(where);
  r.only_keys(j, "",
              {"volume", "box", "model", "tf", "background", "cameras", "rays", "integrator"});
  Scene s;
  if (!j.contains("volume")) r.fail("volume", "a scene needs a volume");
  try {
    s.volume = read_volume(r, j["volume"], base_dir, planes);
  } catch (const Error& e) {
    if (e.status() != Status::invalid_argument && e.status() != Status::io) throw;
    const std::string msg = e.what();
    throw Error(e.status(), msg.rfind(where + ":", 0) == 0 ? msg : where + ": volume: " + msg);
  }
  if (j.contains("model")) {
    const std::string m = r.string(j["model"], "model");
    if (m == "absorption")
      s.model = Model::absorption;
    else if (m == "emission_absorption")
      s.model = Model::emission_absorption;
    else
      r.fail("model", "unknown optical model '" + m + "' (known: absorption, emission_absorption)");
  }
  if (j.contains("box")) {
    r.only_keys(j["box"], "box", {"min", "max"});
    if (!j["box"].contains("min") || !j["box"].contains("max"))
      r.fail("box", "needs 'min' and 'max'");
    s.box_min = r.vec3(j["box"]["min"], "box.min");
    s.box_max = r.vec3(j["box"]["max"], "box.max");
  } else {
    set_default_box(s);
  }
  if (j.contains("tf")) s.tf = read_tf(r, j["tf"]);
  if (j.contains("background")) {
    const json& b = j["background"];
    if (b.is_number())
      s.background = glm::dvec3(b.get<double>());
    else if (b.is_array() && b.size() == 1)
      s.background = glm::dvec3(r.number(b[0], "background[0]"));
    else
      s.background = r.vec3(b, "background");
  }
  if (j.contains("rays")) {
    if (j.contains("cameras")) r.fail("rays", "a scene has cameras or rays, not both");
    s.rays = read_rays(r, j["rays"], base_dir, where);
  } else {
    if (!j.contains("cameras")) r.fail("cameras", "a scene needs cameras (or rays)");
    s.cameras = read_cameras(r, j["cameras"]);
  }
  if (j.contains("integrator")) s.integrator = read_integrator(r, j["integrator"], where);
  try {
    if (planes)  // (the densities read were checked as they were read; they are a slab's)
      validate_description(s, s.integrator);
    else
      validate(s);
  } catch (const Error& e) {
    throw Error(e.status(), where + ": " + e.what());
  }
  return s;
}

Scene parse_scene(const std::string& text, const std::string& base_dir, const std::string& where) {
  return parse_scene(text, base_dir, where, {});
}

Scene load_scene(const std::string& path) {
  return parse_scene(read_text_file(path, "scene file"), parent_dir(path), path, {});
}

Scene load_scene(const std::string& path, const std::function<std::pair<int, int>(int nz)>& planes) {
  return parse_scene(read_text_file(path, "scene file"), parent_dir(path), path, planes);
}

}  // namespace ivr
