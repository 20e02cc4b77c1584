// test_environment.cpp — the environment every test process runs in, set by the binary itself:
// the planner's built-in cost model (not a calibration stored on the machine), PoCL's kernel cache
// inside the build tree, the image module of this build, under AddressSanitizer the options and
// LeakSanitizer suppressions (the OpenCL ICD loader and the PoCL driver with its LLVM keep
// process-lifetime allocations), and under ThreadSanitizer its options and suppressions.
#include <cstdlib>

namespace {

const bool environment_set = [] {
  ::setenv("IVR_COST_MODEL", "/nonexistent/ivr-tests-use-the-default-cost-model.json", 0);
  // PoCL's kernel cache of this build's tests (and of the CLI and ivr-bench they start), not the
  // user's ~/.cache/pocl: what is there from other builds or other PoCL programs cannot matter.
  // Set before the first OpenCL call, when PoCL reads it.
  ::setenv("POCL_CACHE_DIR", IVR_TEST_POCL_CACHE_DIR, 0);
#ifdef IVR_TEST_IMAGE_MODULE
  // This binary links libivr statically, so the image module is not next to it.
  ::setenv("IVR_IMAGE_MODULE", IVR_TEST_IMAGE_MODULE, 0);
#endif
  return true;
}();

}  // namespace

// use_sigaltstack=0: LLVM (inside PoCL) installs its own alternate signal stack, from malloc, on
// the thread that first registers its signal handlers — when PoCL first writes a file to its
// cache, on whichever thread that is. AddressSanitizer's teardown of that thread then tries to
// munmap LLVM's heap block as if it were its own stack and aborts ("AddressSanitizer failed to
// deallocate … unable to unmap", Runtime.ContextsMadeOnSeveralThreadsAtOnce under load, 16 runs
// of 25). Without its own alternate stack AddressSanitizer leaves the thread's stack alone; what
// is lost is only its report of a stack overflow (a plain SIGSEGV instead).
#define IVR_ASAN_OPTIONS "detect_leaks=1:use_sigaltstack=0"
extern "C" const char* __asan_default_options() {
  return IVR_ASAN_OPTIONS;
}

// use_tls=0: LeakSanitizer's tracer crashed ("Tracer caught signal 11") reading a garbage
// dynamic-TLS entry ("DTLS 37 at 0x3001-0x800004103" with log_threads=1) once a process had
// compiled enough kernels — PoCL dlopens each compiled kernel library. Without scanning TLS,
// heap blocks that only thread-locals point to look leaked: the per-thread data of libraries that
// OpenImageIO pulls in, and the C API's thread-local last-error text (ivr::capi::fail), which
// are suppressed by name in tests/lsan.supp.
// One list of suppressions (tests/lsan.supp) for this binary and, through LSAN_OPTIONS (and
// ASAN_OPTIONS), for the processes it starts (the CLI, ivr-bench), which have no defaults of
// their own.
#define IVR_LSAN_OPTIONS \
  "use_tls=0:print_suppressions=0:suppressions=" IVR_TESTS_DIR "/lsan.supp"
extern "C" const char* __lsan_default_options() {
  return IVR_LSAN_OPTIONS;
}

namespace {
const bool children_suppressed = [] {
  ::setenv("LSAN_OPTIONS", IVR_LSAN_OPTIONS, 0);
  ::setenv("ASAN_OPTIONS", IVR_ASAN_OPTIONS, 0);
  return true;
}();
}  // namespace

// ThreadSanitizer (IVR_TSAN, label tsan): stop at the first report, and the suppressions of
// tests/tsan.supp, each with its reason.
extern "C" const char* __tsan_default_options() {
  return "halt_on_error=1:second_deadlock_stack=1:suppressions=" IVR_TESTS_DIR "/tsan.supp";
}
