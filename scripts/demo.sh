#!/usr/bin/env bash
# Builds ivr and renders the built-in synthetic volume to out/demo.png (the main job, for now).
set -euo pipefail
cd "$(dirname "$0")/.."

"$(pwd)/scripts/install-deps.sh"
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DIVR_BUILD_TESTS=OFF
cmake --build build -j"$jobs" --target ivr_cli
mkdir -p out
./build/ivr devices
./build/ivr render examples/scenes/demo.json -o out/demo.png --json
echo "demo: wrote out/demo.png"
