// bricked_gradient_test.cpp — the out-of-core density gradient (kernels/bricked_adjoint.cl,
// lib/brick/bricked_gradient.cpp) and the TF's equal the in-core adjoint's, under both models,
// for bricks of one cell to one brick, with early termination, every loss and every scheme (the
// endpoint schemes through the bricks' halo); what it does not cover is refused clearly.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "adjoint/adjoint.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "brick_support.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

Scene gradient_scene(Model model) {
  Scene s;
  s.volume.nx = 9, s.volume.ny = 8, s.volume.nz = 10;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  s.volume.data.resize(s.volume.voxel_count());
  for (float& v : s.volume.data) v = u(rng);
  set_default_box(s);
  s.model = model;
  s.tf.kind = TfKind::piecewise_linear;
  s.tf.points = {{0.0, {0.1, 0.2, 0.3}, 0.5}, {0.5, {0.9, 0.5, 0.1}, 40.0}, {1.0, {0.2, 0.6, 1.0}, 15.0}};
  s.integrator.step = 0.45;
  s.background = {0.2, 0.1, 0.3};
  Camera c;
  c.eye = {0.4, 0.5, 1.9}, c.fov_y = 45, c.width = 9, c.height = 8;
  Camera inside = c;
  inside.eye = {0.02, 0.03, -0.05}, inside.target = {-1, 0.4, 0.3};
  s.cameras = {c, inside, ortho({-2, 0, 0}, {0, 1, 0}, 9, 8, s.box_max.y - s.box_min.y)};
  return s;
}

TEST(BrickedGradient, DensityEqualsTheInCoreAdjoint) {
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Precision p : {Precision::f64, Precision::f32}) {
      if (p == Precision::f64 && !device().info().fp64) continue;
      const Scene s = gradient_scene(model);
      Image target = render(device(), s);
      for (float& v : target.pixels) v = 0.8f * v + 0.05f;
      for (Loss loss : {Loss::mse, Loss::l1}) {
        // (The L1 loss changes the pixel adjoints alone: one model and precision.)
        if (loss == Loss::l1 && (model != Model::emission_absorption || p != Precision::f64))
          continue;
        GradientOptions o;
        o.precision = p;
        o.loss = loss;
        o.mode = Mode::adjoint;
        const Gradient in_core = gradient(device(), s, target, {"density"}, o);
        EXPECT_EQ(in_core.bricks, 1);
        const std::vector<double>& a = in_core.groups[0].values;
        for (const char* edge : {"1", "3", "100"}) {
          ScopedEnv brick("IVR_VOLUME_BRICK", edge);
          const Gradient g = gradient(device(), s, target, {"density"}, o);
          const std::string what = std::string(model == Model::absorption ? "absorption " : "emission ") +
                                   name(p) + (loss == Loss::l1 ? " l1" : " mse") + " bricks of " + edge;
          EXPECT_GT(g.bricks, std::string(edge) == "100" ? 0 : 1) << what;
          const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
          EXPECT_NEAR(g.loss, in_core.loss, tol * std::max(std::abs(in_core.loss), 1e-30) + 1e-15) << what;
          expect_close_values(a, g.groups.at(0).values, tol, what);
        }
      }
    }
}

