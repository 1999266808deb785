#!/usr/bin/env bash
# Configures and builds voxshadow (Release) into ./build. Used by run-demo.sh and run-tests.sh.
# Usage: build.sh [TARGET...]: only those targets and what they depend on (run-demo.sh builds `voxshadow`);
# without arguments every target, tests included (run-tests.sh).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${VOXSHADOW_BUILD_DIR:-$root/build}"
jobs="${VOXSHADOW_JOBS:-2}"
launcher=()
# ccache, where installed, makes rebuilds of unchanged sources (another clone, a second tree) nearly free;
# the base directory makes its keys independent of where the tree lies.
if command -v ccache >/dev/null; then
  export CCACHE_BASEDIR="$root"
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
target_args=()
if [ $# -gt 0 ]; then target_args=(--target "$@"); fi
cmake --build "$build" -j "$jobs" "${target_args[@]}"
