#!/usr/bin/env bash
# Build the C++ runtime: fetch onnxruntime's C API header (MIT, vendored in the Go module
# github.com/yalue/onnxruntime_go, fetched through the Go module proxy into a cache, not committed),
# pick the shared library (the Python wheel's in .venv, else onnxruntime-node's), run cmake.
#   tools/onnxruntime_cpp.sh [BUILD_DIR]        prints the path of the built binary
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build/cpp}"
cache="${SEGADEFORM_TOOLS_CACHE:-$HOME/.cache/segadeform-tools}"
mkdir -p "$cache" "$build"
export GOPATH="$cache/gopath" GOFLAGS=-modcacherw
mod="github.com/yalue/onnxruntime_go@v1.27.0"
dir="$(go mod download -json "$mod" | sed -n 's/.*"Dir": "\(.*\)",/\1/p')"
[ -f "$dir/onnxruntime_c_api.h" ] || { echo "onnxruntime_c_api.h not found in $mod" >&2; exit 1; }
lib="$(ls "$root"/.venv/lib/python3*/site-packages/onnxruntime/capi/libonnxruntime.so.* 2>/dev/null | head -1 || true)"
if [ -z "$lib" ]; then
  lib="$(ls "$root"/runtimes/node/node_modules/onnxruntime-node/bin/napi-v*/linux/x64/libonnxruntime.so.* | head -1)"
fi
# the library's soname is libonnxruntime.so.1: give it that name beside the build
mkdir -p "$build/ortlib"
ln -sf "$lib" "$build/ortlib/libonnxruntime.so.1"
cmake -S "$root/runtimes/cpp" -B "$build" -DCMAKE_BUILD_TYPE=Release -DONNXRUNTIME_INCLUDE_DIR="$dir" \
  -DONNXRUNTIME_LIBRARY="$build/ortlib/libonnxruntime.so.1" > "$build/cmake.log"
cmake --build "$build" -j 2 > "$build/build.log" 2>&1 || { cat "$build/build.log" >&2; exit 1; }
echo "$build/segadeform-run"
