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
# Image files: the installed CLI loads the installed image module on its first PNG, and neither it
# nor libivr links OpenImageIO; without the module a PNG is one clear error and no file.
if ldd "$work/prefix/bin/ivr" | grep -q OpenImageIO; then echo "the CLI links OpenImageIO"; exit 1; fi
if [ -e "$work/prefix/lib/libivr_image.so" ]; then
  python3 - "$work" <<'PY'
import struct, sys
w = sys.argv[1]
header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 2, 2), }"
header += " " * (63 - len(header)) + "\n"
open(w + "/vol.npy", "wb").write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) +
                                 header.encode() + struct.pack("<8f", *[0.5] * 8))
open(w + "/scene.json", "w").write('{"volume": {"file": "vol.npy"}, "tf": {"type": "identity"}, '
  '"cameras": [{"eye": [0, 0, 2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40, '
  '"width": 4, "height": 4}]}')
PY
  IVR_IMAGE_MODULE= "$work/prefix/bin/ivr" render "$work/scene.json" -o "$work/a.png" >/dev/null
  [ -s "$work/a.png" ] || { echo "no PNG through the installed image module"; exit 1; }
  rm "$work/prefix/lib/libivr_image.so"
  if IVR_IMAGE_MODULE= "$work/prefix/bin/ivr" render "$work/scene.json" -o "$work/b.png" 2>"$work/err"; then
    echo "a PNG without the image module"; exit 1
  fi
  grep -q "ivr: error: cannot write .*libivr_image.so" "$work/err" || { cat "$work/err"; exit 1; }
  [ ! -e "$work/b.png" ] || { echo "a PNG written despite the error"; exit 1; }
fi
echo "install test passed"
