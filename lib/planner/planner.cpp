// planner.cpp — the forward/adjoint choice: cost models per device (calibration JSON or
// defaults) and the plan for one gradient request.
#include "ivr/planner.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <limits>
#include <nlohmann/json.hpp>

#include "ivr/error.hpp"

namespace ivr {

namespace {

constexpr std::size_t kMaxLanes = 32;  // lib/jacobian/jacobian.cpp

// A file name from the device's identity: letters, digits and '-' kept, the rest as '_'.
std::string file_key(const DeviceInfo& d) {
  std::string key = d.platform + "-" + d.name + "-" + d.driver;
  for (char& c : key)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-') c = '_';
  return key;
}

double number(const nlohmann::json& j, const char* field, const std::string& path) {
  if (!j.contains(field) || !j[field].is_number())
    throw Error(Status::io, "cost model '" + path + "': field '" + field +
                                "' is missing or not a "
                                "number");
  const double v = j[field].get<double>();
  if (!(v > 0) || !std::isfinite(v))
    throw Error(Status::io, "cost model '" + path + "': field '" + field +
                                "' must be a positive number, got " + std::to_string(v));
  return v;
}

}  // namespace

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::automatic:
      return "auto";
    case Mode::forward:
      return "forward";
    case Mode::adjoint:
      return "adjoint";
  }
  return "?";
}

std::string cost_model_path(const DeviceInfo& device) {
  if (const char* env = std::getenv("IVR_COST_MODEL"); env && *env) return env;
  std::string base;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
    base = xdg;
  else if (const char* home = std::getenv("HOME"); home && *home)
    base = std::string(home) + "/.cache";
  else
    base = ".";
  return base + "/ivr/cost/" + file_key(device) + ".json";
}

CostModel read_cost_model(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(Status::io, "cannot read cost model '" + path + "'");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw Error(Status::io, "cost model '" + path + "' is not valid JSON: " + e.what());
  }
  CostModel m;
  m.forward_base = number(j, "forward_base", path);
  m.forward_per_lane = number(j, "forward_per_lane", path);
  // Optional (files written before them): the same as the other forward lanes.
  m.forward_ray_base =
      j.contains("forward_ray_base") ? number(j, "forward_ray_base", path) : m.forward_base;
  m.forward_ray_per_lane = j.contains("forward_ray_per_lane")
                               ? number(j, "forward_ray_per_lane", path)
                               : m.forward_per_lane;
  m.adjoint = number(j, "adjoint", path);
  m.seconds_per_sample = number(j, "seconds_per_sample", path);
  m.source = path;
  return m;
}

// Float32 lanes per compute unit of a GPU (CUDA cores per SM on NVIDIA, by compute capability:
// 64 on sm_60, sm_70–sm_80, 128 on the others since sm_50; AMD 64 per CU; Intel 8 per EU).
namespace {
double gpu_lanes_per_unit(const DeviceInfo& d) {
  const int cc = d.nv_compute_capability;
  if (cc > 0) return (cc == 60 || (cc >= 70 && cc <= 80)) ? 64 : 128;
  if (d.vendor.find("Intel") != std::string::npos) return 8;
  return 64;
}
}  // namespace

CostModel default_cost_model(const DeviceInfo& device) {
  CostModel m;
  if (device.type == "cpu") {
    // ivr calibrate, 2-core Xeon (Sapphire Rapids; PoCL 3.1 targets it as skylake-avx512),
    // 2026-11-27, with packets of 4x4 rays, the adjoint's private sums and the render's vector
    // TF lookup (64³ → 128² and 128³ → 256², against a target 10 % off): base 1.25–1.37, per lane
    // 0.118–0.125, adjoint 4.85–5.52 renders, 3.1–3.2e-9 s per sample.
    m.forward_base = 1.3;
    m.forward_per_lane = 0.12;
    // Camera and voxel lanes: one ray per work-item (the same calibrations: 5.77–7.65 +
    // 1.04–1.17 · L renders; the render they are counted in got faster, they did not).
    m.forward_ray_base = 6.7;
    m.forward_ray_per_lane = 1.1;
    m.adjoint = 5.2;
    // Per compute unit (PoCL: one a hardware thread) 6.4e-9 s, so a CPU of more threads is
    // estimated faster (the H200 machine's 16-thread host: 4.0e-10 against 6.8e-10 measured).
    m.seconds_per_sample = 6.4e-9 / std::max(device.compute_units, 1);
  } else if (device.compute_units > 0 && device.max_clock_mhz > 0) {
    // Without a calibration, an estimate from the device's size: ~950 cycles of one float32 lane
    // per sample, over its lanes (compute units × lanes per unit) at its clock. 950: the render
    // kernel's 2.85e-11 s per sample on an NVIDIA H200 (132 SMs of 128 lanes at 1980 MHz; ivr-bench
    // v128_i256_s0.500 ivr-resident, bench/results/ivr_bench_h200_render_gradient.json). What it
    // is for: the share of views each of several devices takes (share_weights) — a GPU beside the
    // CPU an order of magnitude more than the CPU, not an equal share.
    m.seconds_per_sample = 950.0 / (double(device.compute_units) * gpu_lanes_per_unit(device) *
                                     double(device.max_clock_mhz) * 1e6);
  }
  return m;
}

