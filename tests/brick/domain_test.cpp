// domain_test.cpp — domain-parallel render and density gradient (lib/brick/domain.cpp): workers on
// threads, each with its own device context and only its slab of the volume, exchanging the rays'
// states through an in-process all-gather, give one process's image and gradient; bad input is
// refused with clear errors.
#include "ivr/domain.hpp"
#include "ivr/volume_io.hpp"

#include <gtest/gtest.h>

#include "brick_support.hpp"
#include "domain_support.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

TEST(Domain, SlabsCutTheCellsEvenlyAndShareOnePlane) {
  for (int ranks : {1, 2, 3, 5, 12}) {
    int next = 0;
    for (int w = 0; w < ranks; ++w) {
      const Slab s = domain_slab(13, w, ranks);
      EXPECT_EQ(s.first, next) << ranks << " workers, worker " << w;
      EXPECT_GE(s.planes(), 1 + 12 / ranks);
      EXPECT_LE(s.planes(), 2 + 12 / ranks);
      next = s.last;
    }
    EXPECT_EQ(next, 12);
  }
}

TEST(Domain, RenderEqualsOneProcessForEveryScheme) {
  for (Model model : {Model::emission_absorption, Model::absorption})
    for (Scheme scheme :
         {Scheme::midpoint, Scheme::trapezoid, Scheme::preintegrated, Scheme::exact}) {
      if (scheme == Scheme::exact && model != Model::absorption) continue;  // absorption only
      const Scene s = bricked_scene(model, scheme);
      for (Precision p : {Precision::f64, Precision::f32}) {
        if (p == Precision::f64 && !device().info().fp64) continue;
        RenderOptions o;
        o.precision = p;
        const Image one = render(device(), s, o);
        // Two workers with bricks of 3 cells in their slabs, five with one brick per slab.
        for (const std::pair<int, int>& c :
             {std::pair<int, int>{2, 3}, std::pair<int, int>{5, 0}}) {
          const int ranks = c.first, edge = c.second;
          const std::string what =
              std::string(model == Model::absorption ? "absorption " : "emission ") +
              scheme_name(scheme) + " " + name(p) + ", " + std::to_string(ranks) +
              " workers, bricks " + std::to_string(edge);
          o.volume_brick = edge;
          std::vector<DomainStats> ds(ranks);
          const std::vector<Image> images =
              on_workers<Image>(ranks, [&](int w, const DomainPart& part, Device& d) {
                RenderStats st;
                Image img = render_domain(d, domain_share(s, w, ranks), part, o, &st, &ds[w]);
                EXPECT_GE(st.sweeps, 1) << what;
                return img;
              });
          expect_same(one, images[0], p == Precision::f64 ? 1e-12 : 1e-5, what);
          for (int w = 1; w < ranks; ++w) {
            EXPECT_EQ(images[w].pixels, images[0].pixels) << what << ": worker " << w;
            EXPECT_EQ(images[w].pixels_f64, images[0].pixels_f64) << what << ": worker " << w;
          }
          // The rays cross slabs: some worker sent states, and every worker received some.
          std::uint64_t sent = 0;
          for (const DomainStats& d : ds) sent += d.sent_bytes;
          EXPECT_GT(sent, 0u) << what;
          for (int w = 0; w < ranks; ++w) {
            EXPECT_GT(ds[w].received_bytes, 0u) << what << ": worker " << w;
            EXPECT_EQ(ds[w].exchanges, ds[0].exchanges) << what;
          }
        }
      }
    }
}

