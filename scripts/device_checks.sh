#!/usr/bin/env bash
# device_checks.sh — the lent GPU machine's batch of checks as one prepared command: the suite on
# the GPU, the out-of-core and gradient benchmarks there, and MPI strong scaling on its CPU cores,
# each stage under its own time limit, every result written under $OUT (what the `device` tool
# brings back).
#
#   scripts/device_checks.sh [STAGE[:SECONDS] ...]     (default: suite out_of_core gradient mpi)
#
# Stages (seconds: the stage's limit; default in brackets):
#   suite[240]        IVR_DEVICE=gpu ctest -L default: the failures' names and the summary
#   out_of_core[150]  ivr-bench --device gpu --suite out_of_core (64³ and 128³ → 256²: bricked
#                     against in core, end to end and kernels; docs/scaling.md's GPU table)
#   gradient[60]      ivr-bench --device gpu --suite render,gradient --quick
#   mpi[120]          scripts/mpi_scaling.sh on the machine's CPU cores (1, 2, 4 ranks; views and
#                     segments; render, gradient and the reconstruction's loop)
# A stage that runs out of time is stopped and named in $OUT/stages.txt; the next one runs. The
# total of the defaults (570 s) fits one call of at most 600 s.
#
# Here (this machine: build, then bundle):
#   ../shared/gpu/bundle.sh && scripts/gpu_carry_extras.sh
# There (one `run` call, carry [".gpu-carry"]):
#   C=$PWD/.gpu-carry && source .gpu-carry/setup.sh && source "$C/extras.sh" &&
#     scripts/device_checks.sh
# Without a GPU (to try the script itself): IVR_CHECK_DEVICE=cpu OUT=/tmp/out scripts/device_checks.sh
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-device-checks}
mkdir -p "$out"
out=$(cd "$out" && pwd)
device=${IVR_CHECK_DEVICE:-gpu}
build=${IVR_BUILD_DIR:-build}
stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(suite out_of_core gradient mpi)
: > "$out/stages.txt"

default_limit() {
  case "$1" in suite) echo 240 ;; out_of_core) echo 150 ;; gradient) echo 60 ;; mpi) echo 120 ;; *) echo 0 ;; esac
}

run_stage() {  # run_stage NAME LIMIT
  local name=$1 limit=$2 t0 rc
  t0=$(date +%s)
  case "$name" in
    suite)
      IVR_DEVICE=$device timeout -k 10 "$limit" ctest --test-dir "$build" -L default -j12 --timeout 150 \
        > "$out/suite.log" 2>&1
      rc=$?
      grep -E "tests passed|tests failed|\*\*\*Failed|\*\*\*Timeout|Exception" "$out/suite.log" \
        > "$out/suite_summary.txt"
      ;;
    out_of_core)
      timeout -k 10 "$limit" "$build/bench/ivr-bench" --device "$device" --suite out_of_core \
        --cases v64_i256,v128_i256 --no-baselines --budget 0.3 -o "$out/out_of_core" \
        > "$out/out_of_core.log" 2>&1
      rc=$?
      ;;
    gradient)
      timeout -k 10 "$limit" "$build/bench/ivr-bench" --device "$device" --suite render,gradient --quick \
        --no-baselines --budget 0.3 -o "$out/render_gradient" > "$out/render_gradient.log" 2>&1
      rc=$?
      ;;
    mpi)
      IVR_DEVICE=cpu timeout -k 10 "$limit" scripts/mpi_scaling.sh -o "$out/mpi" --ranks "1 2 4" \
        --size 128 --views 24 --image 192 --reps 2 --iterations 8 --ivr "$build/ivr" \
        --mpirun "${MPIRUN:-mpirun}" > "$out/mpi.log" 2>&1
      rc=$?
      ;;
    *)
      echo "device_checks.sh: unknown stage '$name' (suite, out_of_core, gradient, mpi)" >&2
      return 2
      ;;
  esac
  local took=$(( $(date +%s) - t0 )) what=done
  { [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ]; } && what="stopped at its limit"
  [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && [ "$rc" -ne 137 ] && what="exit status $rc"
  echo "$name: $what, ${took} s of ${limit} s" | tee -a "$out/stages.txt"
}

status=0
for s in "${stages[@]}"; do
  name=${s%%:*} limit=${s#*:}
  [ "$limit" = "$s" ] && limit=$(default_limit "$name")
  if ! [[ "$limit" =~ ^[0-9]+$ ]] || [ "$limit" -le 0 ]; then
    echo "device_checks.sh: stage '$s': no such stage or limit" >&2
    exit 2
  fi
  run_stage "$name" "$limit" || status=1
done
exit $status
