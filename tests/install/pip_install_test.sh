#!/usr/bin/env bash
# pip_install_test.sh — `pip install .` into a fresh virtual environment (CTest label package):
# scikit-build-core builds libivr with CMake, the package carries the library, `import ivr`
# finds it without IVR_LIBRARY, renders and differentiates; without an OpenCL platform the import
# fails with one line naming what to install.
# Usage: pip_install_test.sh SOURCE_DIR NO_PLATFORM_SHIM [BUILD_DIR]
# The first python3 on PATH makes the environment (a machine's first python3 need not be
# Debian's: numpy then comes from PyPI as the package's dependency), else Debian's.
set -euo pipefail
src=$1
shim=$2
build_dir=${3:-}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python=python3
"$python" -m venv --help >/dev/null 2>&1 || python=/usr/bin/python3
"$python" -m venv "$work/venv"
pip=("$work/venv/bin/python" -m pip)
# The build needs scikit-build-core and numpy from the package index: say so plainly without it.
if ! "${pip[@]}" download -q --no-deps -d "$work/probe" scikit-build-core >/dev/null 2>&1; then
  echo "pip_install_test: the package index is unreachable (pip download scikit-build-core failed): not run"
  exit 77
fi
args=()
[ -n "$build_dir" ] && args+=("-Cbuild-dir=$build_dir")  # kept between runs: rebuilds are incremental
unset IVR_LIBRARY PYTHONPATH
"${pip[@]}" install -q "${args[@]}" "$src"
cd "$work"  # not the source tree: the installed package is imported
"$work/venv/bin/python" - <<'PY'
import json, os, sys
import numpy as np
import ivr
site = os.path.dirname(ivr.__file__)
assert site.startswith(sys.prefix), (site, sys.prefix)
lib = ivr._library()._name
assert os.path.dirname(os.path.realpath(lib)) == os.path.realpath(site), lib
devices = ivr.devices()
assert devices and all("name" in d for d in devices), devices
print("devices:", [d["name"] for d in devices])
scene = {"model": "emission_absorption",
         "tf": {"type": "piecewise_linear", "points": [
             {"density": 0, "color": [0, 0, 0], "extinction": 0},
             {"density": 1, "color": [1, 0.8, 0.6], "extinction": 8}]},
         "cameras": [{"eye": [1.2, 0.8, 1.5], "width": 6, "height": 5}]}
v = np.full((6, 6, 6), 0.5, np.float32)
with ivr.Context() as ctx:
    image = ctx.render(scene, v)
    assert image.shape == (1, 5, 6, 4) and np.isfinite(image).all() and image.max() > 0
    loss, g = ctx.gradient(scene, v, image * 0.9, wrt=("density",))
    assert loss > 0 and g["density"].shape == (6, 6, 6) and np.abs(g["density"]).max() > 0
print("installed:", site, "library:", lib)
PY
# No OpenCL platform: the import itself fails, naming the package to install.
if out=$(LD_PRELOAD="$shim" "$work/venv/bin/python" -c "import ivr" 2>&1); then
  echo "import ivr succeeded without an OpenCL platform"; exit 1
fi
echo "$out" | tail -1 | grep -q "ImportError: ivr: .*no OpenCL platform found.*pocl-opencl-icd" || {
  echo "unclear error without a platform: $out"; exit 1; }
echo "without a platform: $(echo "$out" | tail -1)"
