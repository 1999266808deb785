#!/usr/bin/env bash
# Installs the Debian packages that building and testing voxshadow need (clang and llvm for the sanitizer
# build and the fuzzers, python3-matplotlib for `bench --loop --plot`, libembree-dev for the bench's Embree
# peer, slurm-wlm and munge for the single-node cluster of the Farm tests), only those missing.
# Idempotent; run as root (or with sudo available). Safe to run on every build.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  mesa-vulkan-drivers libvulkan-dev vulkan-validationlayers vulkan-tools
  glslang-tools glslang-dev
  libglm-dev
  libopenvdb-dev libopenvdb-tools libboost-iostreams-dev libtbb-dev
  libopenimageio-dev openimageio-tools
  libgtest-dev libcli11-dev nlohmann-json3-dev
  libembree-dev
  slurm-wlm munge
  python3-matplotlib
  clang-14 libclang-rt-14-dev llvm-14
  ccache
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: run as root (missing: ${missing[*]})" >&2; exit 1; }
  SUDO=sudo
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