// Every form of the adjoint march through the bricks (kernels/bricked_adjoint.cl): packets of rays
// summing into private copies of the brick's gradient, packets with atomic adds, and one ray per
// work-item (the GPUs' form) each equal the in-core adjoint.
TEST(BrickedGradient, EveryMarchFormEqualsTheInCoreAdjoint) {
  struct Form {
    const char* name;
    const char* packet;
    const char* private_sums;
  };
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Precision p : {Precision::f64, Precision::f32}) {
      if (p == Precision::f64 && !device().info().fp64) continue;
      const Scene s = gradient_scene(model);
      Image target = render(device(), s);
      for (float& v : target.pixels) v = 0.8f * v + 0.05f;
      GradientOptions o;
      o.precision = p;
      o.mode = Mode::adjoint;
      const Gradient in_core = gradient(device(), s, target, {"density"}, o);
      for (const Form& f : {Form{"private sums", "1", "1"}, Form{"atomics", "1", "0"},
                            Form{"one ray", "0", "0"}}) {
        // Private sums serve CPU devices only (elsewhere IVR_PRIVATE_SUMS=1 is refused by name).
        if (std::string(f.name) == "private sums" && device().info().type != "cpu") continue;
        ScopedEnv brick("IVR_VOLUME_BRICK", "4");
        ScopedEnv packet("IVR_PACKET", f.packet);
        ScopedEnv sums("IVR_PRIVATE_SUMS", f.private_sums);
        const Gradient g = gradient(device(), s, target, {"density"}, o);
        const std::string what = std::string(model == Model::absorption ? "absorption " : "emission ") +
                                 name(p) + " " + f.name;
        EXPECT_GT(g.bricks, 1) << what;
        const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
        EXPECT_NEAR(g.loss, in_core.loss, tol * std::abs(in_core.loss) + 1e-15) << what;
        expect_close_values(in_core.groups[0].values, g.groups.at(0).values, tol, what);
      }
    }
}

// The TF and background gradients out of core (alone, and beside the density's in any order)
// equal the in-core adjoint's, through every form of the march.
TEST(BrickedGradient, TfGradientEqualsTheInCoreAdjoint) {
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Precision p : {Precision::f64, Precision::f32}) {
      if (p == Precision::f64 && !device().info().fp64) continue;
      const Scene s = gradient_scene(model);
      Image target = render(device(), s);
      for (float& v : target.pixels) v = 0.8f * v + 0.05f;
      GradientOptions o;
      o.precision = p;
      o.mode = Mode::adjoint;
      const Gradient in_core = gradient(device(), s, target, {"density", "tf", "background"}, o);
      for (const char* packet : {"1", "0"})
        for (const std::vector<std::string>& groups :
             {std::vector<std::string>{"tf"}, std::vector<std::string>{"tf", "density"},
              std::vector<std::string>{"background", "density", "tf"}}) {
          // (One ray per work-item, the GPUs' form: float64 here, float32 in EveryMarchForm.)
          if (*packet == '0' && p != Precision::f64) continue;
          ScopedEnv brick("IVR_VOLUME_BRICK", "3");
          ScopedEnv packets("IVR_PACKET", packet);
          const Gradient g = gradient(device(), s, target, groups, o);
          ASSERT_EQ(g.groups.size(), groups.size());
          EXPECT_GT(g.bricks, 1);
          for (std::size_t k = 0; k < groups.size(); ++k) {
            const std::string what = std::string(model == Model::absorption ? "absorption " : "emission ") +
                                     name(p) + (*packet == '1' ? " packets " : " one ray ") +
                                     groups[k] + " of " + std::to_string(groups.size());
            const GroupGradient& want =
                in_core.groups[groups[k] == "density" ? 0 : groups[k] == "tf" ? 1 : 2];
            EXPECT_EQ(g.groups[k].name, groups[k]) << what;
            EXPECT_EQ(g.groups[k].shape, want.shape) << what;
            EXPECT_GT(largest(want.values), 1e-6) << what;
            expect_close_values(want.values, g.groups[k].values,
                                p == Precision::f64 ? 1e-12 : 1e-5, what);
          }
        }
    }
}

