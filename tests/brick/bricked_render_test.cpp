// bricked_render_test.cpp — the out-of-core render (kernels/bricked.cl, lib/brick/) equals the
// in-core render (the exact scheme's bit for bit): every scheme under both models, bricks of one cell to one brick, cameras outside,
// inside and grazing the bricks' planes, ray lists; and the device-memory cap that chooses it.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "brick/bricked_render.hpp"
#include "ivr/error.hpp"
#include "ivr/render.hpp"
#include "test_support.hpp"
#include "brick_support.hpp"

namespace ivr {
namespace {
using namespace test;

Image render_with(const Scene& s, Precision p, int brick, RenderStats* st = nullptr) {
  RenderOptions o;
  o.precision = p;
  o.volume_brick = brick;
  return render(device(), s, o, st);
}

struct Case {
  Model model;
  Scheme scheme;
};

class BrickedRender : public ::testing::TestWithParam<Case> {};

TEST_P(BrickedRender, EqualsInCoreForEveryBrickEdge) {
  const Case c = GetParam();
  const Scene s = bricked_scene(c.model, c.scheme);
  for (Precision p : {Precision::f64, Precision::f32}) {
    if (p == Precision::f64 && !device().info().fp64) continue;
    RenderStats in_stats;
    const Image in_core = render_with(s, p, 0, &in_stats);
    EXPECT_EQ(in_stats.bricks, 1);
    for (int edge : {1, 3, 4, 100}) {
      RenderStats st;
      const Image bricked = render_with(s, p, edge, &st);
      const BrickLayout l = brick_layout(11, 9, 13, edge);
      EXPECT_EQ(st.bricks, l.total()) << edge;
      EXPECT_EQ(st.brick_edge, edge);
      EXPECT_GE(st.sweeps, 1);
      expect_same(in_core, bricked, p == Precision::f64 ? 1e-12 : 1e-5,
                  std::string(name(p)) + " bricks of " + std::to_string(edge));
      // The exact scheme's pieces are cut in the whole volume's coordinates (kernels/exact.cl),
      // each in one brick: the in-core image bit for bit (before: 43 % of a float32 image's
      // values differed in their last bits).
      if (c.scheme == Scheme::exact) {
        EXPECT_EQ(in_core.pixels, bricked.pixels) << name(p) << " bricks of " << edge;
        EXPECT_EQ(in_core.pixels_f64, bricked.pixels_f64) << name(p) << " bricks of " << edge;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Schemes, BrickedRender,
    ::testing::Values(Case{Model::emission_absorption, Scheme::midpoint},
                      Case{Model::emission_absorption, Scheme::trapezoid},
                      Case{Model::emission_absorption, Scheme::preintegrated},
                      Case{Model::absorption, Scheme::midpoint},
                      Case{Model::absorption, Scheme::trapezoid},
                      Case{Model::absorption, Scheme::preintegrated},
                      Case{Model::absorption, Scheme::exact}),
    [](const ::testing::TestParamInfo<Case>& i) {
      return std::string(i.param.model == Model::absorption ? "absorption_" : "emission_") +
             scheme_name(i.param.scheme);
    });

// A ray list: rays from inside and outside, ends inside the box, infinite ends.
TEST(BrickedRenderRays, RayListEqualsInCore) {
  Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  const std::vector<double> rows = random_ray_rows(64, 3);
  s.rays = make_ray_list(rows.data(), 64, 8);
  s.cameras.clear();
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  const Image in_core = render_with(s, p, 0);
  for (int edge : {2, 5}) {
    RenderStats st;
    expect_same(in_core, render_with(s, p, edge, &st), p == Precision::f64 ? 1e-12 : 1e-5,
                "ray list, bricks of " + std::to_string(edge));
    EXPECT_GE(st.sweeps, 1);
  }
}

// The device-memory cap: a volume that does not fit is bricked by itself (and renders the same),
// one that fits stays in core, an impossible cap and malformed values are clear errors.
// On CPUs the fixed-step marches go through the bricks in packets of rays
// (kernels/bricked_packet.cl): the image and the sample counts are the one-ray kernel's
// (IVR_PACKET=0) bit for bit, under both models and precisions (midpoint; trapezoid and
// preintegrated with their carried end sample), for bricks of one cell to one brick, with rays
// that stop early.
TEST(BrickedPacket, MarchesAsTheOneRayKernelBitForBit) {
  for (Scheme scheme : {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated})
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Precision p : {Precision::f32, Precision::f64}) {
      if (p == Precision::f64 && !device().info().fp64) continue;
      // (The endpoint schemes: trapezoid absorption f32 and emission f64, preintegrated the
      // other two pairs.)
      const bool pair = (model == Model::absorption) == (p == Precision::f32);
      if ((scheme == Scheme::trapezoid && !pair) || (scheme == Scheme::preintegrated && pair))
        continue;
      const Scene s = bricked_scene(model, scheme);
      for (int edge : {1, 3, 100}) {
        const std::string what = std::string(scheme_name(scheme)) +
                                 (model == Model::absorption ? " absorption " : " emission ") +
                                 name(p) + ", bricks of " + std::to_string(edge);
        RenderStats packet_stats, one_stats;
        const Image packet = render_with(s, p, edge, &packet_stats);
        Image one;
        {
          ScopedEnv off("IVR_PACKET", "0");
          one = render_with(s, p, edge, &one_stats);
        }
        if (device().info().type == "cpu")
          EXPECT_NE(packet_stats.variant.find("packet"), std::string::npos)
              << what << ": " << packet_stats.variant;
        EXPECT_EQ(one_stats.variant.find("packet"), std::string::npos) << what;
        EXPECT_EQ(packet.pixels, one.pixels) << what;
        EXPECT_EQ(packet.pixels_f64, one.pixels_f64) << what;
        EXPECT_EQ(packet_stats.samples, one_stats.samples) << what;
        EXPECT_EQ(packet_stats.sweeps, one_stats.sweeps) << what;
      }
    }
}

TEST(BrickedRenderMemory, CapChoosesBricksAndErrorsAreClear) {
  Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  s.volume.nx = 40, s.volume.ny = 36, s.volume.nz = 44;
  s.volume.data.assign(s.volume.voxel_count(), 0.5f);
  for (std::size_t i = 0; i < s.volume.data.size(); ++i) s.volume.data[i] = float((i * 7919) % 101) / 100;
  set_default_box(s);
  const Image in_core = render_with(s, Precision::f32, 0);
  {
    ScopedEnv cap("IVR_DEVICE_MEMORY_LIMIT", "160K");  // the volume alone is 253 KiB
    RenderStats st;
    const Image capped = render_with(s, Precision::f32, 0, &st);
    EXPECT_GT(st.bricks, 1);
    EXPECT_LE(st.device_bytes, 160u * 1024);
    expect_same(in_core, capped, 1e-5, "under a 160 KiB cap");
  }
  {
    ScopedEnv cap("IVR_DEVICE_MEMORY_LIMIT", "64M");
    RenderStats st;
    render_with(s, Precision::f32, 0, &st);
    EXPECT_EQ(st.bricks, 1);
  }
  {
    ScopedEnv cap("IVR_DEVICE_MEMORY_LIMIT", "2K");
    try {
      render_with(s, Precision::f32, 0);
      ADD_FAILURE() << "a 2 KiB cap rendered";
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::out_of_memory);
      EXPECT_TRUE(has(e.what(), "IVR_DEVICE_MEMORY_LIMIT")) << e.what();
    }
  }
  for (const char* bad : {"lots", "-5", "12Q", "0"}) {
    ScopedEnv cap("IVR_DEVICE_MEMORY_LIMIT", bad);
    try {
      render_with(s, Precision::f32, 0);
      ADD_FAILURE() << bad;
    } catch (const Error& e) {
      EXPECT_EQ(e.status(), Status::invalid_argument) << bad;
      EXPECT_TRUE(has(e.what(), "IVR_DEVICE_MEMORY_LIMIT")) << e.what();
    }
  }
  {
    ScopedEnv brick("IVR_VOLUME_BRICK", "x");
    EXPECT_THROW(render_with(s, Precision::f32, 0), Error);
  }
  {
    ScopedEnv brick("IVR_VOLUME_BRICK", "16");
    RenderStats st;
    expect_same(in_core, render_with(s, Precision::f32, 0, &st), 1e-5, "IVR_VOLUME_BRICK=16");
    EXPECT_EQ(st.bricks, brick_layout(40, 36, 44, 16).total());
  }
}

}  // namespace
}  // namespace ivr
