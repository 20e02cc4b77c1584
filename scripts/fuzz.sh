#!/usr/bin/env bash
# Builds the loaders' libFuzzer harnesses with clang (build-fuzz/) and runs each for a bounded time.
# Usage: scripts/fuzz.sh [SECONDS_EACH [HARNESS...]]   (default 60 s each, every harness)
# A crash leaves build-fuzz/fuzz-corpus/crash-<harness>-*: fix it, then copy the input into
# tests/fuzz/regressions/<harness>/, where the default suite replays it (fuzz_replay_<harness>).
set -euo pipefail
cd "$(dirname "$0")/.."
"$(pwd)/scripts/install-deps.sh"
seconds=${1:-60}
shift || true
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DIVR_FUZZ=ON \
  -DIVR_BUILD_TESTS=OFF -DIVR_BUILD_BENCH=OFF -DIVR_BUILD_EXAMPLES=OFF -DIVR_FUZZ_SECONDS="$seconds" >/dev/null
cmake --build build-fuzz -j"$(nproc 2>/dev/null || echo 2)"
filter="fuzz_"
[ $# -gt 0 ] && filter="^fuzz_($(IFS='|'; echo "$*"))\$"
ctest --test-dir build-fuzz -L fuzz -R "$filter" --output-on-failure --timeout 0
