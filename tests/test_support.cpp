// test_support.cpp — temp folders, scene builders, the shared device and running the CLI.
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;

namespace ivr::test {

std::string temp_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("ivr_test_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  static const bool cleanup = [] {
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(fs::temp_directory_path() / ("ivr_test_" + std::to_string(::getpid())), ec);
    });
    return true;
  }();
  (void)cleanup;
  return dir.string();
}

std::string file_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

std::string write_file(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

Device& device() {
  static Device d;
  return d;
}

std::vector<std::unique_ptr<Device>> device_contexts(int count) {
  std::vector<std::unique_ptr<Device>> out;
  for (int i = 0; i < count; ++i)
    out.push_back(std::make_unique<Device>(std::to_string(device().info().index)));
  return out;
}

std::vector<Device*> pointers_to(const std::vector<std::unique_ptr<Device>>& devices) {
  std::vector<Device*> out;
  for (const auto& d : devices) out.push_back(d.get());
  return out;
}

Scene constant_scene(float density, int n, int image) {
  Scene s;
  s.volume.nx = s.volume.ny = s.volume.nz = n;
  s.volume.data.assign(std::size_t(n) * n * n, density);
  set_default_box(s);
  s.model = Model::absorption;
  s.tf.kind = TfKind::identity;
  Camera c;
  c.projection = Projection::orthographic;
  c.eye = {0, 0, 2};
  c.target = {0, 0, 0};
  c.ortho_height = 1.0;
  c.width = c.height = image;
  s.cameras = {c};
  s.integrator.min_transmittance = 0;
  return s;
}

Camera ortho(glm::dvec3 eye, glm::dvec3 up, int w, int h, double height) {
  Camera c;
  c.projection = Projection::orthographic;
  c.eye = eye;
  c.target = {0, 0, 0};
  c.up = up;
  c.width = w;
  c.height = h;
  c.ortho_height = height;
  return c;
}

const char* name(Precision p) {
  return p == Precision::f64 ? "f64" : "f32";
}

Image render_at(const Scene& scene, Precision precision, double step, RenderStats* stats) {
  RenderOptions o;
  o.precision = precision;
  o.step = step;
  return render(device(), scene, o, stats);
}

Image render_checked(const Scene& s, Precision p, double step) {
  const Image img = render_at(s, p, step);
  EXPECT_EQ(img.views, int(s.cameras.size()));
  EXPECT_EQ(img.height, s.cameras[0].height);
  EXPECT_EQ(img.width, s.cameras[0].width);
  EXPECT_EQ(img.channels, s.channels());
  EXPECT_EQ(img.pixels.size(), std::size_t(img.views) * img.height * img.width * img.channels);
  const auto bad = std::count_if(img.pixels.begin(), img.pixels.end(),
                                 [](float v) { return !std::isfinite(v); });
  EXPECT_EQ(bad, 0) << "NaN/Inf pixels (" << name(p) << ")";
  return img;
}

std::string where(int v, int y, int x) {
  std::ostringstream s;
  s << "view " << v << " pixel (x=" << x << ", y=" << y << ")";
  return s.str();
}

std::string where(Precision p, int v, int y, int x, double extra) {
  std::ostringstream s;
  s << name(p) << " " << where(v, y, x);
  if (!std::isnan(extra)) s << " [" << extra << "]";
  return s.str();
}

CliResult run_cli(const std::string& args, const std::string& env) {
  return run_program(IVR_CLI_PATH, args, env);
}

int signalled_cli(const std::vector<std::string>& args, const std::string& err,
                  const std::string& wait_for, int signal, const std::string& env) {
  fs::remove(err);
  std::vector<char*> argv = {const_cast<char*>("ivr")};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // The child's environment, made before the fork (nothing but async-signal-safe calls after it).
  std::vector<std::string> environment;
  for (char** e = environ; *e; ++e) environment.emplace_back(*e);
  if (!env.empty()) environment.push_back(env);
  std::vector<char*> envp;
  for (std::string& e : environment) envp.push_back(e.data());
  envp.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(::open("/dev/null", O_WRONLY), 1);
    ::dup2(::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644), 2);
    ::execve(IVR_CLI_PATH, argv.data(), envp.data());
    std::_Exit(127);
  }
  const auto start = std::chrono::steady_clock::now();
  while (file_text(err).find(wait_for) == std::string::npos) {
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(60)) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
      ADD_FAILURE() << "no '" << wait_for << "' within 60 s: " << file_text(err);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ::kill(pid, signal);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

CliResult run_program(const std::string& program, const std::string& args, const std::string& env) {
  const std::string dir = temp_dir("cli_capture");
  const std::string out = dir + "/stdout", err = dir + "/stderr";
  const std::string cmd = env + " " + program + " " + args + " >" + out + " 2>" + err;
  const int raw = std::system(cmd.c_str());
  CliResult r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::ifstream o(out), e(err);
  std::stringstream so, se;
  so << o.rdbuf();
  se << e.rdbuf();
  r.out = so.str();
  r.err = se.str();
  return r;
}

}  // namespace ivr::test