double samples_per_second(const DeviceInfo& device) {
  return 1.0 / load_cost_model(device).seconds_per_sample;
}

CostModel load_cost_model(const DeviceInfo& device) {
  const std::string path = cost_model_path(device);
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return default_cost_model(device);
  return read_cost_model(path);
}

void save_cost_model(const std::string& path, const CostModel& m, const DeviceInfo& device) {
  const nlohmann::json j = {{"device", device.name},
                            {"platform", device.platform},
                            {"driver", device.driver},
                            {"forward_base", m.forward_base},
                            {"forward_per_lane", m.forward_per_lane},
                            {"forward_ray_base", m.forward_ray_base},
                            {"forward_ray_per_lane", m.forward_ray_per_lane},
                            {"adjoint", m.adjoint},
                            {"seconds_per_sample", m.seconds_per_sample}};
  std::error_code ec;
  const std::filesystem::path p(path);
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path(), ec);
  const std::string staged = path + ".tmp";
  {
    std::ofstream out(staged);
    out << j.dump(2) << "\n";
    if (!out) throw Error(Status::io, "cannot write cost model '" + path + "'");
  }
  std::filesystem::rename(staged, path, ec);
  if (ec) throw Error(Status::io, "cannot write cost model '" + path + "': " + ec.message());
}

double forward_cost(const CostModel& model, std::size_t parameters, std::size_t* passes,
                    std::size_t* lanes, bool per_ray) {
  const double base = per_ray ? model.forward_ray_base : model.forward_base;
  const double per_lane = per_ray ? model.forward_ray_per_lane : model.forward_per_lane;
  std::size_t n = 0, widest = 0;
  double cost = 0;
  for (std::size_t left = std::max<std::size_t>(parameters, 1); left > 0;) {
    const std::size_t count = std::min(left, kMaxLanes);
    std::size_t l = 1;
    while (l < count) l *= 2;
    cost += base + per_lane * double(l);
    widest = std::max(widest, l);
    left -= count;
    ++n;
  }
  if (passes) *passes = n;
  if (lanes) *lanes = widest;
  return cost;
}

Plan plan_gradient(const CostModel& model, const Scene& scene, std::size_t forward_parameters,
                   bool forward_possible, bool adjoint_possible, Mode requested, double step,
                   bool per_ray) {
  if (!forward_possible && !adjoint_possible)
    throw Error(Status::invalid_argument, "no mode computes every group asked for");
  // Samples of one render, roughly: every pixel marches the box's diagonal at the step.
  const glm::dvec3 h = scene.voxel_size();
  const double world_step = (step > 0 ? step : scene.integrator.step) * std::min({h.x, h.y, h.z});
  const ImageExtent extent = image_extent(scene);  // cameras' pixels, or a ray list's rays
  const double pixels = double(extent.views) * double(extent.width) * double(extent.height);
  const double samples = pixels * glm::length(scene.box_max - scene.box_min) / world_step;
  const double render = samples * model.seconds_per_sample;

  Plan p;
  p.model = model.source;
  const double inf = std::numeric_limits<double>::infinity();
  p.forward_seconds = forward_possible ? render * forward_cost(model, forward_parameters, &p.passes,
                                                               &p.lanes, per_ray)
                                       : inf;
  p.adjoint_seconds = adjoint_possible ? render * model.adjoint : inf;
  if (requested == Mode::forward && !forward_possible)
    throw Error(Status::invalid_argument, "--mode forward cannot compute every group asked for");
  if (requested == Mode::adjoint && !adjoint_possible)
    throw Error(Status::invalid_argument, "--mode adjoint cannot compute every group asked for");
  p.mode = requested != Mode::automatic
               ? requested
               : (p.forward_seconds <= p.adjoint_seconds ? Mode::forward : Mode::adjoint);
  return p;
}

}  // namespace ivr