// The density and TF gradients over slabs (midpoint under both models; exact, absorption: its
// pieces lie between centre planes, so in one slab) equal one process's.
// Every scheme's density and TF gradients over slabs: the endpoint schemes' bricks hold a halo of
// their neighbours' planes (with_neighbour_planes) and send back what it gathered (return_halo).
TEST(Domain, GradientEqualsOneProcess) {
  for (Scheme scheme :
       {Scheme::midpoint, Scheme::exact, Scheme::trapezoid, Scheme::preintegrated})
    for (Model model : {Model::emission_absorption, Model::absorption})
      for (Precision p : {Precision::f64, Precision::f32}) {
        if (p == Precision::f64 && !device().info().fp64) continue;
        if (scheme == Scheme::exact && model != Model::absorption) continue;
        // (The endpoint schemes' halo exchange once, in the stricter precision: CI time.)
        const bool endpoint = scheme == Scheme::trapezoid || scheme == Scheme::preintegrated;
        if (endpoint && p == Precision::f32 && device().info().fp64) continue;
        const Scene s = bricked_scene(model, scheme);
        Image target = render(device(), s);
        for (float& v : target.pixels) v = 0.8f * v + 0.05f;
        GradientOptions o;
        o.precision = p;
        o.mode = Mode::adjoint;
        const Gradient one = gradient(device(), s, target, {"density", "tf"}, o);
        const std::vector<double>& tf_one = one.groups[1].values;
        const double tol = p == Precision::f64 ? 1e-12 : 1e-5;
        for (int ranks : {2, 4}) {
          const std::string what = std::string(scheme_name(scheme)) +
                                   (model == Model::absorption ? " absorption " : " emission ") +
                                   name(p) + ", " + std::to_string(ranks) + " workers";
          const std::vector<Gradient> parts =
              on_workers<Gradient>(ranks, [&](int w, const DomainPart& part, Device& d) {
                return gradient_domain(d, domain_share(s, w, ranks), target, part, o, nullptr,
                                       {"density", "tf"});
              });
          std::vector<std::vector<double>> slabs;
          std::vector<double> tf(tf_one.size(), 0.0);  // the workers' parts summed
          for (int w = 0; w < ranks; ++w) {
            const Slab slab = domain_slab(s.volume.nz, w, ranks);
            ASSERT_EQ(parts[w].groups.size(), 2u) << what;
            ASSERT_EQ(parts[w].groups[1].values.size(), tf.size()) << what;
            for (std::size_t i = 0; i < tf.size(); ++i) tf[i] += parts[w].groups[1].values[i];
            EXPECT_EQ(parts[w].groups[0].shape,
                      (std::vector<std::size_t>{std::size_t(slab.planes()), 9, 11}))
                << what;
            EXPECT_NEAR(parts[w].loss, one.loss, tol * std::abs(one.loss) + 1e-15) << what;
            slabs.push_back(parts[w].groups[0].values);
          }
          expect_close_values(one.groups[0].values, domain_join(11, 9, 13, slabs), tol,
                              what + " density");
          expect_close_values(tf_one, tf, tol, what + " tf");
        }
      }
}

// load_scene with a plane chooser reads a worker's slab (domain_slab) — of a .npy file and of a
// synthetic volume alike — and equals domain_share of the whole scene.
TEST(Domain, LoadSceneKeepsOnlyTheSlab) {
  const std::string dir = temp_dir("domain_load_slab");
  const Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  save_npy(dir + "/v.npy", {std::size_t(s.volume.nz), std::size_t(s.volume.ny), std::size_t(s.volume.nx)},
           s.volume.data.data());
  const std::string cameras = R"("cameras": [{"eye": [1.2, 0.8, 1.5], "width": 6, "height": 5}])";
  const std::string file_scene = write_file(dir + "/file.json", R"({"volume": {"file": "v.npy"}, )" + cameras + "}");
  const std::string synthetic_scene = write_file(
      dir + "/synthetic.json", R"({"volume": {"synthetic": "sphere", "dims": [11, 9, 13]}, )" + cameras + "}");
  for (const std::string& path : {file_scene, synthetic_scene})
    for (int rank : {0, 1, 2}) {
      const Scene slab = load_scene(path, [&](int nz) {
        const Slab cut = domain_slab(nz, rank, 3);
        return std::pair<int, int>{cut.first, cut.last};
      });
      const Scene want = domain_share(load_scene(path), rank, 3);
      EXPECT_EQ(slab.volume.nz, 13) << path;
      EXPECT_EQ(slab.volume.data, want.volume.data) << path << " worker " << rank;
    }
}

