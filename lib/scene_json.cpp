// scene_json.cpp — scene files: DESIGN.md's JSON, exact field names, unknown keys and values
// rejected with the path of the offending field.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "files.hpp"
#include "ivr/error.hpp"
#include "ivr/scene.hpp"
#include "ivr/volume_io.hpp"

using nlohmann::json;
namespace fs = std::filesystem;

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

Volume read_volume(const Reader& r, const json& j, const std::string& base_dir) {
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
  return load_volume(src);
}

TransferFunction read_tf(const Reader& r, const json& j) {
  TransferFunction tf;
  if (!j.is_object() || !j.contains("type")) r.fail("tf", "needs a 'type'");
  const std::string type = r.string(j["type"], "tf.type");
  if (type == "identity") {
    r.only_keys(j, "tf", {"type", "extinction_scale", "color_scale"});
    tf.kind = TfKind::identity;
    if (j.contains("extinction_scale"))
      tf.extinction_scale = r.number(j["extinction_scale"], "tf.extinction_scale");
    if (j.contains("color_scale")) tf.color_scale = r.number(j["color_scale"], "tf.color_scale");
  } else if (type == "piecewise_linear") {
    r.only_keys(j, "tf", {"type", "points"});
    tf.kind = TfKind::piecewise_linear;
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
  } else if (type == "table") {
    r.only_keys(j, "tf", {"type", "range", "entries"});
    tf.kind = TfKind::table;
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
  } else if (type == "gaussian") {
    r.only_keys(j, "tf", {"type", "gaussians"});
    tf.kind = TfKind::gaussian;
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
  } else {
    r.fail("tf.type", "unknown transfer function type '" + type +
                          "' (known: identity, piecewise_linear, table, gaussian)");
  }
  return tf;
}

Camera read_camera(const Reader& r, const json& j, const std::string& p) {
  r.only_keys(j, p,
              {"eye", "target", "up", "fov_y", "projection", "ortho_height", "width", "height"});
  Camera c;
  if (j.contains("eye")) c.eye = r.vec3(j["eye"], p + ".eye");
  if (j.contains("target")) c.target = r.vec3(j["target"], p + ".target");
  if (j.contains("up")) c.up = r.vec3(j["up"], p + ".up");
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
  return c;
}

json parse_json(const std::string& text, const std::string& where) {
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    // e.what() reads "[json.exception.parse_error.101] parse error at line 3, column 5: ..."
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

Scene parse_scene(const std::string& text, const std::string& base_dir, const std::string& where) {
  const json j = parse_json(text, where);
  const Reader r(where);
  r.only_keys(j, "", {"volume", "box", "model", "tf", "background", "cameras", "integrator"});
  Scene s;
  if (!j.contains("volume")) r.fail("volume", "a scene needs a volume");
  try {
    s.volume = read_volume(r, j["volume"], base_dir);
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
  if (!j.contains("cameras")) r.fail("cameras", "a scene needs at least one camera");
  const json& cams = r.array(j["cameras"], "cameras");
  for (std::size_t i = 0; i < cams.size(); ++i)
    s.cameras.push_back(read_camera(r, cams[i], "cameras[" + std::to_string(i) + "]"));
  if (j.contains("integrator")) {
    const json& it = j["integrator"];
    r.only_keys(it, "integrator", {"scheme", "step", "min_transmittance", "tolerance"});
    if (it.contains("scheme")) {
      const std::string name = r.string(it["scheme"], "integrator.scheme");
      try {
        s.integrator.scheme = parse_scheme(name);
      } catch (const Error& e) {
        throw Error(e.status(), where + ": " + e.what());
      }
    }
    if (it.contains("tolerance"))
      s.integrator.tolerance = r.number(it["tolerance"], "integrator.tolerance");
    if (it.contains("step")) s.integrator.step = r.number(it["step"], "integrator.step");
    if (it.contains("min_transmittance"))
      s.integrator.min_transmittance =
          r.number(it["min_transmittance"], "integrator.min_transmittance");
  }
  try {
    validate(s);
  } catch (const Error& e) {
    throw Error(e.status(), where + ": " + e.what());
  }
  return s;
}

Scene load_scene(const std::string& path) {
  return parse_scene(read_text_file(path, "scene file"), parent_dir(path), path);
}

}  // namespace ivr
