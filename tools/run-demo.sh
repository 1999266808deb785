#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to the demo: installs what is missing, builds, runs the demo.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/tools/install-deps.sh"
# The CLI and what it links, not the tests: the demo runs nothing else.
bash "$root/tools/build.sh" voxshadow
build="${VOXSHADOW_BUILD_DIR:-$root/build}"
"$build/tools/voxshadow" demo --out "${1:-$root/voxshadow-demo}"
