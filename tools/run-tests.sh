#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a tested build: installs what is missing, builds, runs
# every test (Vulkan tests on lavapipe under the validation layers), then the same suite built with
# AddressSanitizer and UBSan (./build-asan) and a short pass of every fuzz target.
# VOXSHADOW_SANITIZED=0 stops after the plain suite.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/tools/install-deps.sh"
bash "$root/tools/build.sh"
build="${VOXSHADOW_BUILD_DIR:-$root/build}"
cd "$build"
ctest --output-on-failure -j "${VOXSHADOW_JOBS:-2}" --timeout 900
if [ "${VOXSHADOW_SANITIZED:-1}" != 0 ]; then
  bash "$root/tools/run-sanitized.sh"
  bash "$root/tools/fuzz.sh"
fi
