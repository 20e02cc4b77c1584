// ivr/planner.hpp — chooses forward or adjoint mode for a gradient from a per-device cost model:
// forward costs grow with the number of parameters (passes of up to 32 tangent lanes), the
// adjoint's do not. The model comes from `ivr calibrate` (JSON per device in the user's cache
// folder) or, without a calibration, from built-in defaults.
#pragma once
#include <cstddef>
#include <string>

#include "ivr/device.hpp"
#include "ivr/export.h"
#include "ivr/scene.hpp"

namespace ivr {

enum class Mode { automatic, forward, adjoint };

// Costs relative to one render of the same scene: a forward pass with L lanes costs
// (forward_base + forward_per_lane · L) renders, an adjoint gradient `adjoint` renders; a render
// costs seconds_per_sample per density sample (to predict seconds). The defaults are `ivr
// calibrate` on a 2-core AMD EPYC with PoCL 3.1 (rounded): forward wins up to 8 lanes there.
// Forward passes whose lanes include camera or voxel (density) parameters (per-ray geometry) cost
// forward_ray_base + forward_ray_per_lane · L: on CPUs TF and background lanes march packets of
// rays in vector lanes and those lanes one ray per work-item; elsewhere the two are the same.
struct CostModel {
  double forward_base = 1.5;
  double forward_per_lane = 0.16;
  double forward_ray_base = 1.5;
  double forward_ray_per_lane = 0.16;
  double adjoint = 3.0;
  double seconds_per_sample = 1.2e-8;
  std::string source = "default";  // "default", or the file it was read from
};

// The calibration file of a device: $IVR_COST_MODEL if set, else <cache>/ivr/cost/<device>.json
// (<cache>: $XDG_CACHE_HOME or ~/.cache); the name is derived from platform, device and driver.
IVR_API std::string cost_model_path(const DeviceInfo& device);

// The built-in model of a device without a calibration file. CPU devices: measured with PoCL 3.1
// on a 2-core Skylake-AVX512 Xeon, where forward mode marches TF and background lanes in packets
// of rays and the adjoint marches packets too: forward 1.1 + 0.08 · L renders (`ivr calibrate`,
// 64³ → 128² and 128³ → 256²), with camera or voxel lanes 3.8 + 0.75 · L, adjoint 5.4 renders,
// 3.2e-9 s per sample (6.4e-9 s over the compute units: a CPU of more threads is estimated
// faster). Other devices: CostModel's defaults (forward 1.5 + 0.16 · L whatever the lanes,
// adjoint 3), the one-ray-per-work-item kernels' figures on a 2-core EPYC, and where the driver
// gives compute units and clock an estimate of seconds_per_sample from them: 950 cycles of a
// float32 lane per sample (measured on an H200) over the device's lanes.
IVR_API CostModel default_cost_model(const DeviceInfo& device);

// A device's render speed, 1 / seconds_per_sample of load_cost_model(device): what several
// devices' shares of the views are weighted by (share_weights, docs/scaling.md). Measured where
// `ivr calibrate` has run on the device; else default_cost_model()'s estimate from its size.
IVR_API double samples_per_second(const DeviceInfo& device);

// The device's model: its calibration file where one exists, else default_cost_model(). A file that
// exists but cannot be read or lacks a field is an error naming the file and the field (a file
// without the forward_ray_* fields, from before them, takes forward_*'s values for them).
IVR_API CostModel load_cost_model(const DeviceInfo& device);
IVR_API CostModel read_cost_model(const std::string& path);
IVR_API void save_cost_model(const std::string& path, const CostModel& model,
                             const DeviceInfo& device);

struct Plan {
  Mode mode = Mode::adjoint;
  double forward_seconds = 0, adjoint_seconds = 0;  // predicted (infinity where not possible)
  std::size_t passes = 0, lanes = 0;                // of the forward mode
  std::string model;                                // the cost model's source
};

// The passes and lanes forward mode needs for P parameters, and its cost in renders (per_ray:
// some lane is a camera or voxel parameter).
IVR_API double forward_cost(const CostModel& model, std::size_t parameters,
                            std::size_t* passes = nullptr, std::size_t* lanes = nullptr,
                            bool per_ray = false);

// Picks the cheaper mode for `forward_parameters` parameters (what forward mode would carry) of
// `scene` at `step` (voxel units; 0: the scene's). `requested` other than automatic is kept (and
// checked against what is possible); forward_possible / adjoint_possible say whether the
// parameter groups are available in each mode; per_ray that some of them are camera or voxel
// parameters (forward_cost).
IVR_API Plan plan_gradient(const CostModel& model, const Scene& scene,
                           std::size_t forward_parameters, bool forward_possible,
                           bool adjoint_possible, Mode requested = Mode::automatic,
                           double step = 0, bool per_ray = false);

IVR_API const char* mode_name(Mode mode);

}  // namespace ivr