// Forward lanes over slabs: the camera's tangents travel with the rays' states, so every worker
// ends with the whole camera gradient — the in-core adjoint's to rounding — beside the density's
// slab parts (joined) and the background's (whole).
// The camera's gradient by forward lanes over slabs — the tangents carried with the rays' states,
// or (SlabMarch::segments) each worker's segments' tangents composited with the others' — beside
// the density's and background's by the adjoint, against one process's adjoint.
TEST(Domain, CameraGradientOverSlabsAndSegments) {
  struct Case {
    SlabMarch march;
    Model model;
    Scheme scheme;
  };
  const Case cases[] = {{SlabMarch::states, Model::emission_absorption, Scheme::midpoint},
                        {SlabMarch::segments, Model::emission_absorption, Scheme::midpoint},
                        {SlabMarch::segments, Model::emission_absorption, Scheme::trapezoid},
                        {SlabMarch::segments, Model::absorption, Scheme::exact}};
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  for (const Case& c : cases) {
    Scene s = bricked_scene(c.model, c.scheme);
    // (Over segments one process's march where early termination is off.)
    if (c.march == SlabMarch::segments) s.integrator.min_transmittance = 0;
    Image target = render(device(), s);
    for (float& v : target.pixels) v = 0.8f * v + 0.05f;
    GradientOptions o;
    o.precision = p;
    o.mode = Mode::adjoint;
    const std::vector<std::string> groups = {"density", "camera", "background"};
    const Gradient one = gradient(device(), s, target, groups, o);
    o.mode = Mode::automatic;
    const double tol = p == Precision::f64 ? 1e-10 : 1e-4;
    for (int ranks : {2, 3}) {
      const std::vector<Gradient> parts =
          on_workers<Gradient>(ranks, [&](int w, DomainPart part, Device& d) {
            part.march = c.march;
            return gradient_domain(d, domain_share(s, w, ranks), target, part, o, nullptr, groups);
          });
      const std::string what = std::string(c.march == SlabMarch::states ? "states " : "segments ") +
                               scheme_name(c.scheme) + ", " + std::to_string(ranks) + " workers";
      std::vector<std::vector<double>> slabs;
      for (int w = 0; w < ranks; ++w) {
        ASSERT_EQ(parts[w].groups.size(), 3u) << what;
        slabs.push_back(parts[w].groups[0].values);
        EXPECT_EQ(parts[w].groups[1].values, parts[0].groups[1].values) << what << ", worker " << w;
        EXPECT_NEAR(parts[w].loss, one.loss, tol * one.loss) << what;
      }
      expect_close_values(one.groups[0].values,
                          domain_join(s.volume.nx, s.volume.ny, s.volume.nz, slabs), tol,
                          what + " density");
      expect_close_values(one.groups[1].values, parts[0].groups[1].values, tol, what + " camera");
      expect_close_values(one.groups[2].values, parts[0].groups[2].values, tol,
                          what + " background");
    }
  }
}

TEST(Domain, BadInputIsRefusedClearly) {
  const Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
  DomainPart part;
  part.ranks = 13;  // 12 cells
  expect_error([&] { render_domain(device(), s, part); }, Status::invalid_argument, "13 workers");
  part.ranks = 2;
  expect_error([&] { render_domain(device(), domain_share(s, 0, 2), part); },
               Status::invalid_argument, "all_gather");
  part.rank = 2;
  part.all_gather = [](const std::vector<unsigned char>& m) {
    return std::vector<std::vector<unsigned char>>{m, m};
  };
  expect_error([&] { render_domain(device(), s, part); }, Status::invalid_argument,
               "worker 2 of 2");
  part.rank = 0;
  // The whole volume where worker 0's slab (planes 0..6) was wanted.
  expect_error([&] { render_domain(device(), s, part); }, Status::invalid_argument, "planes 0..6");
  Scene trapezoid = s;  // (the whole volume, where the gradient with a halo wants the slab)
  trapezoid.integrator.scheme = Scheme::trapezoid;
  expect_error([&] { gradient_domain(device(), trapezoid, render(device(), s), part); },
               Status::invalid_argument, "planes 0..6");
  expect_error(
      [&] {
        GradientOptions forward;
        forward.mode = Mode::forward;
        gradient_domain(device(), domain_share(s, 0, 2), render(device(), s), part, forward,
                        nullptr, {"tf"});
      },
      Status::unsupported, "not forward mode");
  expect_error(
      [&] {
        domain_join(11, 9, 13, {std::vector<double>(11 * 9 * 7), {1.0}});
      },
      Status::invalid_argument, "worker 1");
}

}  // namespace
}  // namespace ivr::test
