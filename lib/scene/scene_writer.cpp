// scene_writer.cpp — the inverse of scene_json.cpp for what reconstructions produce: a TF and a
// camera as docs/design.md's JSON objects (doubles written to round-trip exactly), and a Volume as NRRD.
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/files.hpp"
#include "ivr/error.hpp"
#include "ivr/scene.hpp"
#include "ivr/volume_io.hpp"
#include "scene/tf_kinds.hpp"

namespace ivr {

namespace {
using nlohmann::json;
json vec(const glm::dvec3& v) {
  return json::array({v.x, v.y, v.z});
}
}  // namespace

std::string tf_json(const TransferFunction& tf) {
  json j;
  switch (tf.kind) {
    case TfKind::identity:
      j = {{"extinction_scale", tf.extinction_scale}, {"color_scale", tf.color_scale}};
      break;
    case TfKind::piecewise_linear: {
      json points = json::array();
      for (const TfPoint& p : tf.points)
        points.push_back(
            {{"density", p.density}, {"color", vec(p.color)}, {"extinction", p.extinction}});
      j = {{"points", points}};
    } break;
    case TfKind::table: {
      json entries = json::array();
      for (const glm::dvec4& e : tf.entries) entries.push_back({e.x, e.y, e.z, e.w});
      j = {{"range", {tf.range.x, tf.range.y}}, {"entries", entries}};
    } break;
    case TfKind::gaussian: {
      json gs = json::array();
      for (const TfGaussian& g : tf.gaussians)
        gs.push_back({{"mean", g.mean},
                      {"width", g.width},
                      {"color", vec(g.color)},
                      {"extinction", g.extinction}});
      j = {{"gaussians", gs}};
    } break;
  }
  j["type"] = tf_kind_name(tf.kind);
  return j.dump(1);
}

std::string camera_json(const Camera& c) {
  json j = {{"eye", vec(c.eye)},
            {"target", vec(c.target)},
            {"up", vec(c.up)},
            {"width", c.width},
            {"height", c.height}};
  if (c.projection == Projection::orthographic) {
    j["projection"] = "orthographic";
    j["ortho_height"] = c.ortho_height;
  } else {
    j["fov_y"] = c.fov_y;
  }
  return j.dump(1);
}

void save_nrrd(const std::string& path, const Volume& v) {
  if (v.voxel_count() == 0 || v.data.size() != v.voxel_count())
    throw Error(Status::invalid_argument,
                "cannot write '" + path + "': the volume's data does not match its shape");
  std::string header =
      "NRRD0004\n# written by ivr\ntype: float\ndimension: 3\nsizes: " + std::to_string(v.nx) +
      " " + std::to_string(v.ny) + " " + std::to_string(v.nz) +
      "\nspacings: " + json(v.spacing.x).dump() + " " + json(v.spacing.y).dump() + " " +
      json(v.spacing.z).dump() + "\nencoding: raw\nendian: little\n\n";
  const std::uint16_t probe = 1;
  if (*reinterpret_cast<const unsigned char*>(&probe) != 1)
    throw Error(Status::unsupported, "cannot write '" + path +
                                         "': NRRD output needs a "
                                         "little-endian host");
  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(header.data(), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(v.data.data()),
              std::streamsize(v.data.size() * sizeof(float)));
    out.close();
    if (!out) throw Error(Status::io, "cannot write '" + path + "' (disk full?)");
  });
}

}  // namespace ivr
