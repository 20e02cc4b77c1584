// baselines.hpp — the Python baselines (bench/baselines: JAX, Dr.Jit, PyTorch, and ASTRA for the
// projectors) as ivr-bench runs them: a case directory with the scene, one subprocess per framework
// and task, its JSON result and output array read back.
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "ivr/core.hpp"

namespace ivr::bench {

struct BaselineEnv {
  std::string python;  // the interpreter with the frameworks installed
  std::string script;  // bench/baselines/run.py
  bool usable = false;
  std::string note;                     // why not, when not
  std::vector<std::string> frameworks;  // the ones to try
  double timeout = 900;                 // seconds per subprocess
  int threads = 0;                      // passed to the frameworks (0: their default)
};

// `python` (option) else $IVR_BENCH_PYTHON else SOURCE/.venv-bench/bin/python, made by
// scripts/bench_setup.sh; unusable (with a note) when none exists.
BaselineEnv find_baselines(const std::string& python, const std::vector<std::string>& frameworks);

// Writes DIR/scene.json ("ivr-bench-scene/1"), DIR/volume.npy and DIR/target.npy for an
// emission–absorption scene with a piecewise-linear TF and the step (voxel units); returns DIR.
std::string write_case(const std::string& dir, const Scene& scene, double step_voxels,
                       const Image& target);

// Writes DIR/tomo.json ("ivr-bench-tomo/1": box, orthographic cameras), DIR/volume.npy (float32
// (nz, ny, nx)) and DIR/lines.npy (float32 (views, H, W), ivr's ray order) for the projector
// baseline (bench/baselines/astra_project.py); returns DIR.
std::string write_tomo_case(const std::string& dir, const Scene& scene,
                            const std::vector<double>& volume, const std::vector<double>& lines);

// Whether `framework` does `task`: the march frameworks (jax, drjit, torch) render, grad and
// tf_forward; astra projects and backprojects (run.py's table).
bool baseline_does(const std::string& framework, const std::string& task);

struct BaselineRun {
  bool available = false;      // the framework is installed
  bool ok = false;             // it ran to the end
  std::string note;            // why not
  nlohmann::json result;       // run.py's document
  std::vector<double> output;  // the array named by `output` (empty when none)
  double loss = NAN;
};

// Runs `framework`'s `task` ("render", "grad", "tf_forward"; astra: "project", "backproject") on
// the case and reads back its output array `output` ("image", "grad", "tf_grad"; "lines",
// "volume").
// `device`: "cpu" or "gpu" (run.py's --device: the data on the GPU before the timed calls).
BaselineRun run_baseline(const BaselineEnv& env, const std::string& framework,
                         const std::string& task, const std::string& case_dir, double budget,
                         const std::string& output, const std::string& device = "cpu");

}  // namespace ivr::bench
