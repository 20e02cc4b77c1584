#!/usr/bin/env bash
# gpu_carry_extras.sh — adds to .gpu-carry/ (after ../shared/gpu/bundle.sh) what the lent GPU
# machine lacks for ivr's own runs: Open MPI's runtime (mpirun, libmpi and their libraries, from
# this machine's Debian packages) and the CMake module the suite's test discovery includes
# (GoogleTestAddTests.cmake of this machine's CMake: the machine's CMake is another version).
# On the device, after `source .gpu-carry/setup.sh`: `source "$C/extras.sh"` with C the carry's
# absolute path taken before setup.sh changes directory (C=$PWD/.gpu-carry). Then `ctest` finds
# the tests and `$MPIRUN` (mpirun.openmpi) runs ranks (scripts/mpi_scaling.sh --mpirun "$MPIRUN").
# Files already on the device are kept (tar --skip-old-files); everything lands at this machine's
# absolute paths. About 5.5 MiB.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -d .gpu-carry ] || { echo "gpu_carry_extras.sh: no .gpu-carry/: run ../shared/gpu/bundle.sh first" >&2; exit 1; }
packages=(openmpi-bin libopenmpi3 openmpi-common libpmix2 libhwloc15 libevent-core-2.1-7
  libevent-pthreads-2.1-7 libfabric1 libucx0 libpsm-infinipath1 libpsm2-2 librdmacm1 libibverbs1
  ibverbs-providers libnl-3-200 libnl-route-3-200 libnuma1 libmunge2 libatomic1)
list=$(mktemp)
trap 'rm -f "$list"' EXIT
dpkg -L "${packages[@]}" | grep -v '^/usr/share/\(doc\|man\|lintian\)' | while read -r f; do
  if [ -L "$f" ] || [ -f "$f" ]; then echo "${f#/}"; fi
done | sort -u > "$list"
tar -C / -cJf .gpu-carry/mpi-runtime.tar.xz -T "$list"
module=$(ls /usr/share/cmake-*/Modules/GoogleTestAddTests.cmake | head -1)
cp "$module" .gpu-carry/
cat > .gpu-carry/extras.sh <<EXTRAS
# Sourced on the GPU machine after setup.sh, with C the carry's absolute path.
tar -C / --skip-old-files -xJf "\$C/mpi-runtime.tar.xz"
mkdir -p "$(dirname "$module")" && cp -n "\$C/GoogleTestAddTests.cmake" "$module"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export MPIRUN=/usr/bin/mpirun.openmpi
EXTRAS
du -sh .gpu-carry/mpi-runtime.tar.xz
echo "gpu_carry_extras.sh: on the device: C=\$PWD/.gpu-carry; source .gpu-carry/setup.sh && source \$C/extras.sh"
