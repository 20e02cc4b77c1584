// test_support.hpp — shared helpers for the test suite: temp folders, scene builders, the CLI.
#pragma once
#include <string>

#include "ivr/ivr.hpp"

namespace ivr::test {

// A fresh empty folder under the system temp dir, removed at exit of the test process.
std::string temp_dir(const std::string& name);

// Writes text to a file (creating parent folders); returns the path.
std::string write_file(const std::string& path, const std::string& text);

// One shared device for the whole test process ($IVR_DEVICE or the default).
Device& device();

// A scene of a constant-density volume filling the default unit box, one orthographic camera
// looking down -z through the whole box, identity TF. Tests tweak fields from here.
Scene constant_scene(float density, int n = 4, int image = 8);

// Runs the ivr CLI with the arguments (a shell-quoted string); captures stdout and stderr.
struct CliResult {
  int status = 0;
  std::string out, err;
};
CliResult run_cli(const std::string& args, const std::string& env = "");

}  // namespace ivr::test
