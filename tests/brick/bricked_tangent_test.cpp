// bricked_tangent_test.cpp — forward mode out of core (kernels/bricked_tangent.cl,
// lib/brick/bricked_tangent.cpp): the loss gradient through tangent lanes carried brick by brick
// equals the in-core forward mode's for every lane kind (TF, background, camera, voxels, TF points,
// scales, a ray list's own columns), under both models and precisions, with rays that stop early
// and passes of several lanes — TF and background lanes in packets of rays on CPUs; the camera
// beside the adjoint's groups; what is not covered is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "brick_support.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// The target: the scene's own render, changed so that the loss has a gradient.
Image target_of(const Scene& s) {
  Image t = render(device(), s);
  for (std::size_t i = 0; i < t.pixels.size(); ++i)
    t.pixels[i] = 0.7f * t.pixels[i] + 0.1f * float(i % 3);
  return t;
}

double tolerance(Precision p) {
  return p == Precision::f64 ? 1e-12 : 1e-5;
}

void expect_same_gradient(const Gradient& want, const Gradient& got, double tol,
                          const std::string& what) {
  EXPECT_NEAR(got.loss, want.loss, tol * std::abs(want.loss) + 1e-15) << what;
  ASSERT_EQ(got.groups.size(), want.groups.size()) << what;
  for (std::size_t g = 0; g < want.groups.size(); ++g) {
    EXPECT_EQ(got.groups[g].name, want.groups[g].name) << what;
    EXPECT_EQ(got.groups[g].shape, want.groups[g].shape) << what << " " << want.groups[g].name;
    if (want.groups[g].name != "step")  // (its derivative is 0)
      EXPECT_GT(largest(want.groups[g].values), 0.0) << what << " " << want.groups[g].name;
    expect_close_values(want.groups[g].values, got.groups[g].values, tol,
                        what + " " + want.groups[g].name);
  }
}

// The TF, background and every view's camera (6 views: 42 camera lanes; three passes) in forward
// mode, bricked as in core; perspective views from outside and inside the volume and orthographic
// ones with rays on the bricks' planes (tests/brick/brick_support.hpp), where the density's
// gradient is not clamped at a brick's inner faces.
TEST(BrickedForward, EqualsTheInCoreForwardMode) {
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Precision p : {Precision::f64, Precision::f32}) {
      if (p == Precision::f64 && !device().info().fp64) continue;
      const Scene all = bricked_scene(model, Scheme::midpoint);
      // Bricks of one cell (960 of them) once, with a perspective and an orthographic view.
      Scene two = all;
      two.cameras = {all.cameras[0], all.cameras[4]};
      const bool ones = p == Precision::f64 && model == Model::emission_absorption;
      for (const Scene* s : std::vector<const Scene*>{&all, &two}) {
        if (s == &two && !ones) continue;
        const Image target = target_of(*s);
        GradientOptions o;
        o.precision = p;
        o.mode = Mode::forward;
        const std::vector<std::string> groups = {"tf", "background", "camera"};
        const Gradient in_core = gradient(device(), *s, target, groups, o);
        ASSERT_EQ(in_core.bricks, 1);
        for (const char* edge :
             s == &two ? std::vector<const char*>{"1"} : std::vector<const char*>{"3", "100"}) {
          ScopedEnv brick("IVR_VOLUME_BRICK", edge);
          const Gradient g = gradient(device(), *s, target, groups, o);
          const std::string what =
              std::string(model == Model::absorption ? "absorption " : "emission ") + name(p) +
              " bricks of " + edge;
          EXPECT_GE(g.bricks, std::string(edge) == "100" ? 1 : 2) << what;
          EXPECT_EQ(g.plan.mode, Mode::forward) << what;
          EXPECT_EQ(g.plan.passes, (in_core.parameters + 31) / 32) << what;  // 32 lanes a pass
          expect_same_gradient(in_core, g, tolerance(p), what);
        }
      }
    }
}

