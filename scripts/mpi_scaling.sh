#!/usr/bin/env bash
# mpi_scaling.sh — strong scaling of `mpirun -np N ivr render|gradient|reconstruct` on one machine's
# CPU cores.
#
#   scripts/mpi_scaling.sh [-o DIR] [--ranks "1 2 4"] [--size 256] [--views 16] [--image 384]
#                          [--reps 3] [--ivr build/ivr] [--mpirun mpirun] [--splits "views segments"]
#                          [--ops "render gradient reconstruct"] [--iterations 8]
#
# The same problem (a SIZE³ Shepp–Logan phantom read from .npy, VIEWS orbit views of IMAGE², emission–absorption, midpoint,
# step 0.5, early termination off so that every split marches the same samples) is rendered and
# differentiated (`--wrt density`, adjoint) and reconstructed (`ivr reconstruct`, ITERATIONS steps
# of Adam over every view at one level: a loop that pays the start-up once) by 1, 2, 4 … ranks,
# data-parallel over views and
# domain-parallel over independent segments (docs/scaling.md). Each rank's PoCL device gets
# cores / N threads (POCL_CPU_MAX_CU_NUM, and POCL_MAX_PTHREAD_COUNT for older PoCL) and ranks are
# not bound to cores (Open MPI binds each rank to one core by default), so N ranks share the same
# cores one rank had. Times: the whole mpirun command's wall time (what a user waits for: launch,
# scene, upload, march, gather) and rank 0's kernel seconds from --json (reconstruct: its loop's
# seconds, start-up and writing excluded), medians of REPS runs
# after one warm-up (kernel caches). Writes DIR/runs.csv (every run) and DIR/scaling.md (medians,
# speed-up and efficiency against one rank). Needs numpy only for the result check (rank counts'
# images against one rank's), skipped with a note where python3 lacks it.
set -euo pipefail
out=mpi-scaling ranks="1 2 4" size=256 views=16 image=384 reps=3 ivr=build/ivr
mpirun=mpirun splits="views segments" python=${PYTHON:-python3}
ops="render gradient reconstruct" iterations=8
while [ $# -gt 0 ]; do
  case "$1" in
    -o) out=$2 ;; --ranks) ranks=$2 ;; --size) size=$2 ;; --views) views=$2 ;;
    --image) image=$2 ;; --reps) reps=$2 ;; --ivr) ivr=$2 ;; --mpirun) mpirun=$2 ;;
    --splits) splits=$2 ;; --ops) ops=$2 ;; --iterations) iterations=$2 ;;
    *) echo "mpi_scaling.sh: unknown option '$1'" >&2; exit 2 ;;
  esac
  shift 2
