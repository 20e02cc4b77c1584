// device_slabs_test.cpp — one volume's slabs spread over several devices of one process
// (lib/multi_device/device_slabs.cpp; here separate contexts on the test device): the render and
// every gradient group equal one device's, fixed point gives the same bits twice, the command
// line takes it with --device A,B --split (render, gradient and tomo), and bad input is refused
// before any work.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "adjoint/adjoint.hpp"
#include "brick/brick_support.hpp"
#include "brick/domain_support.hpp"
#include "ivr/domain.hpp"
#include "ivr/gradient.hpp"
#include "ivr/render.hpp"
#include "ivr/volume_io.hpp"
#include "multi_device/worker_sum.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

const char* march_name(SlabMarch m) {
  return m == SlabMarch::states ? "states" : "segments";
}

// The devices' slabs against one device in core: the image, the loss, the density of the whole
// volume (the slabs joined), the TF gradient (the devices' parts summed) and the background and
// camera gradients, for both marches, 2 and 3 devices, bricks inside the slabs or not.
TEST(DeviceSlabs, RenderAndGradientsEqualOneDevice) {
  const Precision p = device().info().fp64 ? Precision::f64 : Precision::f32;
  for (SlabMarch march : {SlabMarch::states, SlabMarch::segments}) {
    Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);
    // (Over segments one device's march where early termination is off.)
    if (march == SlabMarch::segments) s.integrator.min_transmittance = 0;
    RenderOptions ro;
    ro.precision = p;
    const Image one = render(device(), s, ro);
    const Image target = dimmed(one);
    GradientOptions go;
    go.precision = p;
    go.mode = Mode::adjoint;
    const std::vector<std::string> groups = {"density", "tf", "background", "camera"};
    const Gradient g1 = gradient(device(), s, target, groups, go);
    go.mode = Mode::automatic;  // (the camera by forward lanes over the slabs)
    for (int count : {2, 3}) {
      const std::string what =
          std::string(march_name(march)) + ", " + std::to_string(count) + " devices";
      const auto devices = device_contexts(count);
      RenderStats st;
      DomainStats ds;
      ro.volume_brick = count == 2 ? 3 : 0;  // bricks inside each slab, or a slab a brick
      const Image many = render_domain(pointers_to(devices), s, march, ro, &st, &ds);
      expect_same(one, many, p == Precision::f64 ? 1e-12 : 1e-5, what);
      EXPECT_EQ(st.devices, count) << what;
      EXPECT_GE(st.bricks, count) << what;  // (summed over the devices' slabs)
      EXPECT_GT(ds.exchanges, 0) << what;
      EXPECT_GT(ds.received_bytes, 0u) << what;

      const Gradient gm = gradient_domain(pointers_to(devices), s, target, march, go, nullptr, groups);
      EXPECT_EQ(gm.devices, count) << what;
      const double tol = p == Precision::f64 ? 1e-10 : 1e-4;
      EXPECT_NEAR(gm.loss, g1.loss, tol * g1.loss) << what;
      ASSERT_EQ(gm.groups.size(), groups.size()) << what;
      std::size_t parameters = 0;
      for (std::size_t k = 0; k < groups.size(); ++k) {
        EXPECT_EQ(gm.groups[k].name, groups[k]) << what;
        EXPECT_EQ(gm.groups[k].shape, g1.groups[k].shape) << what << " " << groups[k];
        expect_close_values(g1.groups[k].values, gm.groups[k].values, tol,
                            what + " " + groups[k]);
        parameters += gm.groups[k].values.size();
      }
      EXPECT_EQ(gm.parameters, parameters) << what;
    }
  }
}

