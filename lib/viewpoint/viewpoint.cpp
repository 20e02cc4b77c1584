// viewpoint.cpp — best-viewpoint selection: the entropy of the image and its derivative with
// respect to the camera's eye (forward mode, 3 lanes), chained to the orbit's azimuth and
// elevation, and ascended with Adam, SGD or L-BFGS.
#include "ivr/viewpoint.hpp"

#include <cmath>
#include <limits>
#include <glm/geometric.hpp>

#include "ivr/error.hpp"
#include "ivr/jacobian.hpp"
#include "reconstruct/lbfgs.hpp"
#include "scene/scene.hpp"
#include "session/session.hpp"
#include "render/render.hpp"
#include "jacobian/jacobian.hpp"

namespace ivr {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxElevation = 85 * kPi / 180;  // keeps the view direction off the up axis
constexpr double kInf = std::numeric_limits<double>::infinity();

[[noreturn]] void fail(const std::string& what) {
  throw Error(Status::invalid_argument, what);
}

// The orbit frame of a camera: up axis a, and e1, e2 spanning the plane orthogonal to it (as the
// scene file's orbits: e1 from +x, or +y when a is near x).
struct Frame {
  glm::dvec3 a, e1, e2, target;
  double radius;
  glm::dvec3 eye(double az, double el) const {
    return target +
           radius * (std::cos(el) * (std::cos(az) * e1 + std::sin(az) * e2) + std::sin(el) * a);
  }
};

}  // namespace

double image_entropy(const Image& image, std::vector<double>* gradient, double background) {
  const std::size_t n = std::size_t(image.height) * image.width;
  const int c = image.channels;
  if (n < 2 || image.views < 1 || (c != 1 && c != 4) || image.pixels.size() < n * std::size_t(c))
    fail("image_entropy: needs an image of at least 2 pixels with 1 or 4 channels");
  if (c == 1 && !(background > 0))
    fail("image_entropy: the absorption background (I_in) must be > 0");
  // q_i: brightness + 1e-6 (a floor that keeps ln p finite and every p_i > 0).
  std::vector<double> q(n);
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float* px = image.pixels.data() + i * std::size_t(c);
    const double b = c == 4 ? (double(px[0]) + px[1] + px[2]) / 3 : 1 - double(px[0]) / background;
    q[i] = std::max(b, 0.0) + 1e-6;
    sum += q[i];
  }
  double h = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double p = q[i] / sum;
    h -= p * std::log(p);
  }
  const double norm = std::log(double(n));
  if (gradient) {
    // dH/dq_i = −(ln p_i + H) / Σq; pixels clamped at 0 brightness get 0.
    gradient->assign(n * std::size_t(c), 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const float* px = image.pixels.data() + i * std::size_t(c);
      const double b =
          c == 4 ? (double(px[0]) + px[1] + px[2]) / 3 : 1 - double(px[0]) / background;
      if (b < 0) continue;
      const double dq = -(std::log(q[i] / sum) + h) / sum / norm;
      if (c == 4)
        for (int k = 0; k < 3; ++k) (*gradient)[i * 4 + std::size_t(k)] = dq / 3;
      else
        (*gradient)[i] = -dq / background;
    }
  }
  return h / norm;
}