// Under a device-memory cap that the plan's bricks just fit, the private sums' copies of a brick's
// gradient do not: the automatic choice falls back to atomic adds (same gradient), and forcing
// them (IVR_PRIVATE_SUMS=1) is one clear error.
TEST(BrickedGradient, PrivateSumsKeepToTheMemoryCap) {
  if (device().info().type != "cpu") GTEST_SKIP() << "private sums serve CPU packet kernels";
  const Scene s = gradient_scene(Model::emission_absorption);
  Image target = render(device(), s);
  for (float& v : target.pixels) v = 0.8f * v + 0.05f;
  GradientOptions o;
  o.mode = Mode::adjoint;
  ScopedEnv brick("IVR_VOLUME_BRICK", "4");
  ScopedEnv slots("IVR_GRADIENT_SLOTS", "2");  // (the plan's two: no more where room is left)
  Gradient free;  // with atomic adds: the plan's bytes alone
  {
    ScopedEnv atomics("IVR_PRIVATE_SUMS", "0");
    free = gradient(device(), s, target, {"density"}, o);
  }
  ASSERT_GT(free.bricks, 1);
  EXPECT_GT(gradient(device(), s, target, {"density"}, o).device_bytes, free.device_bytes)
      << "the private sums' copies are counted";
  ScopedEnv cap("IVR_DEVICE_MEMORY_LIMIT", std::to_string(free.device_bytes + 64));
  const Gradient capped = gradient(device(), s, target, {"density"}, o);
  EXPECT_LE(capped.device_bytes, free.device_bytes + 64);
  expect_close_values(free.groups[0].values, capped.groups[0].values, 1e-5, "under the cap");
  ScopedEnv forced("IVR_PRIVATE_SUMS", "1");
  try {
    gradient(device(), s, target, {"density"}, o);
    ADD_FAILURE() << "forced private sums beyond the cap ran";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), Status::invalid_argument) << e.what();
    EXPECT_TRUE(has(e.what(), "IVR_PRIVATE_SUMS=1")) << e.what();
    EXPECT_TRUE(has(e.what(), "budget")) << e.what();
  }
}

// The ring of slots for a brick's gradient (the host adds a brick's while the device marches the
// next ones): its size changes neither the bits (fixed point; the host adds the bricks in the
// order they were marched, so float sums too) nor the memory cap it keeps to, and a bad
// $IVR_GRADIENT_SLOTS is one clear error.
TEST(BrickedGradient, GradientSlotsChangeNothingButTheWaits) {
  const Scene s = gradient_scene(Model::emission_absorption);
  Image target = render(device(), s);
  for (float& v : target.pixels) v = 0.8f * v + 0.05f;
  GradientOptions o;
  o.mode = Mode::adjoint;
  o.deterministic = has_int64_atomics(device().impl());
  ScopedEnv brick("IVR_VOLUME_BRICK", "3");
  ScopedEnv atomics("IVR_PRIVATE_SUMS", "0");  // (float sums: each brick's own, no copies)
  std::vector<Gradient> got;
  for (const char* slots : {"1", "2", "8"}) {
    ScopedEnv ring("IVR_GRADIENT_SLOTS", slots);
    got.push_back(gradient(device(), s, target, {"density", "tf"}, o));
    EXPECT_GT(got.back().bricks, 8) << slots;
    EXPECT_EQ(got.back().deterministic, o.deterministic) << slots;
  }
  for (std::size_t i = 1; i < got.size(); ++i) {
    if (o.deterministic)
      EXPECT_EQ(got[0].groups[0].values, got[i].groups[0].values) << "ring " << i;
    else
      expect_close_values(got[0].groups[0].values, got[i].groups[0].values, 1e-6, "density");
    expect_close_values(got[0].groups[1].values, got[i].groups[1].values, 1e-6, "tf");
  }
  // Each slot more is counted; under a cap that leaves no room beyond the plan's two (float
  // slots) the ring keeps to it.
  EXPECT_GT(got[2].device_bytes, got[1].device_bytes);
  EXPECT_GT(got[1].device_bytes, got[0].device_bytes - (o.deterministic ? 1 : 0));
  {
    ScopedEnv ring("IVR_GRADIENT_SLOTS", "8");
    ScopedEnv cap("IVR_DEVICE_MEMORY_LIMIT", std::to_string(got[1].device_bytes + 64));
    const Gradient capped = gradient(device(), s, target, {"density", "tf"}, o);
    EXPECT_LE(capped.device_bytes, got[1].device_bytes + 64);
    if (o.deterministic) EXPECT_EQ(capped.groups[0].values, got[0].groups[0].values);
  }
  for (const char* bad : {"0", "65", "two"}) {
    ScopedEnv ring("IVR_GRADIENT_SLOTS", bad);
    try {
      gradient(device(), s, target, {"density"}, o);
      ADD_FAILURE() << "IVR_GRADIENT_SLOTS=" << bad << " ran";
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument) << e.what();
      EXPECT_TRUE(has(e.what(), "IVR_GRADIENT_SLOTS")) << e.what();
    }
  }
}