// Fixed point over the devices' slabs: one device's in-core fixed-point gradient bit for bit
// (so the same bits on every run), within the fixed-point rounding of its float sums.
TEST(DeviceSlabs, DeterministicGradientIsOneDevicesBits) {
  if (!has_int64_atomics(device().impl())) GTEST_SKIP() << "no cl_khr_int64_base_atomics";
  const Scene s = bricked_scene(Model::emission_absorption, Scheme::trapezoid);
  Image target = render(device(), s);
  for (float& v : target.pixels) v = 0.8f * v + 0.05f;
  GradientOptions o;
  o.precision = Precision::f32;
  o.mode = Mode::adjoint;
  const Gradient floats = gradient(device(), s, target, {"density"}, o);
  o.deterministic = true;
  const Gradient one = gradient(device(), s, target, {"density"}, o);
  const auto devices = device_contexts(2);
  const Gradient a = gradient_domain(pointers_to(devices), s, target, SlabMarch::states, o);
  const Gradient b = gradient_domain(pointers_to(devices), s, target, SlabMarch::states, o);
  EXPECT_TRUE(a.deterministic);
  ASSERT_EQ(a.groups.size(), 1u);
  EXPECT_EQ(a.groups[0].values, b.groups[0].values);
  EXPECT_EQ(a.groups[0].values, one.groups[0].values) << "not one device's bits";
  expect_close_values(floats.groups[0].values, a.groups[0].values, 1e-5, "fixed point");
}

TEST(DeviceSlabs, BadInputIsRefusedBeforeAnyWork) {
  const Scene s = bricked_scene(Model::emission_absorption, Scheme::midpoint);  // 13 planes
  const auto many = device_contexts(13);  // one more than the 12 cells
  expect_error([&] { render_domain(pointers_to(many), s); }, Status::invalid_argument,
               "13 workers for a volume of 13 planes");
  expect_error([&] { render_domain(std::vector<Device*>{}, s); }, Status::invalid_argument,
               "none given");
  expect_error([&] { render_domain(std::vector<Device*>{&device(), nullptr}, s); },
               Status::invalid_argument, "devices[1]: null");
  GradientOptions worker;
  worker.worker = 1, worker.workers = 2;
  const Image target = render(device(), s);
  expect_error(
      [&] { gradient_domain(pointers_to(device_contexts(2)), s, target, SlabMarch::states, worker); },
      Status::invalid_argument, "give each worker one device");
  // A device's own error is the one reported, the other devices' exchanges stopped.
  Scene bad = s;
  bad.volume.data.pop_back();
  expect_error([&] { render_domain(pointers_to(device_contexts(2)), bad); }, Status::invalid_argument, "volume");
}

// The in-process all-gather: every worker's part in worker order each round; a worker's abort
// stops the others' waiting instead of leaving them waiting for ever.
TEST(DeviceSlabs, WorkerGatherMeetsInOrderAndStopsOnAbort) {
  WorkerGather meeting(3);
  std::vector<std::vector<std::vector<unsigned char>>> got(3);
  std::vector<std::thread> threads;
  for (int w = 0; w < 3; ++w)
    threads.emplace_back([&, w] {
      for (unsigned char round = 0; round < 4; ++round) {
        const auto all = meeting.all_gather(w, {static_cast<unsigned char>(10 * w + round)});
        for (const auto& part : all) got[std::size_t(w)].push_back(part);
      }
    });
  for (std::thread& t : threads) t.join();
  for (int w = 0; w < 3; ++w) {
    ASSERT_EQ(got[std::size_t(w)].size(), 12u);
    for (int round = 0; round < 4; ++round)
      for (int from = 0; from < 3; ++from)
        EXPECT_EQ(got[std::size_t(w)][std::size_t(3 * round + from)],
                  std::vector<unsigned char>{static_cast<unsigned char>(10 * from + round)});
  }
  WorkerGather stopped(2);
  std::string error;
  std::thread waiter([&] {
    try {
      stopped.all_gather(0, {1});
    } catch (const WorkerSumStopped& e) {
      error = e.what();
    }
  });
  stopped.abort();
  waiter.join();
  EXPECT_TRUE(has(error, "another worker failed")) << error;
  EXPECT_THROW(stopped.all_gather(1, {2}), WorkerSumStopped);
}