done
ivr=$(cd "$(dirname "$ivr")" && pwd)/$(basename "$ivr")
[ -x "$ivr" ] || { echo "mpi_scaling.sh: no ivr at '$ivr'" >&2; exit 2; }
command -v "$mpirun" >/dev/null || { echo "mpi_scaling.sh: no '$mpirun'" >&2; exit 2; }
cores=$(nproc)
mkdir -p "$out"
out=$(cd "$out" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
export IVR_DEVICE=${IVR_DEVICE:-cpu} OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# One machine: shared memory between ranks, no network probing; CMA (process_vm_readv) is refused
# in many containers, so the shared-memory transport copies through its own buffers.
mpi_flags=(--bind-to none --oversubscribe --mca btl self,vader --mca pml ob1
  --mca btl_vader_single_copy_mechanism none)

scene() {  # scene(extinction) → JSON on stdout
  cat <<JSON
{"volume": {"file": "volume.npy"}, "model": "emission_absorption",
 "tf": {"type": "piecewise_linear", "points": [
   {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0},
   {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": $1}]},
 "cameras": [{"orbit": {"views": $views, "axis": [0.2, 1, 0.1], "start": 10, "radius": 2.2,
              "fov_y": 40, "width": $image, "height": $image}}],
 "integrator": {"scheme": "midpoint", "step": 0.5, "min_transmittance": 0}}
JSON
}
"$ivr" phantom shepp-logan --size "$size" -o volume.npy >/dev/null
scene 20 > scene.json
scene 14 > target_scene.json
"$ivr" render target_scene.json -o target.npy >/dev/null

# run(ranks, split, op) → "wall_seconds kernel_seconds" of one mpirun; the images/gradients kept.
run() {
  local n=$1 split=$2 op=$3 threads=$(( cores / $1 > 0 ? cores / $1 : 1 ))
  local args=(render scene.json -o "r_${split}_$n.npy")
  [ "$op" = gradient ] && args=(gradient scene.json --target target.npy --wrt density
    --mode adjoint -o "g_${split}_$n")
  [ "$op" = reconstruct ] && args=(reconstruct scene.json --targets target.npy -o "c_${split}_$n"
    --iterations "$iterations" --levels 1 --checkpoint-every 0)
  [ "$split" = views ] || args+=(--split "$split")
  local t0 t1 json
  t0=$(date +%s.%N)
  json=$(POCL_CPU_MAX_CU_NUM=$threads POCL_MAX_PTHREAD_COUNT=$threads \
    "$mpirun" -np "$n" "${mpi_flags[@]}" "$ivr" "${args[@]}" --json | grep -m1 '^{')
  t1=$(date +%s.%N)
  local k
  k=$(echo "$json" | "$python" -c 'import json,sys; j=json.load(sys.stdin); print(j.get("kernel_seconds", j.get("seconds")))')
  echo "$t0 $t1 $k" | awk '{printf "%.4f %.6f\n", $2 - $1, $3}'
}

echo "split,op,ranks,threads_per_rank,run,wall_s,kernel_s" > "$out/runs.csv"
for split in $splits; do
  for n in $ranks; do
    [ "$split" != views ] && [ "$n" = 1 ] && continue  # one rank: no split (the views row)
    for op in $ops; do
      run "$n" "$split" "$op" >/dev/null  # warm-up: PoCL's and ivr's kernel caches
      for r in $(seq 1 "$reps"); do
        read -r wall kern < <(run "$n" "$split" "$op")
        echo "$split,$op,$n,$(( cores / n )),$r,$wall,$kern" >> "$out/runs.csv"
        echo "mpi_scaling: $split $op -np $n: wall ${wall} s, rank 0 kernels ${kern} s" >&2
      done
    done
  done
done

# Every rank count's render and density gradient against one rank's (float32: to 1e-5 of the largest).
"$python" - "$out" <<'PY'
import csv, glob, statistics, sys
out = sys.argv[1]
rows = list(csv.DictReader(open(f"{out}/runs.csv")))
check = []
try:
    import numpy as np
    for f in (sorted(glob.glob("r_*.npy")) + sorted(glob.glob("g_*_density.npy"))
              + sorted(glob.glob("c_*_density.npy"))):
        ref = {"r": "r_views_1.npy", "g": "g_views_1_density.npy", "c": "c_views_1_density.npy"}[f[0]]
        a, b = np.load(f).astype(np.float64), np.load(ref).astype(np.float64)
        check.append(f"{f}: max |difference| {np.abs(a - b).max() / max(np.abs(b).max(), 1e-300):.2e} of the largest")
except ImportError:
    check.append("(numpy missing: results not compared)")
groups = {}
for r in rows:
    groups.setdefault((r["split"], r["op"], int(r["ranks"])), []).append(r)
ops = ("render", "gradient", "reconstruct")
base = {op: statistics.median(float(r["wall_s"]) for r in groups[("views", op, 1)])
        for op in ops if ("views", op, 1) in groups}
kbase = {op: statistics.median(float(r["kernel_s"]) for r in groups[("views", op, 1)])
         for op in ops if ("views", op, 1) in groups}
lines = ["| split | operation | ranks × threads | wall (median) | speed-up | efficiency | rank 0 kernels (reconstruct: loop) | its speed-up |",
         "|---|---|---|---|---|---|---|---|"]
for (split, op, n), rs in sorted(groups.items(), key=lambda g: (g[0][1], g[0][0] != "views", g[0][0], g[0][2])):
    w = statistics.median(float(r["wall_s"]) for r in rs)
    k = statistics.median(float(r["kernel_s"]) for r in rs)
    s = base[op] / w if op in base else float("nan")
    ks = kbase[op] / k if op in kbase and k > 0 else float("nan")
    lines.append(f"| {split} | {op} | {n} × {rs[0]['threads_per_rank']} | {w:.3f} s | {s:.2f}× | "
                 f"{s / n:.0%} | {k:.3f} s | {ks:.2f}× |")
text = "\n".join(lines + [""] + ["- " + c for c in check]) + "\n"
open(f"{out}/scaling.md", "w").write(text)
print(text)
PY
