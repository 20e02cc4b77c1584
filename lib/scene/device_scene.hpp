// device_scene.hpp — a scene packed for the kernels: cameras, camera parameters and transfer
// function in the layouts of kernels/config.cl, jacobian_geometry.cl and tf.cl (a session uploads
// them, lib/session/session.cpp).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <string>
#include <type_traits>
#include <vector>

#include "ivr/scene.hpp"
#include "ivr_constants.h"
#include "runtime/runtime.hpp"

namespace ivr {

template <class Real>
struct ClVec;
template <>
struct ClVec<float> {
  using type = cl_float4;
};
template <>
struct ClVec<double> {
  using type = cl_double4;
};

template <class Real>
inline typename ClVec<Real>::type vec4(double x, double y, double z, double w = 0) {
  typename ClVec<Real>::type v;
  v.s[0] = Real(x);
  v.s[1] = Real(y);
  v.s[2] = Real(z);
  v.s[3] = Real(w);
  return v;
}

// Per view: eye, forward, right and up scaled to the image plane, orthographic flag (see
// kernels/config.cl, IVR_CAMERA_STRIDE).
template <class Real>
std::vector<Real> pack_cameras(const std::vector<Camera>& cameras) {
  constexpr int stride = IVR_CAMERA_STRIDE;
  static_assert(stride >= 13, "the packed camera holds 13 values");
  std::vector<Real> out(cameras.size() * stride, Real(0));
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    const glm::dvec3 fwd = glm::normalize(c.target - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(fwd, c.up));
    const glm::dvec3 up = glm::cross(right, fwd);
    const double aspect = double(c.width) / double(c.height);
    const bool ortho = c.projection == Projection::orthographic;
    const double half = ortho ? 0.5 * c.ortho_height : std::tan(0.5 * c.fov_y * M_PI / 180.0);
    const glm::dvec3 r = half * aspect * right, u = half * up;
    const double values[13] = {
        c.eye.x, c.eye.y, c.eye.z,          fwd.x, fwd.y, fwd.z, r.x, r.y, r.z, u.x,
        u.y,     u.z,     ortho ? 1.0 : 0.0};
    for (int k = 0; k < 13; ++k) out[i * stride + k] = Real(values[k]);
  }
  return out;
}

// Camera parameters for the derivatives (kernels/jacobian_geometry.cl), per view: eye, target,
// up, fov_y, aspect, ortho_height, orthographic flag.
template <class Real>
std::vector<Real> pack_camera_params(const std::vector<Camera>& cameras) {
  constexpr int stride = IVR_CAMERA_PARAMS_STRIDE;
  static_assert(stride >= 13, "the camera parameters are 13 values");
  std::vector<Real> out(cameras.size() * stride, Real(0));
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    const double v[13] = {c.eye.x,
                          c.eye.y,
                          c.eye.z,
                          c.target.x,
                          c.target.y,
                          c.target.z,
                          c.up.x,
                          c.up.y,
                          c.up.z,
                          c.fov_y,
                          double(c.width) / double(c.height),
                          c.ortho_height,
                          c.projection == Projection::orthographic ? 1.0 : 0.0};
    for (int k = 0; k < 13; ++k) out[i * stride + k] = Real(v[k]);
  }
  return out;
}

// Transfer-function rows in the layout of kernels/tf.cl; scalars = (a, b) or (lo, hi).
template <class Real>
std::vector<Real> pack_tf(const TransferFunction& tf, int* count, double scalars[2]) {
  static_assert(IVR_TF_STRIDE_PIECEWISE_LINEAR == 5 && IVR_TF_STRIDE_TABLE == 4 &&
                    IVR_TF_STRIDE_GAUSSIAN == 6,
                "the rows below are written out for these widths");
  std::vector<Real> out;
  scalars[0] = scalars[1] = 0;
  switch (tf.kind) {
    case TfKind::identity:
      scalars[0] = tf.extinction_scale;
      scalars[1] = tf.color_scale;
      *count = 0;
      out.push_back(0);  // buffers cannot be empty
      break;
    case TfKind::piecewise_linear:
      for (const TfPoint& p : tf.points)
        out.insert(out.end(), {Real(p.density), Real(p.color.x), Real(p.color.y), Real(p.color.z),
                               Real(p.extinction)});
      *count = int(tf.points.size());
      break;
    case TfKind::table:
      for (const glm::dvec4& e : tf.entries)
        out.insert(out.end(), {Real(e.x), Real(e.y), Real(e.z), Real(e.w)});
      scalars[0] = tf.range.x;
      scalars[1] = tf.range.y;
      *count = int(tf.entries.size());
      break;
    case TfKind::gaussian:
      for (const TfGaussian& g : tf.gaussians)
        out.insert(out.end(), {Real(g.mean), Real(g.width), Real(g.color.x), Real(g.color.y),
                               Real(g.color.z), Real(g.extinction)});
      *count = int(tf.gaussians.size());
      break;
  }
  // The rows' columns after them, for the packets' permutes (ivr_constants.h).
  const std::size_t width = tf.kind == TfKind::piecewise_linear ? IVR_TF_STRIDE_PIECEWISE_LINEAR
                            : tf.kind == TfKind::table          ? IVR_TF_STRIDE_TABLE
                                                                : 0;
  if (width && *count <= IVR_TF_COLUMN_ENTRIES) {
    const std::size_t rows = std::size_t(*count);
    for (std::size_t c = 0; c < width; ++c)
      for (std::size_t j = 0; j < IVR_TF_COLUMN_ENTRIES; ++j) {
        const Real v = out[std::min(j, rows - 1) * width + c];
        out.push_back(v);
      }
  }
  return out;
}

}  // namespace ivr