// `ivr render|gradient --split slabs|segments --device A,B` without mpirun: each device a slab,
// the image and the density gradient one device's (float64 files).
TEST(DeviceSlabs, CommandLine) {
  if (!device().info().fp64) GTEST_SKIP() << "float64 files";
  const std::string dir = temp_dir("device_slabs_cli");
  const std::string scene = write_file(dir + "/scene.json", R"({
    "volume": {"synthetic": "sphere", "dims": [14, 12, 16]}, "model": "emission_absorption",
    "tf": {"type": "piecewise_linear", "points": [
      {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0},
      {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
    "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 12, "height": 10},
                {"eye": [0.1, 0.2, -1.9], "width": 12, "height": 10}],
    "integrator": {"scheme": "midpoint", "step": 0.5, "min_transmittance": 0}})");
  const std::string d = std::to_string(device().info().index);
  CliResult r = run_cli("render '" + scene + "' -o '" + dir + "/one.npy' --precision f64 --device " + d);
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_cli("gradient '" + scene + "' --target '" + dir + "/one.npy' --wrt density --loss dot "
              "--mode adjoint --precision f64 -o '" + dir + "/g1' --device " + d);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<double> image = load_npy(dir + "/one.npy").data;
  const std::vector<double> density = load_npy(dir + "/g1_density.npy").data;
  for (const char* split : {"slabs", "segments"}) {
    r = run_cli("render '" + scene + "' -o '" + dir + "/two.npy' --precision f64 --json --split " +
                split + " --device " + d + "," + d);
    ASSERT_EQ(r.status, 0) << split << ": " << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["devices"], 2) << r.out;
    EXPECT_GE(j["bricks"].get<int>(), 2) << r.out;
    expect_close_values(image, load_npy(dir + "/two.npy").data, 1e-12,
                        std::string(split) + " render");
    r = run_cli("gradient '" + scene + "' --target '" + dir + "/one.npy' --wrt density --loss dot "
                "--mode adjoint --precision f64 -o '" + dir + "/g2' --json --split " + split +
                " --device " + d + "," + d + "," + d);
    ASSERT_EQ(r.status, 0) << split << ": " << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["devices"], 3) << r.out;
    expect_close_values(density, load_npy(dir + "/g2_density.npy").data, 1e-12,
                        std::string(split) + " density");
  }
  // Tomography: each device a slab of the iterate, or a share of the views.
  const std::string tomo_scene = write_file(dir + "/tomo.json", R"({
    "volume": {"synthetic": "shepp_logan", "dims": [12, 11, 10]}, "model": "absorption",
    "tf": {"type": "identity"},
    "cameras": [{"orbit": {"views": 4, "axis": [0, 1, 0], "radius": 2.5, "fov_y": 40,
                 "width": 10, "height": 9}}],
    "integrator": {"scheme": "midpoint", "step": 0.5}})");
  r = run_cli("project '" + tomo_scene + "' -o '" + dir + "/p.npy' --precision f64 --device " + d);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string tomo = "tomo '" + tomo_scene + "' --projections '" + dir +
                           "/p.npy' --iterations 4 --precision f64 --device " + d;
  r = run_cli(tomo + " -o '" + dir + "/x1.npy'");
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_cli(tomo + "," + d + " -o '" + dir + "/x2.npy' --json --split slabs");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["devices"], 2) << r.out;
  expect_close_values(load_npy(dir + "/x1.npy").data, load_npy(dir + "/x2.npy").data, 1e-10,
                      "tomo over 2 devices' slabs");
  r = run_cli(tomo + "," + d + " -o '" + dir + "/x3.npy' --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["devices"], 2) << r.out;
  expect_close_values(load_npy(dir + "/x1.npy").data, load_npy(dir + "/x3.npy").data, 1e-10,
                      "tomo over 2 devices' views");
}

}  // namespace
}  // namespace ivr::test
