// ivr/tune.hpp — measuring the work-group shape of each kernel on a device and writing the launch
// database's rows for it (what `ivr tune` runs; the rows go into lib/runtime/device_params_db.inc).
#pragma once
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "ivr/device.hpp"
#include "ivr/export.h"

namespace ivr {

struct TuneCandidate;

// What ranks the candidates: the median of each one's timed rounds, or their minimum — the
// better estimate on a machine others share, where load only ever adds time.
enum class TuneStatistic { median, minimum };

struct TuneOptions {
  int volume = 128;   // the Marschner–Lobb volume's edge (ivr::calibration_scene)
  int image = 256;    // the image's width and height
  int views = 1;      // views around the volume (more work per launch, for large GPUs)
  double step = 0.5;  // the integrator step in voxels
  int repeats = 5;    // timed rounds, each running every candidate once, after warm-ups
  TuneStatistic statistic = TuneStatistic::median;
  // Tuning names to measure (render, render_packet, adjoint, tangents, project, backproject);
  // empty: every one the device launches.
  std::vector<std::string> kernels;
  // Work-group shapes to try; {0, 0} is the driver's choice. Empty: tune_candidates(). Shapes
  // beyond the device's or the kernel's limit are recorded as skipped.
  std::vector<std::pair<int, int>> candidates;
  // The shape in use now (the database's) stays the winner unless the fastest is faster by more
  // than this fraction: a new row has to beat the noise.
  double tie = 0.03;
  // Called for each candidate (timed or skipped) once its kernel is done, e.g. to show progress;
  // may be empty.
  std::function<void(const std::string& kernel, const TuneCandidate&)> progress;
};

// The default candidates: the driver's choice, 8x8, 16x8, 16x16, 32x4, 32x8, 64x1, 64x4, 128x1,
// 256x1.
IVR_API std::vector<std::pair<int, int>> tune_candidates();
// Every tuning name the tuner knows, in the order it measures them.
IVR_API std::vector<std::string> tune_kernels();

struct TuneCandidate {
  int local_x = 0, local_y = 0;  // 0x0: the driver's choice
  std::vector<double> seconds;   // device time of the kernel in each timed run
  double median_seconds = 0, min_seconds = 0;
  double score_seconds = 0;  // the one of the two that the options' statistic ranks by
  std::string skipped;       // why it was not timed (beyond a limit, a launch failure); "" if timed
};

struct KernelTuning {
  std::string kernel;        // the tuning name (the database's "kernel" field)
  std::string operation;     // what ran to launch it, e.g. "gradient (adjoint, d mse / d density)"
  std::string skipped;       // why the kernel was not measured ("" if it was)
  bool failed = false;       // it was launched, but no candidate ran (skipped says why)
  bool needs_group = false;  // barriers or local memory: never the driver's choice
  std::size_t kernel_max_group = 0;  // CL_KERNEL_WORK_GROUP_SIZE
  std::string check;                 // how the candidates' outputs were compared
  int current_x = 0, current_y = 0;  // the shape the database gives now (as launched)
  std::string current_source;        // the row it came from (LaunchParams::source)
  std::vector<TuneCandidate> candidates;
  int fastest = -1;  // index into candidates: the smallest score
  int winner = -1;   // the current shape unless the fastest beats it by more than `tie`
};

struct TuneResult {
  DeviceInfo device;
  TuneOptions options;
  std::string date;  // UTC, ISO 8601
  std::vector<KernelTuning> kernels;
};

// Times every candidate shape of every kernel on the representative scene and picks each one's
// winner. Outputs that do not depend on the shape (render, render_packet, tangents, project, the
// adjoint's loss) must agree bit for bit across candidates, the scattered sums (the adjoint's
// density gradient, backproject) to 1e-4 of their largest value; anything else throws
// ivr::Error(opencl) naming the kernel and shapes. Bad options throw invalid_argument.
IVR_API TuneResult tune(Device& device, const TuneOptions& options = {});

// The database rows of the winners, ready to paste into lib/runtime/device_params_db.inc: a comment line
// naming the device, vendor, driver, date and `command`, then one
// {kernel, vendor, device, local_x, local_y}, row a line with the scores in a trailing comment.
IVR_API std::string tune_database_rows(const TuneResult& result, const std::string& command);

}  // namespace ivr
