// ray_list.cpp — ray lists (docs/design.md, "Ray lists"): checking and normalising the rays a
// caller gives, the rays of a camera's pixels built as the kernels build them, and the image
// extent of a scene with either geometry.
#include <cmath>
#include <limits>
#include <string>

#include "ivr/error.hpp"
#include "ivr/scene.hpp"
#include "scene/device_scene.hpp"

namespace ivr {

namespace {

const char* const kFields[RayList::kColumns] = {"origin.x",    "origin.y",    "origin.z",
                                                "direction.x", "direction.y", "direction.z",
                                                "t_start",     "t_end"};
const char* const kPointFields[6] = {"start.x", "start.y", "start.z", "end.x", "end.y", "end.z"};

[[noreturn]] void bad_ray(const std::string& where, std::size_t i, const std::string& field,
                          const std::string& what) {
  throw Error(Status::invalid_argument,
              where + "[" + std::to_string(i) + "]." + field + ": " + what);
}

std::string number_text(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace

RayList make_ray_list(const double* values, std::size_t rows, int columns,
                      const std::string& where) {
  if (columns != 8 && columns != 6)
    throw Error(Status::invalid_argument,
                where + ": rays have 8 columns (ox oy oz dx dy dz t_start t_end) or 6 (start and "
                        "end points), not " +
                    std::to_string(columns));
  if (rows == 0) throw Error(Status::invalid_argument, where + ": no rays");
  if (rows > std::size_t(std::numeric_limits<int>::max()))
    throw Error(Status::invalid_argument,
                where + ": " + std::to_string(rows) + " rays (at most 2^31 - 1)");
  if (!values) throw Error(Status::invalid_argument, where + ": no values given");
  RayList list;
  list.values.resize(rows * RayList::kColumns);
  for (std::size_t i = 0; i < rows; ++i) {
    const double* in = values + i * std::size_t(columns);
    double* out = list.values.data() + i * RayList::kColumns;
    // NaN anywhere, then infinities where they mean nothing (only the interval's ends may be).
    for (int k = 0; k < columns; ++k) {
      const std::string field = columns == 8 ? kFields[k] : kPointFields[k];
      if (std::isnan(in[k])) bad_ray(where, i, field, "is NaN");
      if (std::isinf(in[k]) && (columns == 6 || k < 6))
        bad_ray(where, i, field, "is " + number_text(in[k]) + "; it must be finite");
    }
    double d[3], t0, t1;
    if (columns == 8) {
      d[0] = in[3], d[1] = in[4], d[2] = in[5];
      t0 = in[6], t1 = in[7];
      if (t0 == INFINITY) bad_ray(where, i, "t_start", "is inf; it must be finite or -inf");
      if (t1 == -INFINITY) bad_ray(where, i, "t_end", "is -inf; it must be finite or inf");
      if (t1 < t0)
        bad_ray(where, i, "t_end",
                number_text(t1) + " is before t_start " + number_text(t0));
    } else {
      d[0] = in[3] - in[0], d[1] = in[4] - in[1], d[2] = in[5] - in[2];
      t0 = 0;
      t1 = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (!std::isfinite(t1)) bad_ray(where, i, "end", "is too far from start (overflow)");
      if (t1 == 0) d[0] = 1, d[1] = d[2] = 0;  // a ray of length 0: any direction, adds nothing
    }
    const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(length > 0)) bad_ray(where, i, "direction", "is zero");
    if (!std::isfinite(length)) bad_ray(where, i, "direction", "overflows (its length is inf)");
    // Unit within 1e-6: kept as given (a float32 unit vector is rarely unit in float64, and
    // renormalising would move the rays ray_list_of_camera() built bit for bit).
    const double scale = std::abs(length - 1) <= 1e-6 ? 1.0 : 1.0 / length;
    for (int k = 0; k < 3; ++k) {
      out[k] = in[k];
      out[3 + k] = d[k] * scale;
    }
    out[6] = t0;
    out[7] = t1;
  }
  return list;
}

// camera_ray() and sample_count() of kernels/geometry.cl and sample_count.cl, in `Real`: the
// screen coordinates as correctly rounded quotients, every sum of products an explicit fma, the
// perspective direction divided by its correctly rounded norm (IEEE host arithmetic is correctly
// rounded; std::fma is fused).
template <class Real>
static void camera_rays(const Camera& camera, RayList& list) {
  const std::vector<Real> cam = pack_cameras<Real>({camera});
  const int w = camera.width, h = camera.height;
  const bool ortho = cam[12] != Real(0);
  list.values.resize(std::size_t(w) * h * RayList::kColumns);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Real sx = Real(2 * x + 1 - w) / Real(w), sy = Real(h - 2 * y - 1) / Real(h);
      Real o[3], d[3];
      for (int k = 0; k < 3; ++k) {
        if (ortho) {
          o[k] = std::fma(sy, cam[9 + k], std::fma(sx, cam[6 + k], cam[k]));
          d[k] = cam[3 + k];
        } else {
          o[k] = cam[k];
          d[k] = std::fma(sy, cam[9 + k], std::fma(sx, cam[6 + k], cam[3 + k]));
        }
      }
      if (!ortho) {
        const Real dz2 = d[2] * d[2];
        const Real norm = std::sqrt(std::fma(d[0], d[0], std::fma(d[1], d[1], dz2)));
        for (Real& c : d) c = c / norm;
      }
      double* out = list.values.data() + (std::size_t(y) * w + x) * RayList::kColumns;
      for (int k = 0; k < 3; ++k) out[k] = double(o[k]), out[3 + k] = double(d[k]);
      out[6] = 0;
      out[7] = INFINITY;
    }
}

RayList ray_list_of_camera(const Camera& camera, bool f64) {
  if (camera.width < 1 || camera.height < 1)
    throw Error(Status::invalid_argument, "ray_list_of_camera: the camera has no pixels");
  RayList list;
  if (f64)
    camera_rays<double>(camera, list);
  else
    camera_rays<float>(camera, list);
  return list;
}

ImageExtent image_extent(const Scene& scene) {
  if (scene.has_ray_list()) return {1, 1, int(scene.rays.count())};
  if (scene.cameras.empty()) return {};
  return {int(scene.cameras.size()), scene.cameras.front().height, scene.cameras.front().width};
}

}  // namespace ivr
