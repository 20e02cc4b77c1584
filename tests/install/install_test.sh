#!/usr/bin/env bash
# install_test.sh — `cmake --install` into a temporary prefix, then build and run a consumer
# through find_package(ivr) and through pkg-config. Usage: install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >/dev/null
for f in include/ivr/ivr.hpp include/ivr/ivr.h include/ivr/version.h lib/cmake/ivr/ivrConfig.cmake lib/pkgconfig/ivr.pc bin/ivr; do
  [ -e "$work/prefix/$f" ] || { echo "install is missing $f"; exit 1; }
done
ls "$work/prefix/lib/"libivr.so.0* >/dev/null || { echo "libivr.so has no SOVERSION link"; exit 1; }
# Only the API is exported: internal symbols stay hidden.
nm -D --defined-only "$work/prefix/lib/libivr.so" >"$work/symbols"
if grep -q "fnv1a64" "$work/symbols"; then echo "internal symbols exported"; exit 1; fi
grep -q "load_scene" "$work/symbols" || { echo "API not exported"; exit 1; }

cmake -S "$src/tests/install" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/consumer" >/dev/null
LD_LIBRARY_PATH="$work/prefix/lib" "$work/consumer/consumer"

export PKG_CONFIG_PATH="$work/prefix/lib/pkgconfig"
c++ -std=c++17 "$src/tests/install/consumer.cpp" -o "$work/consumer_pc" $(pkg-config --cflags --libs ivr)
LD_LIBRARY_PATH="$work/prefix/lib" "$work/consumer_pc"
# The C API from a C compiler, through pkg-config.
cc -std=c99 "$src/tests/install/consumer.c" -o "$work/consumer_c" $(pkg-config --cflags --libs ivr)
LD_LIBRARY_PATH="$work/prefix/lib" "$work/consumer_c"
"$work/prefix/bin/ivr" --version
echo "install test passed"
