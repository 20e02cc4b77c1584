// reconstruct_checkpoint.hpp — internal: reading a reconstruction's checkpoint into plain values,
// every part checked against what the run expects before any of the run's state changes (and
// without a device, so that tests/fuzz/fuzz_checkpoint.cpp can feed it any bytes).
#pragma once
#include <cstddef>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "ivr/reconstruct.hpp"
#include "reconstruct/lbfgs.hpp"
#include "reconstruct/optimize.hpp"

namespace ivr {

// What a checkpoint must hold to continue a run.
struct CheckpointShape {
  nlohmann::json fingerprint;  // the options, grid and targets that must match
  int iterations = 0;          // the run's
  // Density: the level iteration i (0-based) runs on, and each level's voxel count; empty
  // `voxels` when the run has no density.
  std::function<int(int)> level_of;
  std::vector<std::size_t> voxels;
  bool density_second_moments = false;  // Adam keeps them
  // TF: its parameter count (0: none), and which optimiser state it keeps.
  std::size_t tf_parameters = 0;
  std::optional<bool> tf_optimizer_second_moments;  // nullopt: no first-order TF optimiser
  int lbfgs_history = -1;                            // -1: no L-BFGS
};

struct CheckpointData {
  int iteration = 0, level = 0;
  std::vector<double> density;  // the level's grid, x fastest
  Optimizer::State density_state;
  std::vector<double> u;
  std::optional<Optimizer::State> tf_state;
  std::optional<Lbfgs::State> lbfgs;
  std::vector<IterationRecord> history;
};

// Reads PREFIX_checkpoint.json and the .npy files it names; throws Error(invalid_argument) "resume:
// …" naming the file and what does not fit, or Error(io) for files that cannot be read.
CheckpointData read_checkpoint(const std::string& prefix, const CheckpointShape& shape);

}  // namespace ivr
