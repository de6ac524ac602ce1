#!/usr/bin/env bash
# Installs every Debian 12 package Umbra needs to build, run and test.
# Safe to run again: apt-get skips what is already installed.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git ca-certificates curl
  libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri   # EGL + OpenGL (Mesa llvmpipe)
  libglm-dev                                          # vector math
  libcpp-httplib-dev                                  # HTTP server (and test client)
  nlohmann-json3-dev                                  # JSON
  libstb-dev                                          # stb_image_write (PNG)
  zlib1g-dev                                          # deflate for the PNGs
  libgtest-dev                                        # GoogleTest
)
# --fuzz: also clang and its libFuzzer runtime (scripts/fuzz.sh).
if [ "${1:-}" = "--fuzz" ]; then
  PACKAGES+=(clang-14 libclang-rt-14-dev)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
