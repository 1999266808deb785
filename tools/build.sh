#!/usr/bin/env bash
# Configures and builds voxshadow (Release) into ./build. Used by run-demo.sh and run-tests.sh.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${VOXSHADOW_BUILD_DIR:-$root/build}"
jobs="${VOXSHADOW_JOBS:-2}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "$jobs"
