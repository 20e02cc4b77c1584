#!/usr/bin/env bash
# Installs ivr's build and run dependencies from Debian's packages, idempotently.
set -euo pipefail

packages=(
  build-essential cmake pkg-config git python3
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers clinfo
  libopenimageio-dev libglm-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev zlib1g-dev
  python3-numpy python3-pytest python3-matplotlib  # Python binding tests, bench/ plots
  python3-pip python3-venv  # the test of `pip install .` in a fresh virtual environment (label package)
  python3-torch  # ivr.torch's tests and examples (skipped where absent)
  clang libclang-rt-dev  # the loaders' libFuzzer harnesses (scripts/fuzz.sh, CTest label fuzz)
  libopenmpi-dev openmpi-bin  # `mpirun -np N ivr …` (docs/scaling.md; CTest label mpi)
  python3-mpi4py  # ivr.mpi, the Python API under mpirun (CTest label mpi)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
