// baselines.cpp — case directories for the Python baselines and their subprocesses.
#include "baselines.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

extern char** environ;

namespace ivr::bench {

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

json vec(const glm::dvec3& v) {
  return {v.x, v.y, v.z};
}

}  // namespace

BaselineEnv find_baselines(const std::string& python, const std::vector<std::string>& frameworks) {
  BaselineEnv env;
  env.frameworks = frameworks;
  env.script = std::string(IVR_SOURCE_DIR) + "/bench/baselines/run.py";
  if (!python.empty())
    env.python = python;
  else if (const char* p = std::getenv("IVR_BENCH_PYTHON"); p && *p)
    env.python = p;
  else
    env.python = std::string(IVR_SOURCE_DIR) + "/.venv-bench/bin/python";
  std::error_code ec;
  if (frameworks.empty()) {
    env.note = "no Python baselines asked for";
  } else if (!fs::exists(env.python, ec)) {
    env.note = "no baseline environment at " + env.python +
               " (scripts/bench_setup.sh makes one; --python or $IVR_BENCH_PYTHON name another)";
  } else if (!fs::exists(env.script, ec)) {
    env.note = "the baseline driver " + env.script + " is missing";
  } else {
    env.usable = true;
  }
  return env;
}

std::string write_case(const std::string& dir, const Scene& scene, double step_voxels,
                       const Image& target) {
  if (scene.model != Model::emission_absorption || scene.tf.kind != TfKind::piecewise_linear)
    throw Error(Status::invalid_argument,
                "the baselines march emission_absorption with a piecewise_linear TF only");
  fs::create_directories(dir);
  const Volume& v = scene.volume;
  save_npy(dir + "/volume.npy", {std::size_t(v.nz), std::size_t(v.ny), std::size_t(v.nx)},
           v.data.data());
  save_image_npy(dir + "/target.npy", target);
  const glm::dvec3 h = scene.voxel_size();
  json tf = json::array();
  for (const TfPoint& p : scene.tf.points)
    tf.push_back({p.density, p.color.x, p.color.y, p.color.z, p.extinction});
  json cams = json::array();
  for (const Camera& c : scene.cameras) {
    if (c.projection != Projection::perspective)
      throw Error(Status::invalid_argument, "the baselines use perspective cameras only");
    cams.push_back({{"eye", vec(c.eye)},
                    {"target", vec(c.target)},
                    {"up", vec(c.up)},
                    {"fov_y", c.fov_y},
                    {"width", c.width},
                    {"height", c.height}});
  }
  const json doc = {{"format", "ivr-bench-scene/1"},
                    {"volume", "volume.npy"},
                    {"target", "target.npy"},
                    {"tf", tf},
                    {"background", vec(scene.effective_background())},
                    {"min_transmittance", scene.integrator.min_transmittance},
                    {"step", step_voxels * std::min(h.x, std::min(h.y, h.z))},
                    {"loss", "mse"},
                    {"box_min", vec(scene.box_min)},
                    {"box_max", vec(scene.box_max)},
                    {"cameras", cams}};
  std::ofstream(dir + "/scene.json") << doc.dump(2) << "\n";
  return dir;
}

std::string write_tomo_case(const std::string& dir, const Scene& scene,
                            const std::vector<double>& volume, const std::vector<double>& lines) {
  fs::create_directories(dir);
  const Volume& v = scene.volume;
  const Camera& first = scene.cameras.front();
  const std::size_t views = scene.cameras.size(), h = std::size_t(first.height),
                    w = std::size_t(first.width);
  if (volume.size() != v.voxel_count() || lines.size() != views * h * w)
    throw Error(Status::invalid_argument, "write_tomo_case: the arrays do not fit the scene");
  const std::vector<float> vf(volume.begin(), volume.end()), lf(lines.begin(), lines.end());
  save_npy(dir + "/volume.npy", {std::size_t(v.nz), std::size_t(v.ny), std::size_t(v.nx)},
           vf.data());
  save_npy(dir + "/lines.npy", {views, h, w}, lf.data());
  json cams = json::array();
  for (const Camera& c : scene.cameras) {
    if (c.projection != Projection::orthographic || c.width != first.width ||
        c.height != first.height)
      throw Error(Status::invalid_argument,
                  "the projector baseline takes orthographic cameras of one size only");
    cams.push_back({{"eye", vec(c.eye)},
                    {"target", vec(c.target)},
                    {"up", vec(c.up)},
                    {"projection", "orthographic"},
                    {"ortho_height", c.ortho_height},
                    {"width", c.width},
                    {"height", c.height}});
  }
  const json doc = {{"format", "ivr-bench-tomo/1"},  {"volume", "volume.npy"},
                    {"lines", "lines.npy"},          {"box_min", vec(scene.box_min)},
                    {"box_max", vec(scene.box_max)}, {"cameras", cams}};
  std::ofstream(dir + "/tomo.json") << doc.dump(2) << "\n";
  return dir;
}

bool baseline_does(const std::string& framework, const std::string& task) {
  const bool projector = task == "project" || task == "backproject";
  return framework == "astra" ? projector : !projector;
}

BaselineRun run_baseline(const BaselineEnv& env, const std::string& framework,
                         const std::string& task, const std::string& case_dir, double budget,
                         const std::string& output, const std::string& device) {
  BaselineRun run;
  const std::string out = case_dir + "/" + framework + "_" + task + ".json";
  const std::string log = case_dir + "/" + framework + "_" + task + ".log";
  std::error_code ec;
  fs::remove(out, ec);
  std::vector<std::string> args = {env.python,    env.script,
                                   "--framework", framework,
                                   "--task",      task,
                                   "--case",      case_dir,
                                   "--out",       out,
                                   "--budget",    std::to_string(budget),
                                   "--threads",   std::to_string(env.threads),
                                   "--device",    device};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, env.python.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    run.note = "cannot start " + env.python;
    return run;
  }
  const auto start = std::chrono::steady_clock::now();
  int status = 0;
  for (;;) {
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
        env.timeout) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      run.available = true;
      run.note = framework + " " + task + " ran past " + std::to_string(int(env.timeout)) +
                 " s and was stopped (log: " + log + ")";
      return run;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::ifstream in(out);
  if (!in) {
    run.note = framework + " " + task + " wrote no result (exit " +
               std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ", log: " + log + ")";
    return run;
  }
  try {
    in >> run.result;
  } catch (const json::exception&) {
    run.note = framework + " " + task + ": unreadable result " + out;
    return run;
  }
  run.available = run.result.value("available", false);
  if (!run.available) {
    run.note = run.result.value("note", framework + " is not available");
    return run;
  }
  if (!run.result.value("ok", false)) {
    run.note = framework + " " + task + " failed: " + run.result.value("error", "?") +
               " (log: " + log + ")";
    return run;
  }
  run.ok = true;
  run.loss = run.result.value("loss", NAN);
  if (!output.empty()) {
    const json outs = run.result.value("outputs", json::object());
    if (!outs.contains(output)) {
      run.ok = false;
      run.note = framework + " " + task + " gave no '" + output + "' array";
      return run;
    }
    run.output = load_npy(case_dir + "/" + outs[output].get<std::string>()).data;
  }
  return run;
}

}  // namespace ivr::bench
