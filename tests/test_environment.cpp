// test_environment.cpp — the environment every test process runs in, set by the binary itself:
// the planner's built-in cost model (not a calibration stored on the machine), and under
// AddressSanitizer the options and LeakSanitizer suppressions (the OpenCL ICD loader and the PoCL
// driver with its LLVM keep process-lifetime allocations; nothing of ivr's own is suppressed).
#include <cstdlib>

namespace {

const bool environment_set = [] {
  ::setenv("IVR_COST_MODEL", "/nonexistent/ivr-tests-use-the-default-cost-model.json", 0);
  return true;
}();

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
