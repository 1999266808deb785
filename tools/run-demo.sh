#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to the demo: installs what is missing, builds, runs the demo.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/tools/install-deps.sh"
bash "$root/tools/build.sh"
build="${VOXSHADOW_BUILD_DIR:-$root/build}"
"$build/tools/voxshadow" demo --out "${1:-$root/voxshadow-demo}"
