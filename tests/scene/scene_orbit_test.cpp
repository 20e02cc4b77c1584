// scene_orbit_test.cpp — `{"orbit": {...}}` cameras in scene JSON: eye positions on the circle
// (axis z and a tilted axis), the shared lens keys, and errors naming the key path.
#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "ivr/error.hpp"
#include "ivr/scene.hpp"

using nlohmann::json;

namespace ivr {
namespace {

constexpr double kPi = 3.14159265358979323846;

Scene scene_with(const json& cameras) {
  json j = {{"volume", {{"synthetic", "zeros"}, {"dims", {8, 8, 8}}}},
            {"model", "absorption"},
            {"tf", {{"type", "identity"}}},
            {"cameras", cameras}};
  return parse_scene(j.dump(), ".");
}

// The message of the invalid_argument error parse_scene throws ("" and a failure if none).
std::string error_of(const json& cameras) {
  try {
    scene_with(cameras);
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no error for " << cameras.dump();
  return "";
}

void expect_near(const glm::dvec3& got, const glm::dvec3& want, const std::string& what) {
  EXPECT_LT(glm::length(got - want), 1e-12)
      << what << ": got (" << got.x << ", " << got.y << ", " << got.z << "), want (" << want.x
      << ", " << want.y << ", " << want.z << ")";
}

TEST(SceneOrbit, AxisZQuarterTurnsAndLensKeys) {
  const glm::dvec3 t(0.1, 0.2, 0.3);
  const Scene s = scene_with(json::array({{{"orbit",
                                            {{"views", 4},
                                             {"radius", 3},
                                             {"target", {t.x, t.y, t.z}},
                                             {"projection", "orthographic"},
                                             {"ortho_height", 1.5},
                                             {"width", 16},
                                             {"height", 8}}}}}));
  ASSERT_EQ(s.cameras.size(), 4u);
  const glm::dvec3 want[4] = {{3, 0, 0}, {0, 3, 0}, {-3, 0, 0}, {0, -3, 0}};
  for (int k = 0; k < 4; ++k) {
    const Camera& c = s.cameras[k];
    expect_near(c.eye, t + want[k], "eye " + std::to_string(k));
    expect_near(c.target, t, "target");
    expect_near(c.up, {0, 0, 1}, "up");
    EXPECT_EQ(c.projection, Projection::orthographic);
    EXPECT_EQ(c.ortho_height, 1.5);
    EXPECT_EQ(c.width, 16);
    EXPECT_EQ(c.height, 8);
  }
}

TEST(SceneOrbit, ParallelBeamHalfTurnDefaults) {
  const Scene s = scene_with(
      json::array({{{"orbit", {{"views", 90}, {"arc", 180}, {"projection", "orthographic"}}}}}));
  ASSERT_EQ(s.cameras.size(), 90u);
  for (int k = 0; k < 90; ++k) {  // radius 2 about z through the origin, 2° apart from +x
    const double theta = 2.0 * k * kPi / 180;
    expect_near(s.cameras[k].eye, {2 * std::cos(theta), 2 * std::sin(theta), 0},
                "eye " + std::to_string(k));
  }
  expect_near(s.cameras[45].eye, {0, 2, 0}, "eye 45");
  EXPECT_EQ(s.cameras[0].width, Camera().width);  // lens keys default like a plain camera's
  EXPECT_EQ(s.cameras[0].fov_y, Camera().fov_y);
}

TEST(SceneOrbit, TiltedAxisCircleAnglesAndBasis) {
  const glm::dvec3 t(0.5, -0.25, 1.0), axis = glm::normalize(glm::dvec3(0, 1, 1));
  const double radius = 2.5, start = 30;
  const Scene s = scene_with(json::array({{{"orbit",
                                            {{"views", 6},
                                             {"radius", radius},
                                             {"target", {t.x, t.y, t.z}},
                                             {"axis", {0, 2, 2}},
                                             {"start", start}}}}}));
  ASSERT_EQ(s.cameras.size(), 6u);
  // The documented basis: e1 = +x made orthogonal to the axis (already is), e2 = axis × e1.
  const glm::dvec3 e1(1, 0, 0), e2 = glm::cross(axis, e1);
  for (int k = 0; k < 6; ++k) {
    const Camera& c = s.cameras[k];
    const glm::dvec3 d = c.eye - t;
    EXPECT_NEAR(glm::length(d), radius, 1e-12) << k;
    EXPECT_NEAR(glm::dot(d, axis), 0.0, 1e-12) << k;
    expect_near(c.up, axis, "up");
    expect_near(c.target, t, "target");
    const double theta = (start + 60.0 * k) * kPi / 180;
    expect_near(d, radius * (std::cos(theta) * e1 + std::sin(theta) * e2),
                "eye " + std::to_string(k));
    // Counter-clockwise about the axis: each step turns by +60°.
    const glm::dvec3 next = s.cameras[(k + 1) % 6].eye - t;
    EXPECT_NEAR(glm::dot(glm::cross(d, next), axis), radius * radius * std::sin(kPi / 3), 1e-12);
  }
  // An axis along x takes e1 from +y: e1 = +y, e2 = x × y = +z.
  const Scene x = scene_with(json::array({{{"orbit", {{"views", 2}, {"axis", {-3, 0, 0}}}}}}));
  expect_near(x.cameras[0].eye, {0, 2, 0}, "axis -x, eye 0");
  expect_near(x.cameras[1].eye, {0, -2, 0}, "axis -x, eye 1");
  expect_near(x.cameras[0].up, {-1, 0, 0}, "axis -x, up");
}

TEST(SceneOrbit, MixesWithPlainCameras) {
  const Scene s = scene_with(
      json::array({{{"eye", {0, 0, 3}}}, {{"orbit", {{"views", 3}}}}, {{"eye", {3, 0, 0.1}}}}));
  ASSERT_EQ(s.cameras.size(), 5u);
  expect_near(s.cameras[0].eye, {0, 0, 3}, "first");
  expect_near(s.cameras[1].eye, {2, 0, 0}, "orbit 0");
  expect_near(s.cameras[4].eye, {3, 0, 0.1}, "last");
}

TEST(SceneOrbit, ErrorsNameTheKeyPath) {
  const auto orbit = [](json o) { return json::array({{{"orbit", o}}}); };
  const auto has = [](const std::string& msg, const std::string& part) {
    EXPECT_NE(msg.find(part), std::string::npos) << msg;
  };
  has(error_of(orbit({{"views", 0}})), "scene: cameras[0].orbit.views: expected an integer >= 1");
  has(error_of(orbit({{"views", 2.5}})), "cameras[0].orbit.views: expected an integer >= 1");
  has(error_of(orbit({{"views", "ten"}})), "cameras[0].orbit.views: expected an integer >= 1");
  has(error_of(orbit({{"views", 1e7}})), "cameras[0].orbit.views: at most 100000 views");
  has(error_of(orbit({{"radius", 2}})), "cameras[0].orbit: needs 'views'");
  has(error_of(orbit({{"views", 4}, {"spin", 1}})), "cameras[0].orbit.spin: unknown key (known:");
  has(error_of(orbit({{"views", 4}, {"eye", {1, 2, 3}}})), "cameras[0].orbit.eye: unknown key");
  has(error_of(orbit({{"views", 4}, {"radius", 0}})), "cameras[0].orbit.radius: must be > 0");
  has(error_of(orbit({{"views", 4}, {"axis", {0, 0, 0}}})), "cameras[0].orbit.axis: must be");
  has(error_of(orbit({{"views", 4}, {"axis", {0, 1}}})), "cameras[0].orbit.axis: expected");
  has(error_of(orbit({{"views", 4}, {"arc", "half"}})), "cameras[0].orbit.arc: expected a number");
  has(error_of(orbit({{"views", 4}, {"projection", "fisheye"}})),
      "cameras[0].orbit.projection: unknown projection 'fisheye'");
  has(error_of(orbit({{"views", 4}, {"width", 1.5}})),
      "cameras[0].orbit.width: expected an integer");
  has(error_of(orbit(json::array({4}))), "cameras[0].orbit: expected an object");
  // Keys beside "orbit" belong to no camera.
  has(error_of(json::array({{{"orbit", {{"views", 4}}}, {"eye", {0, 0, 2}}}})),
      "cameras[0].eye: unknown key (known: orbit)");
  // The index is the element's, and size mismatches with other cameras are still caught.
  has(error_of(json::array({{{"eye", {0, 0, 3}}}, {{"orbit", {{"views", -1}}}}})),
      "cameras[1].orbit.views");
  has(error_of(json::array({{{"eye", {0, 0, 3}}}, {{"orbit", {{"views", 2}, {"width", 32}}}}})),
      "all cameras must share width and height");
}

}  // namespace
}  // namespace ivr
