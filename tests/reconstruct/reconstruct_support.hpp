// reconstruct_support.hpp — scenes shared by the reconstruction tests: a 32³ Shepp–Logan
// phantom under an emission–absorption TF, seen by 16 training views on two orbits and 4
// held-out views on a third; a small scene and workers on threads.
#pragma once
#include <string>
#include <thread>
#include <vector>

#include "ivr/domain.hpp"
#include "ivr/reconstruct.hpp"
#include "multi_device/worker_sum.hpp"
#include "test_support.hpp"

namespace ivr::test {

// The phantom's TF: extinction and colour rising with density, so every density is visible.
inline const char* kPhantomTf =
    R"({"type": "piecewise_linear", "points": [
         {"density": 0, "color": [0, 0, 0], "extinction": 0},
         {"density": 1, "color": [1, 0.7, 0.4], "extinction": 8},
         {"density": 2, "color": [0.5, 0.8, 1], "extinction": 16}]})";

// `cameras`: a JSON array of camera objects or orbits; image size `size`².
inline Scene phantom_scene(const std::string& cameras, int n = 32) {
  const std::string text = R"({"volume": {"synthetic": "zeros", "dims": [)" + std::to_string(n) +
                           "," + std::to_string(n) + "," + std::to_string(n) +
                           R"(]}, "model": "emission_absorption", "tf": )" + kPhantomTf +
                           R"(, "background": [0, 0, 0], "cameras": )" + cameras +
                           R"(, "integrator": {"scheme": "midpoint", "step": 0.5}})";
  Scene s = parse_scene(text, ".", "test scene");
  s.volume = phantom("shepp-logan", n, 1, 2);
  return s;
}

inline std::string orbit(int views, const char* axis, double start, int size) {
  return R"({"orbit": {"views": )" + std::to_string(views) + R"(, "axis": )" + axis +
         R"(, "start": )" + std::to_string(start) + R"(, "radius": 2.2, "fov_y": 40, "width": )" +
         std::to_string(size) + R"(, "height": )" + std::to_string(size) + "}}";
}

// 16 training views of size² (8 about z, 8 about x) and 4 held-out views about y.
inline std::string training_cameras(int size = 64) {
  return "[" + orbit(8, "[0, 0, 1]", 0, size) + ", " + orbit(8, "[1, 0, 0]", 22.5, size) + "]";
}
inline std::string held_out_cameras(int size = 64) {
  return "[" + orbit(4, "[0, 1, 0]", 10, size) + "]";
}

// A 16³ phantom seen by 8 views of 24² about a tilted axis, and its renders.
struct Small {
  Scene scene;
  Image targets;
  Small() {
    scene = test::phantom_scene("[" + test::orbit(8, "[0.2, 0.1, 1]", 3, 24) + "]", 16);
    targets = render(device(), scene);
  }
};

// `workers` reconstructions on threads (each its own context, options `o` with its worker index and
// a sum through a rendezvous: every worker gets Σ of all, added in worker order), run to the end:
// each worker's history and densities (over slabs, o.slabs: its planes, given domain_share()'s),
// and its error where it threw.
struct WorkerRuns {
  std::vector<std::vector<IterationRecord>> histories;
  std::vector<std::vector<double>> densities;
  std::vector<std::string> errors;
};
inline WorkerRuns run_workers(int workers, const Scene& scene, const Image& targets,
                              const ReconstructOptions& o) {
  WorkerSum sum(workers);
  WorkerRuns out;
  out.histories.resize(std::size_t(workers));
  out.densities.resize(std::size_t(workers));
  out.errors.resize(std::size_t(workers));
  std::vector<std::thread> threads;
  for (int w = 0; w < workers; ++w)
    threads.emplace_back([&, w] {
      try {
        Device d(std::to_string(device().info().index));
        ReconstructOptions ow = o;
        ow.worker = w, ow.workers = workers, ow.sum = sum.of(w);
        Reconstruction r(d, ow.slabs ? domain_share(scene, w, workers, ow.shares) : scene, targets,
                         ow);
        while (!r.done()) r.step();
        out.histories[std::size_t(w)] = r.history();
        const std::vector<float>& v = r.result().volume.data;
        out.densities[std::size_t(w)].assign(v.begin(), v.end());
      } catch (const std::exception& e) {
        out.errors[std::size_t(w)] = e.what();
        sum.abort();  // (the others stop rather than wait for this worker)
      }
    });
  for (std::thread& t : threads) t.join();
  return out;
}

}  // namespace ivr::test
