#!/usr/bin/env bash
# Runs the default suite N times at -jJOBS, each from empty caches, to show that it does not flake
# (docs/reliability.md). Usage: scripts/repeat-suite.sh [RUNS [JOBS [BUILD]]]   (default 5 2 build)
# Before each run it empties every cache a run could reuse: PoCL's (~/.cache/pocl and the suite's
# BUILD/pocl-cache) and ivr's kernel cache (~/.cache/ivr and BUILD/kernel-cache). Each run's log is
# BUILD/repeat-suite-<k>.log; the last line says how many runs were green.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
jobs=${2:-2}
build=${3:-build}
[ -f "$build/CTestTestfile.cmake" ] || { echo "repeat-suite.sh: build '$build' first (scripts/test.sh)" >&2; exit 2; }
cache_home=${XDG_CACHE_HOME:-$HOME/.cache}
green=0
for k in $(seq 1 "$runs"); do
  rm -rf "$cache_home/pocl" "$cache_home/ivr" "$build/pocl-cache" "$build/kernel-cache"
  log="$build/repeat-suite-$k.log"
  start=$(date +%s)
  if ctest --test-dir "$build" -L default -j"$jobs" --timeout 600 --output-on-failure >"$log" 2>&1; then
    green=$((green + 1))
    verdict=green
  else
    verdict="RED: $(grep -c 'Failed\|Exception\|Timeout' "$log" || true) failure line(s), see $log"
  fi
  echo "run $k/$runs at -j$jobs: $(grep -o '[0-9]*% tests passed.*' "$log" | head -1) in $(( $(date +%s) - start )) s: $verdict"
done
echo "repeat-suite.sh: $green of $runs runs green at -j$jobs from empty caches"
[ "$green" -eq "$runs" ]