// Voxel lanes (on the bricks' shared planes and inside them), a piecewise-linear TF's points, and
// the step (0) in forward mode; the identity TF's scales. (Both models' lanes: above.)
TEST(BrickedForward, VoxelsPointsAndScales) {
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  for (Model model : {Model::emission_absorption}) {
    Scene s = bricked_scene(model, Scheme::midpoint);
    const Image target = target_of(s);
    GradientOptions o;
    o.precision = p;
    // Voxels on x = 3 and 6 (brick planes of bricks of 3), z = 6, and between them.
    const std::vector<std::string> groups =
        parse_groups("voxels:3-7,600-612,700,1003,tf_points,step");
    o.mode = Mode::forward;
    const Gradient in_core = gradient(device(), s, target, groups, o);
    ScopedEnv brick("IVR_VOLUME_BRICK", "3");
    const Gradient g = gradient(device(), s, target, groups, o);
    EXPECT_GT(g.bricks, 1);
    EXPECT_EQ(g.groups.back().values, std::vector<double>{0.0});
    expect_same_gradient(in_core, g, tolerance(p),
                         model == Model::absorption ? "absorption" : "emission");

    s.tf = TransferFunction{};
    s.tf.kind = TfKind::identity;
    s.tf.extinction_scale = 4.0, s.tf.color_scale = 0.8;
    const Image identity_target = target_of(s);
    ScopedEnv in("IVR_VOLUME_BRICK", "");
    const Gradient scales_in_core = gradient(device(), s, identity_target, {"scales"}, o);
    ScopedEnv bricked("IVR_VOLUME_BRICK", "4");
    o.mode = Mode::automatic;  // scales go to the forward lanes out of core
    expect_same_gradient(scales_in_core, gradient(device(), s, identity_target, {"scales"}, o),
                         tolerance(p), "scales");
  }
}

// A ray list's own columns (one pass of 8 lanes, each ray its own derivatives) beside the TF's
// lanes; rays from inside and outside, ends inside the box and infinite ones.
TEST(BrickedForward, RayListColumns) {
  Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  const std::vector<double> rows = random_ray_rows(40, 5);
  s.rays = make_ray_list(rows.data(), 40, 8);
  s.cameras.clear();
  const Image target = target_of(s);
  GradientOptions o;
  o.precision = device().info().fp64 ? Precision::f64 : Precision::f32;
  const std::vector<std::string> groups = {"rays", "tf"};
  o.mode = Mode::forward;
  const Gradient in_core = gradient(device(), s, target, groups, o);
  for (const char* edge : {"2", "5"}) {
    ScopedEnv brick("IVR_VOLUME_BRICK", edge);
    expect_same_gradient(in_core, gradient(device(), s, target, groups, o), tolerance(o.precision),
                         std::string("ray list, bricks of ") + edge);
  }
}

// Automatic mode out of core: the density and TF by the adjoint's sweeps, the camera by forward
// lanes, in the order asked for; each as the in-core gradient (whose camera comes from its adjoint:
// the same derivative by the other mode, so to rounding of a different sum).
TEST(BrickedForward, CameraBesideTheAdjointGroups) {
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  for (Model model : {Model::absorption}) {
    const Scene s = bricked_scene(model, Scheme::midpoint);
    const Image target = target_of(s);
    GradientOptions o;
    o.precision = p;
    const std::vector<std::string> groups = {"camera", "density", "background", "tf"};
    o.mode = Mode::adjoint;
    const Gradient in_core = gradient(device(), s, target, groups, o);
    ScopedEnv brick("IVR_VOLUME_BRICK", "4");
    o.mode = Mode::automatic;
    const Gradient g = gradient(device(), s, target, groups, o);
    EXPECT_GT(g.bricks, 1);
    EXPECT_EQ(g.plan.mode, Mode::adjoint);
    EXPECT_TRUE(has(g.plan.model, "forward lanes for camera")) << g.plan.model;
    EXPECT_EQ(g.parameters, in_core.parameters);
    expect_same_gradient(in_core, g, p == Precision::f64 ? 1e-10 : 1e-4,
                         model == Model::absorption ? "absorption" : "emission");
  }
}

TEST(BrickedForward, WhatIsNotCoveredIsRefused) {
  Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  const Image target = render(device(), s);
  ScopedEnv brick("IVR_VOLUME_BRICK", "4");
  auto expect_error = [&](const std::vector<std::string>& groups, Mode mode, Status status,
                          const char* words) {
    GradientOptions o;
    o.mode = mode;
    try {
      gradient(device(), s, target, groups, o);
      ADD_FAILURE() << words;
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), status) << e.what();
      EXPECT_TRUE(has(e.what(), words)) << e.what();
    }
  };
  expect_error({"density"}, Mode::forward, Status::unsupported, "density in forward mode");
  expect_error({"density", "camera"}, Mode::adjoint, Status::invalid_argument,
               "mode adjoint cannot compute group 'camera'");
  expect_error({"tf", "tf"}, Mode::automatic, Status::invalid_argument, "asked for twice");
}

