#!/usr/bin/env bash
# mpi_cli_test.sh — `mpirun -np 2` and `-np 4` of `ivr render`, `gradient`, `project`,
# `backproject` and `tomo` (data-parallel over views, docs/scaling.md) give one process's results:
# the render bit for bit, the float64 gradients (density, TF, cameras), the lines and the
# back-projection within 1e-12 of the largest entry, CGLS's iterate within 1e-12; over slabs
# (--split slabs: each rank one slab, the rays' states exchanged) the render and the density and
# TF gradients within 1e-12 and the camera's (forward lanes over slabs) within 1e-10, CGLS over slabs (each rank its slab of the iterate) within 1e-10, SIRT and LSQR (x ≥ 0) over views and slabs within 1e-10, LSQR with TV over slabs within 1e-10; `ivr reconstruct` (views of each batch shared out) follows one
# process's losses within 1e-10 and ends at its densities bit for bit (fixed-point gradients: the
# shares' integer sums added exactly), over slabs (each rank its planes, both priors across them,
# two levels; equal slabs and slabs by speed) its losses and priors within 1e-12 and its
# densities bit for bit, as `ivr gradient --deterministic` gives one process's
# density gradient bit for bit (float32), over views and over slabs alike, and with ranks in core
# and out of core side by side; over independent segments (--split segments, early
# termination off) the render, the density and TF gradients and the reconstruction's losses within
# 1e-12, in one exchange; the ranks' shares of the views and of the slabs' planes by --shares and by
# each rank's speed alike; an error in the
# ranks is one non-zero status with nothing written. CTest label `mpi`.
# Usage: mpi_cli_test.sh IVR MPIEXEC PYTHON
set -euo pipefail
ivr=$1 mpiexec=$2 python=$3
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cd "$dir"
cat > scene.json <<'JSON'
{"volume": {"synthetic": "sphere", "dims": [16, 16, 16]}, "model": "emission_absorption",
 "tf": {"type": "piecewise_linear", "points": [
   {"density": 0.1, "color": [0.2, 0.3, 0.9], "extinction": 0.5},
   {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
 "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 12, "height": 10},
             {"eye": [-1.4, 0.3, -1.0], "width": 12, "height": 10},
             {"eye": [0.2, -1.6, 1.0], "width": 12, "height": 10},
             {"eye": [1.6, 0.1, -0.6], "width": 12, "height": 10},
             {"eye": [-0.3, 1.5, 1.1], "width": 12, "height": 10}],
 "integrator": {"scheme": "midpoint", "step": 0.5}}
JSON
"$ivr" render scene.json -o one.npy --precision f64
"$python" -c "import numpy as np; np.save('target.npy', (0.8 * np.load('one.npy') + 0.05).astype(np.float32))"
"$ivr" gradient scene.json --target target.npy --wrt density,tf,camera -o g1 --precision f64
"$ivr" project scene.json -o p.npy --precision f64 >/dev/null
"$ivr" backproject scene.json --images p.npy -o bp1.npy --precision f64 >/dev/null
"$ivr" tomo scene.json --projections p.npy --iterations 5 -o x1.npy --precision f64 2>/dev/null
for solver in sirt lsqr; do
  "$ivr" tomo scene.json --projections p.npy --iterations 5 --solver "$solver" --nonneg \
    -o "${solver}1.npy" --precision f64 2>/dev/null >/dev/null
done
"$ivr" tomo scene.json --projections p.npy --iterations 5 --solver lsqr --tv 1e-3 -o tv1.npy \
  --precision f64 2>/dev/null >/dev/null
det=(--target target.npy --wrt density,tf --mode adjoint --deterministic --json)
out=$("$ivr" gradient scene.json "${det[@]}" -o d1)
echo "$out" | grep -q '"deterministic":true' || { echo "gradient --deterministic: $out"; exit 1; }
rec=(--targets one.npy --init constant:0.3 --iterations 12 --batch 4 --levels 2 --precision f64)
"$ivr" reconstruct scene.json "${rec[@]}" -o rec1 2>/dev/null >/dev/null
# Over slabs: two levels (8³, 16³), SGD (linear in the gradient), both priors across the slabs.
srec=(--targets one.npy --init constant:0.3 --iterations 6 --batch 4 --levels 2 --precision f64
  --optimizer sgd --lr 1 --tv 0.05 --smoothness 0.02)
"$ivr" reconstruct scene.json "${srec[@]}" -o srec1 2>/dev/null >/dev/null
# Independent segments equal the unsplit march where early termination is off.
sed 's/"step": 0.5}/"step": 0.5, "min_transmittance": 0}/' scene.json > scene0.json
"$ivr" render scene0.json -o one0.npy --precision f64
"$ivr" gradient scene0.json --target target.npy --wrt density,tf,background -o g0 --precision f64
"$ivr" reconstruct scene0.json "${srec[@]}" -o grec1 2>/dev/null >/dev/null
run() { "$mpiexec" -np "$1" --oversubscribe "${@:2}"; }
for np in 2 4; do
  out=$(run "$np" "$ivr" render scene.json -o "r$np.npy" --precision f64 --json)
  echo "$out" | grep -q "\"ranks\":$np" || { echo "render -np $np: no \"ranks\":$np in $out"; exit 1; }
  run "$np" "$ivr" gradient scene.json --target target.npy --wrt density,tf,camera -o "g$np" \
    --precision f64 >/dev/null
  out=$(run "$np" "$ivr" gradient scene.json "${det[@]}" -o "d$np")
  echo "$out" | grep -q '"deterministic":true' || { echo "gradient --deterministic -np $np: $out"; exit 1; }
  out=$(run "$np" "$ivr" project scene.json -o "p$np.npy" --precision f64 --json)
  echo "$out" | grep -q "\"ranks\":$np" || { echo "project -np $np: no \"ranks\":$np in $out"; exit 1; }
  run "$np" "$ivr" backproject scene.json --images p.npy -o "bp$np.npy" --precision f64 >/dev/null
  out=$(run "$np" "$ivr" tomo scene.json --projections p.npy --iterations 5 -o "x$np.npy" \
    --precision f64 --json 2>/dev/null)
  echo "$out" | grep -q "\"ranks\":$np" || { echo "tomo -np $np: no \"ranks\":$np in $out"; exit 1; }
  out=$(run "$np" "$ivr" render scene.json -o "s$np.npy" --precision f64 --split slabs --json)
  echo "$out" | grep -q '"split":"slabs"' || { echo "render --split slabs -np $np: $out"; exit 1; }
  echo "$out" | grep -q '"exchanged_bytes":0,' && { echo "render --split slabs -np $np exchanged nothing: $out"; exit 1; }
  run "$np" "$ivr" gradient scene.json --target target.npy --wrt density,tf,camera -o "sg$np" \
    --precision f64 --split slabs >/dev/null
  out=$(run "$np" "$ivr" gradient scene.json "${det[@]}" --split slabs -o "ds$np")
  echo "$out" | grep -q '"deterministic":true' || { echo "gradient --deterministic --split slabs -np $np: $out"; exit 1; }
  out=$(run "$np" "$ivr" render scene0.json -o "seg$np.npy" --precision f64 --split segments --json)
  echo "$out" | grep -q '"exchanges":1,' || { echo "render --split segments -np $np: $out"; exit 1; }
  run "$np" "$ivr" gradient scene0.json --target target.npy --wrt density,tf,background \
    -o "gseg$np" --precision f64 --split segments >/dev/null
  run "$np" "$ivr" reconstruct scene0.json "${srec[@]}" -o "grec$np" --split segments \
    2>/dev/null >/dev/null
  out=$(run "$np" "$ivr" tomo scene.json --projections p.npy --iterations 5 -o "sx$np.npy" \
    --precision f64 --split slabs --json 2>/dev/null)
  echo "$out" | grep -q '"split":"slabs"' || { echo "tomo --split slabs -np $np: $out"; exit 1; }
  for solver in sirt lsqr; do  # (host vectors: views and slabs)
    run "$np" "$ivr" tomo scene.json --projections p.npy --iterations 5 --solver "$solver" \
      --nonneg -o "$solver$np.npy" --precision f64 2>/dev/null >/dev/null
    run "$np" "$ivr" tomo scene.json --projections p.npy --iterations 5 --solver "$solver" \
      --nonneg -o "s$solver$np.npy" --precision f64 --split slabs 2>/dev/null >/dev/null
  done
  run "$np" "$ivr" tomo scene.json --projections p.npy --iterations 5 --solver lsqr --tv 1e-3 \
    -o "stv$np.npy" --precision f64 --split slabs 2>/dev/null >/dev/null
  out=$(run "$np" "$ivr" reconstruct scene.json "${rec[@]}" -o "rec$np" --json 2>/dev/null)
  echo "$out" | grep -q "\"ranks\":$np" || { echo "reconstruct -np $np: $out"; exit 1; }
  out=$(run "$np" "$ivr" reconstruct scene.json "${srec[@]}" -o "srec$np" --split slabs \
    --checkpoint-every 2 --json 2>/dev/null)
  echo "$out" | grep -q '"levels":\[\[8,8,8\],\[16,16,16\]\]' || { echo "reconstruct --split slabs -np $np: $out"; exit 1; }
  ! ls srec"$np"_*checkpoint* 2>/dev/null || { echo "reconstruct --split slabs left checkpoints"; exit 1; }
done
# The ranks' shares by weight (docs/scaling.md): --shares, one a rank; else each rank's devices'
# speed from its own cost model (here two files, one a rank: rank 0 nine times slower), every rank
# keeping at least one view of each batch. The results stay one process's.
run 2 "$ivr" render scene.json -o w2.npy --precision f64 --shares 1,4 --json > w2.json
grep -q '"shares":\[1,4\]' w2.json || { echo "render --shares 1,4: $(cat w2.json)"; exit 1; }
out=$(run 2 "$ivr" gradient scene.json "${det[@]}" -o dw2 --shares 4,1)
echo "$out" | grep -q '"deterministic":true' || { echo "gradient --shares 4,1: $out"; exit 1; }
cost='{"forward_base": 1.5, "forward_per_lane": 0.16, "adjoint": 3, "seconds_per_sample": '
echo "${cost}9e-9}" > slow.json
echo "${cost}1e-9}" > fast.json
mpmd() { "$mpiexec" --oversubscribe -np 1 env IVR_COST_MODEL=slow.json "$ivr" "$@" : \
  -np 1 env IVR_COST_MODEL=fast.json "$ivr" "$@"; }
mpmd reconstruct scene.json "${rec[@]}" -o recw2 --json 2>/dev/null > recw2.json
grep -q '"shares":\[1,3\]' recw2.json || { echo "reconstruct by speed: $(cat recw2.json)"; exit 1; }
mpmd tomo scene.json --projections p.npy --iterations 5 -o xw2.npy --precision f64 --json \
  2>/dev/null > xw2.json
grep -q '"shares":\[1,4\]' xw2.json || { echo "tomo by speed: $(cat xw2.json)"; exit 1; }
mpmd project scene.json -o pw2.npy --precision f64 >/dev/null
# Ranks whose devices hold the volume differently (one in core, others over bricks of 3 and of 1
# cell: IVR_VOLUME_BRICK a rank) still sum the density in fixed point: one process's bits.
out=$("$mpiexec" --oversubscribe -np 1 "$ivr" gradient scene.json "${det[@]}" -o dmix2 : \
  -np 1 env IVR_VOLUME_BRICK=3 "$ivr" gradient scene.json "${det[@]}" -o dmix2)
echo "$out" | grep -q '"deterministic":true' || { echo "gradient, ranks in and out of core: $out"; exit 1; }
out=$("$mpiexec" --oversubscribe -np 1 env IVR_VOLUME_BRICK=1 "$ivr" gradient scene.json \
  "${det[@]}" -o dmix3 : -np 1 "$ivr" gradient scene.json "${det[@]}" -o dmix3 : \
  -np 1 env IVR_VOLUME_BRICK=3 "$ivr" gradient scene.json "${det[@]}" -o dmix3)
echo "$out" | grep -q '"deterministic":true' || { echo "gradient, 3 ranks mixed: $out"; exit 1; }
"$python" - <<'PY'
import numpy as np
assert np.array_equal(np.load("w2.npy"), np.load("one.npy")), "render --shares 1,4"
assert np.array_equal(np.load("dw2_density.npy"), np.load("d1_density.npy")), "gradient --shares 4,1"
for f in ("dmix2", "dmix3"):
    a, b = np.load("d1_density.npy"), np.load(f + "_density.npy")
    assert np.array_equal(a, b), f"{f}: {np.count_nonzero(a != b)} voxels differ from one process's"
print("ranks in core and over bricks of 1 and 3 cells: deterministic density identical")
assert np.array_equal(np.load("recw2_density.npy"), np.load("rec1_density.npy")), "reconstruct by speed"
for one, many in (("x1.npy", "xw2.npy"), ("p.npy", "pw2.npy")):
    a, b = np.load(one), np.load(many)
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert a.shape == b.shape and err <= 1e-12, f"{many} by speed: {err}"
print("-np 2 shares by weight and by speed: render, deterministic density and reconstruction identical")
PY
if run 2 "$ivr" render scene.json -o bad.npy --shares 1,2,3 2>err.txt; then
  echo "--shares with 3 weights for 2 ranks succeeded"; exit 1
fi
grep -q "3 weights for 2 ranks" err.txt || { echo "no error naming the ranks:"; cat err.txt; exit 1; }
[ ! -e bad.npy ] || { echo "bad.npy written"; exit 1; }
# The ranks' slabs by weight: --shares (15 cells 1:4, planes 0..3 and 3..15) and each rank's
# speed (the MPMD cost models 1:9: rank 0's slab the shorter); the results one process's.
run 2 "$ivr" render scene.json -o sw2.npy --precision f64 --split slabs --shares 1,4 --json > sw2.json
grep -q '"slabs":\[\[0,3\],\[3,15\]\]' sw2.json || { echo "render --split slabs --shares 1,4: $(cat sw2.json)"; exit 1; }
mpmd gradient scene.json --target target.npy --wrt density,tf,camera -o gsw2 --precision f64 \
  --split slabs --json 2>/dev/null > gsw2.json
mpmd reconstruct scene.json "${srec[@]}" -o srecw2 --split slabs --json 2>/dev/null > srecw2.json
if run 2 "$ivr" render scene.json -o bad.npy --split slabs --shares 1,2,3 2>err.txt; then
  echo "--split slabs --shares with 3 weights for 2 ranks succeeded"; exit 1
fi
grep -q "3 weights for 2 ranks" err.txt || { echo "no error naming the ranks:"; cat err.txt; exit 1; }
[ ! -e bad.npy ] || { echo "bad.npy written"; exit 1; }
"$python" - <<'PY'
import json
import numpy as np
slabs = json.load(open("gsw2.json"))["slabs"]
assert len(slabs) == 2 and slabs[0][0] == 0 and slabs[1][1] == 15 and slabs[0][1] == slabs[1][0], slabs
assert slabs[0][1] < 7, f"the slow rank's slab is not the shorter: {slabs}"
def close(want, got, tol, what):
    a, b = np.load(want), np.load(got)
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert a.shape == b.shape and err <= tol, f"{what}: {err}"
close("one.npy", "sw2.npy", 1e-12, "render --split slabs --shares 1,4")
for g in ("density", "tf", "camera"):
    close(f"g1_{g}.npy", f"gsw2_{g}.npy", 1e-10, f"gradient over slabs by speed: {g}")
a, b = np.load("srec1_density.npy"), np.load("srecw2_density.npy")
assert a.shape == b.shape and np.array_equal(a, b), \
    f"reconstruct over slabs by speed: {np.count_nonzero(a != b)} densities differ"

print(f"-np 2 slabs by weight and by speed {slabs}: render, gradient and reconstruction one process's")
PY
"$python" - <<'PY'
import numpy as np
one = np.load("one.npy")
for n in (2, 4):
    r = np.load(f"r{n}.npy")
    assert r.shape == one.shape and np.array_equal(r, one), f"render -np {n} differs"
    for g in ("density", "tf", "camera"):
        a, b = np.load(f"g1_{g}.npy"), np.load(f"g{n}_{g}.npy")
        assert a.shape == b.shape, (n, g, a.shape, b.shape)
        err = np.max(np.abs(a - b)) / max(np.max(np.abs(a)), 1e-300)
        assert np.all(np.isfinite(b)) and err <= 1e-12, f"gradient {g} -np {n}: {err}"
        print(f"-np {n} {g}: {err:.2e}")
    a, b = np.load("d1_density.npy"), np.load(f"d{n}_density.npy")
    assert a.dtype == np.float32 and np.array_equal(a, b), f"gradient --deterministic -np {n}"
    a, b = np.load("d1_tf.npy"), np.load(f"d{n}_tf.npy")
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert err <= 1e-5, f"gradient --deterministic -np {n} tf: {err}"
    print(f"-np {n} gradient --deterministic: density identical, tf {err:.2e}")
    a, b = np.load("d1_density.npy"), np.load(f"ds{n}_density.npy")
    assert a.shape == b.shape and np.array_equal(a, b), \
        f"gradient --deterministic --split slabs -np {n}: {np.count_nonzero(a != b)} voxels differ"
    print(f"-np {n} gradient --deterministic --split slabs: density identical")
    s = np.load(f"s{n}.npy")
    err = np.max(np.abs(s - one)) / np.max(np.abs(one))
    assert s.shape == one.shape and err <= 1e-12, f"render --split slabs -np {n}: {err}"
    for g in ("density", "tf", "camera"):
        a, b = np.load(f"g1_{g}.npy"), np.load(f"sg{n}_{g}.npy")
        err = np.max(np.abs(a - b)) / np.max(np.abs(a))
        # (the camera's over slabs by forward lanes, one process's by the adjoint: 1e-10)
        tol = 1e-10 if g == "camera" else 1e-12
        assert a.shape == b.shape and np.all(np.isfinite(b)) and err <= tol, f"slabs {g} -np {n}: {err}"
        print(f"-np {n} slabs: render and {g} gradient {err:.2e}")
    s = np.load(f"seg{n}.npy")
    err = np.max(np.abs(s - np.load("one0.npy"))) / np.max(np.abs(one))
    assert s.shape == one.shape and err <= 1e-12, f"render --split segments -np {n}: {err}"
    worst = err
    for g in ("density", "tf", "background"):
        a, b = np.load(f"g0_{g}.npy"), np.load(f"gseg{n}_{g}.npy")
        err = np.max(np.abs(a - b)) / np.max(np.abs(a))
        assert a.shape == b.shape and np.all(np.isfinite(b)) and err <= 1e-12, f"segments {g} -np {n}: {err}"
        worst = max(worst, err)
    la = np.loadtxt("grec1_loss.csv", delimiter=",", skiprows=1)[:, 3:5]
    lb = np.loadtxt(f"grec{n}_loss.csv", delimiter=",", skiprows=1)[:, 3:5]
    lerr = np.max(np.abs(la - lb)) / np.max(np.abs(la))
    assert la.shape == lb.shape and lerr <= 1e-12, f"reconstruct --split segments -np {n}: {lerr}"
    print(f"-np {n} segments: render and gradients {worst:.2e}, reconstruction's losses and priors {lerr:.2e}")
    la = np.loadtxt("rec1_loss.csv", delimiter=",", skiprows=1)[:, 3]
    lb = np.loadtxt(f"rec{n}_loss.csv", delimiter=",", skiprows=1)[:, 3]
    lerr = np.max(np.abs(la - lb) / la)
    assert la.shape == lb.shape and lerr <= 1e-10, f"reconstruct -np {n} losses: {lerr}"
    a, b = np.load("rec1_density.npy"), np.load(f"rec{n}_density.npy")
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert a.shape == b.shape and np.array_equal(a, b), f"reconstruct -np {n} densities: {err}"
    print(f"-np {n} reconstruct: losses {lerr:.2e}, densities identical")
    worst = 0
    for column, what in ((3, "losses"), (4, "priors")):
        la = np.loadtxt("srec1_loss.csv", delimiter=",", skiprows=1)[:, column]
        lb = np.loadtxt(f"srec{n}_loss.csv", delimiter=",", skiprows=1)[:, column]
        lerr = np.max(np.abs(la - lb)) / np.max(np.abs(la))  # (the first prior is 0)
        assert la.shape == lb.shape and lerr <= 1e-12, f"reconstruct --split slabs -np {n} {what}: {lerr}"
        worst = max(worst, lerr)
    # (fixed-point gradients, reconstruct's default: one process's densities bit for bit)
    a, b = np.load("srec1_density.npy"), np.load(f"srec{n}_density.npy")
    assert a.shape == b.shape and np.array_equal(a, b), \
        f"reconstruct --split slabs -np {n}: {np.count_nonzero(a != b)} densities differ"
    print(f"-np {n} reconstruct over slabs: losses and priors {worst:.2e}, densities identical")
    for one_name, many_name, what in (("p.npy", f"p{n}.npy", "project"),
                                      ("bp1.npy", f"bp{n}.npy", "backproject")):
        a, b = np.load(one_name), np.load(many_name)
        err = np.max(np.abs(a - b)) / np.max(np.abs(a))
        assert a.shape == b.shape and np.all(np.isfinite(b)) and err <= 1e-12, f"{what} -np {n}: {err}"
        print(f"-np {n} {what}: {err:.2e}")
    a, b = np.load("x1.npy"), np.load(f"x{n}.npy")
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert a.shape == b.shape and err <= 1e-12, f"tomo -np {n}: {err}"
    print(f"-np {n} tomo: {err:.2e}")
    b = np.load(f"sx{n}.npy")
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert a.shape == b.shape and np.all(np.isfinite(b)) and err <= 1e-10, f"tomo --split slabs -np {n}: {err}"
    print(f"-np {n} tomo over slabs: {err:.2e}")
    for solver in ("sirt", "lsqr"):
        a = np.load(f"{solver}1.npy")
        for name in (f"{solver}{n}.npy", f"s{solver}{n}.npy"):
            b = np.load(name)
            err = np.max(np.abs(a - b)) / np.max(np.abs(a))
            assert a.shape == b.shape and np.all(np.isfinite(b)) and err <= 1e-10, f"{name}: {err}"
            print(f"-np {n} tomo --solver {solver} ({'slabs' if name.startswith('s' + solver) else 'views'}): {err:.2e}")
    a, b = np.load("tv1.npy"), np.load(f"stv{n}.npy")
    err = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert a.shape == b.shape and np.all(np.isfinite(b)) and err <= 1e-10, f"tomo --tv --split slabs -np {n}: {err}"
    print(f"-np {n} tomo --solver lsqr --tv over slabs: {err:.2e}")
PY
# An error (a missing target) ends every rank with a non-zero status and writes nothing.
if run 2 "$ivr" gradient scene.json --target missing.npy --wrt density -o bad 2>err.txt; then
  echo "a missing target under mpirun succeeded"; exit 1
fi
grep -q "missing.npy" err.txt || { echo "no error naming the target:"; cat err.txt; exit 1; }
[ ! -e bad_density.npy ] || { echo "bad_density.npy written"; exit 1; }
# Over slabs, what is not built yet is refused on every rank, nothing written.
if run 2 "$ivr" gradient scene.json --target target.npy --wrt density,tf -o badbg \
    --split slabs --mode forward 2>err.txt; then
  echo "--split slabs --mode forward succeeded"; exit 1
fi
grep -q "not forward mode" err.txt || { echo "no error naming the mode:"; cat err.txt; exit 1; }
[ ! -e badbg_density.npy ] || { echo "badbg_density.npy written"; exit 1; }
echo "mpi_cli_test: passed"