Viewpoint select_viewpoint(Device& device, const Scene& scene, const ViewpointOptions& options,
                           const std::function<bool(const ViewpointStep&)>& progress) {
  if (options.view < 0 || options.view >= int(scene.cameras.size()))
    fail("view " + std::to_string(options.view) + " does not exist (the scene has " +
         std::to_string(scene.cameras.size()) + " cameras)");
  if (options.iterations < 0)
    fail("iterations must be >= 0, got " + std::to_string(options.iterations));
  OptimizerOptions opt = options.optimizer;
  if (opt.lr == 0) opt.lr = 0.05;
  validate_optimizer(opt);

  Scene one = scene;
  const Camera start = scene.cameras[std::size_t(options.view)];
  one.cameras = {start};
  Frame f;
  f.target = start.target;
  f.a = glm::normalize(start.up);
  const glm::dvec3 helper = std::abs(f.a.x) > 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  f.e1 = glm::normalize(helper - glm::dot(helper, f.a) * f.a);
  f.e2 = glm::cross(f.a, f.e1);
  const glm::dvec3 offset = start.eye - start.target;
  f.radius = glm::length(offset);
  if (!(f.radius > 0)) fail("the camera's eye is at its target: no orbit to search");
  double angles[2] = {std::atan2(glm::dot(offset, f.e2), glm::dot(offset, f.e1)),
                      std::clamp(std::asin(std::clamp(glm::dot(offset, f.a) / f.radius, -1.0, 1.0)),
                                 -kMaxElevation, kMaxElevation)};

  const std::vector<Parameter> eye = {{ParameterGroup::camera, 0, 0},
                                      {ParameterGroup::camera, 0, 1},
                                      {ParameterGroup::camera, 0, 2}};
  // The volume stays on the device; each evaluation moves the camera and marches 3 eye lanes.
  SessionOptions so;
  so.precision = options.precision;
  so.step = options.step;
  Session session = one_shot_session(device, one, so);
  Session::Impl& s = session.impl();
  const std::vector<cl_int4> lanes = lanes_of(one, eye);
  const double background = one.effective_background().x;
  // −H and its gradient with respect to (azimuth, elevation).
  auto objective = [&](const std::vector<double>& at, std::vector<double>& grad) {
    one.cameras[0].eye = f.eye(at[0], at[1]);
    s.upload_cameras(one.cameras);
    const JacobianResult t = enqueue_jacobian(s, lanes, nullptr, true, Loss::mse, s.begin("jacobian"));
    const std::vector<std::int64_t> shape = t.image.shape();
    const Image image{int(shape[0]), int(shape[1]), int(shape[2]), int(shape[3]),
                      t.image.to_floats()};
    const std::vector<float> jacobian = t.jacobian.to_floats();
    std::vector<double> dpix;
    const double h = image_entropy(image, &dpix, background);
    glm::dvec3 deye(0.0);
    for (std::size_t i = 0; i < dpix.size(); ++i)
      for (int c = 0; c < 3; ++c) deye[c] += dpix[i] * double(jacobian[i * 3 + std::size_t(c)]);
    const double az = at[0], el = at[1];
    const glm::dvec3 daz = f.radius * std::cos(el) * (-std::sin(az) * f.e1 + std::cos(az) * f.e2);
    const glm::dvec3 del = f.radius * (-std::sin(el) * (std::cos(az) * f.e1 + std::sin(az) * f.e2) +
                                       std::cos(el) * f.a);
    grad = {-glm::dot(deye, daz), -glm::dot(deye, del)};
    return -h;
  };

  Viewpoint result;
  std::vector<double> x = {angles[0], angles[1]}, g;
  auto record = [&](int iteration, double entropy) {
    ViewpointStep s;
    s.iteration = iteration;
    s.entropy = entropy;
    s.azimuth = x[0] * 180 / kPi;
    s.elevation = x[1] * 180 / kPi;
    result.history.push_back(s);
    if (iteration == 0 || entropy > result.entropy) {
      result.entropy = entropy;
      result.camera = one.cameras[0];
      result.camera.eye = f.eye(x[0], x[1]);
    }
    return !progress || progress(s);
  };
  double value = objective(x, g);
  if (!record(0, -value)) return result;
  if (opt.kind == OptimizerKind::lbfgs) {
    Lbfgs lbfgs({-kInf, -kMaxElevation}, {kInf, kMaxElevation}, opt.history, opt.lr);
    for (int k = 1; k <= options.iterations; ++k)
      if (!record(k, -lbfgs.step(x, objective))) break;
  } else {
    opt.lower = -kInf;  // the angles are free; the elevation is clamped below
    opt.upper = kInf;
    Optimizer optimizer(device, 2, opt, options.precision);
    for (int k = 1; k <= options.iterations; ++k) {
      optimizer.step(x, g);
      x[1] = std::clamp(x[1], -kMaxElevation, kMaxElevation);
      value = objective(x, g);
      if (!record(k, -value)) break;
    }
  }
  return result;
}

}  // namespace ivr
