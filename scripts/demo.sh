#!/usr/bin/env bash
# The main job on the built-in default: render 16 views of the 32³ Shepp–Logan phantom through an
# emission–absorption TF, reconstruct its densities from them (coarse to fine, Adam), and report
# the PSNR of 4 held-out views and the relative volume error. Images and volumes go to out/, with
# two pictures drawn by scripts/demo_figures.py (Debian's python3 with numpy and matplotlib, or
# $IVR_PYTHON): target | before | after | error, and slices of the result beside the truth's.
set -euo pipefail
cd "$(dirname "$0")/.."

"$(pwd)/scripts/install-deps.sh"
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DIVR_BUILD_TESTS=OFF
cmake --build build -j"$jobs" --target ivr_cli
mkdir -p out
start=$(date +%s)
./build/ivr devices
scenes=examples/scenes
./build/ivr render "$scenes/reconstruct.json" -o out/targets.npy
./build/ivr render "$scenes/reconstruct_held_out.json" -o out/held_out.npy
./build/ivr phantom shepp-logan --size 32 -o out/truth.npy
./build/ivr reconstruct "$scenes/reconstruct.json" --targets out/targets.npy --init constant:0.5 \
  --iterations 200 --truth out/truth.npy --held-out "$scenes/reconstruct_held_out.json" \
  --held-out-targets out/held_out.npy -o out/reconstruct
"${IVR_PYTHON:-/usr/bin/python3}" scripts/demo_figures.py --ivr ./build/ivr \
  --scene "$scenes/reconstruct.json" --truth out/truth.npy --result out/reconstruct_density.npy \
  --start 0.5 --loss-csv out/reconstruct_loss.csv -o out/reconstruct
./build/ivr render "$scenes/demo.json" -o out/demo.png
echo "demo: the job took $(($(date +%s) - start)) s; wrote out/reconstruct_{density.npy,density.nrrd,loss.csv,loss.svg,before.png,after.png,target.png}, out/reconstruct_compare.png (target | before | after | error), out/reconstruct_slices.png (slices against the truth) and out/demo.png"
