#!/usr/bin/env bash
# Builds ivr and runs the whole test suite (CTest label "default"), from dependencies onward.
# Usage: scripts/test.sh [--sanitize | --tsan]
#   --sanitize: AddressSanitizer + UBSan build in build-asan/, the default label (with build/'s
#               kernel caches; the kernel-against-kernel tests are its label kernel_equivalence:
#               docs/reliability.md)
#   --tsan:     ThreadSanitizer build in build-tsan/, the label tsan (every test on threads)
set -euo pipefail
cd "$(dirname "$0")/.."

"$(pwd)/scripts/install-deps.sh"

build=build
label=default
flags=(-DCMAKE_BUILD_TYPE=Release -DIVR_BUILD_TESTS=ON)  # ON: scripts/demo.sh may have turned it off in build/
if [ "${1:-}" = "--sanitize" ]; then
  build=build-asan
  # The kernels build/'s run compiled (PoCL's cache) serve this run too: CI runs it second.
  # -O1 -g1 (line tables, enough for the sanitizers' stack traces), not RelWithDebInfo's -O2 -g:
  # half the library's build; the tests' own code at -O0 (tests/CMakeLists.txt): 6 s a file, not 13.
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DIVR_SANITIZE=ON -DIVR_BUILD_BENCH=OFF -DIVR_BUILD_TESTS=ON
    "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
    "-DIVR_TEST_CACHE_DIR=$(pwd)/build")
elif [ "${1:-}" = "--tsan" ]; then
  build=build-tsan
  label=tsan
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DIVR_TSAN=ON -DIVR_BUILD_BENCH=OFF -DIVR_BUILD_EXAMPLES=OFF
    -DIVR_BUILD_TESTS=ON)
elif [ -n "${1:-}" ]; then
  echo "test.sh: unknown option '$1' (use --sanitize or --tsan)" >&2
  exit 2
fi
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B "$build" "${flags[@]}"
cmake --build "$build" -j"$jobs"
log="$build/ctest-$label.log"
# The mpirun tests (label mpi) after the default suite, in the plain build (built with MPI).
mpi_tests() {
  if [ "$build" = build ] && ctest --test-dir "$build" -N -L mpi | grep -q "Total Tests: [1-9]"; then
    ctest --test-dir "$build" -L mpi --output-on-failure --timeout 600
  fi
}
if ctest --test-dir "$build" -L "$label" -j"$jobs" --output-on-failure --timeout 600 --output-log "$log"; then
  mpi_tests
  exit 0
fi
# LeakSanitizer's stop-the-world tracer itself crashed in processes whose tests all passed
# ("Tracer caught signal", google/sanitizers#1353) — reading a garbage dynamic-TLS entry, now
# avoided by use_tls=0 (tests/test_environment.cpp). Should it still happen, the failed tests are
# run once more; a test that fails for any other reason fails again and the run stays red.
if [ "$build" = build-asan ] && grep -q "Tracer caught signal" "$log"; then
  echo "test.sh: LeakSanitizer's tracer crashed; running the failed tests once more" >&2
  ctest --test-dir "$build" --rerun-failed -j"$jobs" --output-on-failure --timeout 600
else
  exit 1
fi
