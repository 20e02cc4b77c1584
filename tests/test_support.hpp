// test_support.hpp — shared helpers for the test suite: temp folders, scene builders, the CLI.
#pragma once
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "reference/random.hpp"
#include "ivr/core.hpp"

namespace ivr::test {

// A fresh empty folder under the system temp dir, removed at exit of the test process.
std::string temp_dir(const std::string& name);

// Writes text to a file (creating parent folders); returns the path.
std::string write_file(const std::string& path, const std::string& text);

// A file's whole content ("" when it cannot be read).
std::string file_text(const std::string& path);

// Whether `text` contains `part` (for messages and outputs).
inline bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// n values uniform in [0, 1) from a fixed seed, and ⟨a, b⟩ accumulated in long double (adjoint
// identities checked to ~1e-12): the benchmarks' own, so that both check with the same vectors.
using reference::dot;
using reference::uniform;

// One shared device for the whole test process ($IVR_DEVICE or the default).
Device& device();

// `count` contexts of their own on the test device: the "several devices" of one process (or the
// workers on threads) that the multi-device and domain tests run on; and their pointers.
std::vector<std::unique_ptr<Device>> device_contexts(int count);
std::vector<Device*> pointers_to(const std::vector<std::unique_ptr<Device>>& devices);

// Sets an environment variable for the scope of a test, restoring the old value after.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old, had_ = true;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() { had_ ? ::setenv(name_, old_.c_str(), 1) : ::unsetenv(name_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::string old_;
  bool had_ = false;
};

// A scene of a constant-density volume filling the default unit box, one orthographic camera
// looking down -z through the whole box, identity TF. Tests tweak fields from here.
Scene constant_scene(float density, int n = 4, int image = 8);

// An orthographic w x h camera at eye looking at the origin, `height` world units tall.
Camera ortho(glm::dvec3 eye, glm::dvec3 up, int w, int h, double height);

// "f32" or "f64", for failure messages.
const char* name(Precision p);

// Renders on the shared device at the given precision and step (voxels; 0: the scene's own).
Image render_at(const Scene& scene, Precision precision, double step, RenderStats* stats = nullptr);

// render_at, then checks the image shape and that no pixel is NaN/Inf (non-fatal failures).
Image render_checked(const Scene& s, Precision p, double step = 0);

// "view v pixel (x=.., y=..)", optionally prefixed by the precision and followed by " [extra]".
std::string where(int v, int y, int x);
std::string where(Precision p, int v, int y, int x, double extra = NAN);

// Runs the ivr CLI with the arguments (a shell-quoted string); captures stdout and stderr.
struct CliResult {
  int status = 0;
  std::string out, err;
};
CliResult run_cli(const std::string& args, const std::string& env = "");
// The same for another program of the build (ivr-bench).
// `ivr args…` started by fork/exec (not through a shell's `&`, whose background jobs ignore
// SIGINT), stdout to /dev/null and stderr to the file `err`; once `err` holds `wait_for`, sent
// `signal`. Returns the raw wait status (-1 when `wait_for` did not come within 60 s, a failure).
int signalled_cli(const std::vector<std::string>& args, const std::string& err,
                  const std::string& wait_for, int signal, const std::string& env = "");

CliResult run_program(const std::string& program, const std::string& args,
                      const std::string& env = "");

}  // namespace ivr::test
