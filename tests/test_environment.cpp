// test_environment.cpp — the environment every test process runs in, set by the binary itself:
// the planner's built-in cost model (not a calibration stored on the machine), and under
// AddressSanitizer the options and LeakSanitizer suppressions (the OpenCL ICD loader and the PoCL
// driver with its LLVM keep process-lifetime allocations; nothing of ivr's own is suppressed).
#include <gtest/gtest.h>

#include <cstdlib>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#endif

namespace {

const bool environment_set = [] {
  ::setenv("IVR_COST_MODEL", "/nonexistent/ivr-tests-use-the-default-cost-model.json", 0);
  return true;
}();

#if defined(__SANITIZE_ADDRESS__)
// The leak check runs when the tests are done, while PoCL's worker threads sleep, instead of at
// exit, where LeakSanitizer's stop-the-world tracer now and then crashes on threads the driver is
// tearing down ("Tracer caught signal 11", google/sanitizers#1353). It is the same check (a leak
// ends the process with LeakSanitizer's report and a failing status) and replaces the one at exit.
class LeakCheckBeforeExit : public ::testing::Environment {
 public:
  void TearDown() override { __lsan_do_leak_check(); }
};

const bool leak_check_registered = [] {
  ::testing::AddGlobalTestEnvironment(new LeakCheckBeforeExit);
  return true;
}();
#endif

}  // namespace

extern "C" const char* __asan_default_options() {
  return "detect_leaks=1";
}

extern "C" const char* __lsan_default_suppressions() {
  return "leak:libOpenCL.so\n"
         "leak:libpocl.so\n"
         "leak:libpocl-devices\n"
         "leak:libLLVM\n"
         "leak:libclang\n"
         "leak:libhwloc\n";
}