// The trapezoid and preintegrated schemes (both models) and the exact one (absorption) out of core:
// a segment's near sample lies in the brick before its far end's, and its part of the gradient is
// scattered there from the brick's halo (brick_halo), so the density, TF and background gradients
// equal the in-core adjoint's; with a step longer than a voxel (a halo of 3) too. Views from
// outside and inside the volume and orthographic rays on the bricks' planes (bricked_scene).
TEST(BrickedGradient, EverySchemeEqualsTheInCoreAdjoint) {
  struct Case {
    Scheme scheme;
    Model model;
    Precision precision;
    double step;
    std::vector<const char*> edges;
  };
  const Precision f64 = device().info().fp64 ? Precision::f64 : Precision::f32;
  const std::vector<Case> cases = {
      {Scheme::trapezoid, Model::emission_absorption, f64, 0.37, {"1", "3", "100"}},
      {Scheme::trapezoid, Model::emission_absorption, Precision::f32, 0.37, {"3"}},
      {Scheme::trapezoid, Model::absorption, f64, 1.6, {"2", "4"}},
      {Scheme::preintegrated, Model::emission_absorption, f64, 1.6, {"2", "5"}},
      {Scheme::preintegrated, Model::absorption, f64, 0.37, {"3"}},
      {Scheme::exact, Model::absorption, f64, 0.37, {"1", "3"}}};
  for (const Case& c : cases) {
    Scene s = bricked_scene(c.model, c.scheme);
    s.integrator.step = c.step;
    Image target = render(device(), s);
    for (float& v : target.pixels) v = 0.8f * v + 0.05f;
    GradientOptions o;
    o.precision = c.precision;
    o.mode = Mode::adjoint;
    const std::vector<std::string> groups = {"density", "tf", "background"};
    const Gradient in_core = gradient(device(), s, target, groups, o);
    ASSERT_EQ(in_core.bricks, 1);
    for (const char* edge : c.edges) {
      ScopedEnv brick("IVR_VOLUME_BRICK", edge);
      const Gradient g = gradient(device(), s, target, groups, o);
      const std::string what = std::string(scheme_name(c.scheme)) +
                               (c.model == Model::absorption ? " absorption " : " emission ") +
                               name(c.precision) + " step " + std::to_string(c.step) +
                               " bricks of " + edge;
      EXPECT_GE(g.bricks, std::string(edge) == "100" ? 1 : 2) << what;
      const double tol = c.precision == Precision::f64 ? 1e-12 : 1e-5;
      EXPECT_NEAR(g.loss, in_core.loss, tol * std::abs(in_core.loss) + 1e-15) << what;
      ASSERT_EQ(g.groups.size(), groups.size()) << what;
      for (std::size_t k = 0; k < groups.size(); ++k) {
        EXPECT_GT(largest(in_core.groups[k].values), 1e-9) << what << " " << groups[k];
        expect_close_values(in_core.groups[k].values, g.groups[k].values, tol,
                            what + " " + groups[k]);
      }
    }
  }
}

}  // namespace
}  // namespace ivr::test