// The trapezoid and preintegrated schemes in forward mode out of core, under both models: each
// segment's near sample (and its tangents) taken again from the brick's halo, so the TF,
// background and camera lanes equal the in-core forward mode's, with a step longer than a voxel
// too; the exact scheme (absorption), whose camera lanes' end terms fall in the ray's first and
// last windows; and the camera beside the adjoint's groups.
TEST(BrickedForward, EverySchemeEqualsTheInCoreForwardMode) {
  struct Case {
    Scheme scheme;
    Model model;
    Precision precision;
    double step;
    const char* edge;
  };
  const Precision f64 = device().info().fp64 ? Precision::f64 : Precision::f32;
  for (const Case& c : {Case{Scheme::trapezoid, Model::emission_absorption, f64, 0.37, "3"},
                        Case{Scheme::trapezoid, Model::absorption, Precision::f32, 1.6, "2"},
                        Case{Scheme::preintegrated, Model::emission_absorption, f64, 1.6, "4"},
                        Case{Scheme::preintegrated, Model::absorption, f64, 0.37, "3"},
                        Case{Scheme::exact, Model::absorption, f64, 0.37, "1"},
                        Case{Scheme::exact, Model::absorption, Precision::f32, 0.37, "3"}}) {
    Scene s = bricked_scene(c.model, c.scheme);
    s.integrator.step = c.step;
    s.cameras = {s.cameras[0], s.cameras[2], s.cameras[4]};  // outside, inside, on the planes
    const Image target = target_of(s);
    GradientOptions o;
    o.precision = c.precision;
    o.mode = Mode::forward;
    const std::vector<std::string> groups = {"tf", "background", "camera"};
    const Gradient in_core = gradient(device(), s, target, groups, o);
    ScopedEnv brick("IVR_VOLUME_BRICK", c.edge);
    const Gradient g = gradient(device(), s, target, groups, o);
    const std::string what = std::string(scheme_name(c.scheme)) +
                             (c.model == Model::absorption ? " absorption " : " emission ") +
                             name(c.precision) + " step " + std::to_string(c.step);
    EXPECT_GT(g.bricks, 1) << what;
    EXPECT_EQ(g.plan.mode, Mode::forward) << what;
    expect_same_gradient(in_core, g, tolerance(c.precision), what);
  }
  // Automatic: density and TF by the adjoint, the camera by forward lanes.
  Scene s = bricked_scene(Model::emission_absorption, Scheme::preintegrated);
  s.cameras = {s.cameras[1], s.cameras[5]};
  const Image target = target_of(s);
  GradientOptions o;
  o.precision = f64;
  o.mode = Mode::adjoint;
  const std::vector<std::string> groups = {"camera", "density", "tf"};
  const Gradient in_core = gradient(device(), s, target, groups, o);
  ScopedEnv brick("IVR_VOLUME_BRICK", "4");
  o.mode = Mode::automatic;
  expect_same_gradient(in_core, gradient(device(), s, target, groups, o),
                       f64 == Precision::f64 ? 1e-10 : 1e-4, "preintegrated automatic");
}

// A pass of TF and background lanes alone marches packets of rays on CPUs (as in core; the
// camera's passes above march one ray a work-item): every fixed-step scheme under both models,
// rays stopping early, bricks of 1 and 3 cells, float64 (and float32 once) — the in-core forward
// mode's gradient, and the one-ray out-of-core march's ($IVR_PACKET=0).
TEST(BrickedForward, TfLanesInPacketsEqualTheInCoreForwardMode) {
  struct Case {
    Scheme scheme;
    Model model;
    const char* edge;
  };
  const Precision f64 = device().info().fp64 ? Precision::f64 : Precision::f32;
  struct Run {
    Case c;
    Precision p;
  };
  // (Few cases: each compiles four kernels.)
  for (const Run& run : {Run{{Scheme::midpoint, Model::emission_absorption, "1"}, f64},
                         Run{{Scheme::midpoint, Model::absorption, "3"}, f64},
                         Run{{Scheme::trapezoid, Model::emission_absorption, "3"}, f64},
                         Run{{Scheme::preintegrated, Model::emission_absorption, "3"}, f64},
                         Run{{Scheme::midpoint, Model::emission_absorption, "3"}, Precision::f32}}) {
    {
      const Case& c = run.c;
      const Precision p = run.p;
      Scene s = bricked_scene(c.model, c.scheme);
      s.integrator.min_transmittance = 0.05;  // (early termination: rays stop in a brick)
      const Image target = target_of(s);
      GradientOptions o;
      o.precision = p;
      o.mode = Mode::forward;
      const std::vector<std::string> groups = {"tf", "background"};
      const Gradient in_core = gradient(device(), s, target, groups, o);
      const std::string what = std::string(scheme_name(c.scheme)) +
                               (c.model == Model::absorption ? " absorption " : " emission ") +
                               name(p) + " bricks of " + c.edge;
      ScopedEnv brick("IVR_VOLUME_BRICK", c.edge);
      const Gradient packets = gradient(device(), s, target, groups, o);
      EXPECT_GT(packets.bricks, 1) << what;
      expect_same_gradient(in_core, packets, tolerance(p), what);
      ScopedEnv one_ray("IVR_PACKET", "0");
      expect_same_gradient(gradient(device(), s, target, groups, o), packets, tolerance(p),
                           what + " (one ray a work-item)");
    }
  }
}

}  // namespace
}  // namespace ivr::test
