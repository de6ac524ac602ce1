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
  libspng-dev                                         # PNG encoder (server/png.cpp), chosen by umbra-png-bench
  zlib1g-dev                                          # deflate, under libspng; the PNG tests inflate with it
  libstb-dev                                          # stb_image: the tests' PNG decoder; stb_image_write: bench
  libpng-dev                                          # libpng: only for umbra-png-bench's comparison
  libgtest-dev                                        # GoogleTest
  libtinygltf-dev                                     # glTF 2.0 parser (header; renderer/assets/tiny_gltf_impl.cpp compiles it)
  nettle-dev                                          # SHA-256: the ids of uploaded models
  libembree-dev                                       # Embree 3: the exact reference's ray cast against meshes
  libmeshoptimizer-dev                                # EXT_meshopt_compression in uploaded glTF (renderer/assets/gltf_meshopt.cpp)
  libdraco-dev                                        # KHR_draco_mesh_compression in uploaded glTF (renderer/assets/gltf_draco.cpp)
  libassimp-dev                                       # OBJ, STL, PLY, COLLADA, FBX, 3DS, IFC uploads (server/model_import_main.cpp)
  gltfpack draco assimp-testmodels                    # tests: compressed variants written by Debian's own tools from real models
  python3-ephem                                       # PyEphem: the sun positions tests/data/sun_positions.csv is checked against
)
# Optional groups:
#   --fuzz     clang and its libFuzzer runtime (scripts/fuzz.sh)
#   --browser  Debian's chromium, and node + npm for the panel's browser test
#   --metrics  promtool, from Debian's prometheus package, into .tools/bin
#              (the tests check GET /metrics with it)
#   --cluster  HAProxy, in front of several servers (scripts/cluster.sh), and
#              systemd-analyze for deploy/umbra@.service
want_promtool=0
for group in "$@"; do
  case "$group" in
    --fuzz) PACKAGES+=(clang-14 libclang-rt-14-dev) ;;
    --metrics) want_promtool=1 ;;
    --cluster) PACKAGES+=(haproxy systemd) ;;  # systemd: systemd-analyze checks deploy/umbra@.service
    --browser)
      PACKAGES+=(chromium nodejs)
      # A node from elsewhere (e.g. NodeSource) brings its own npm, and
      # Debian's npm package would conflict with it.
      command -v npm >/dev/null || PACKAGES+=(npm)
      ;;
    *) echo "install-deps: unknown option $group (known: --fuzz, --browser, --metrics, --cluster)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
else
  if [ -n "$SUDO" ] && ! command -v sudo >/dev/null; then
    echo "install-deps: need root or sudo to install: ${missing[*]}" >&2
    exit 1
  fi
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# promtool alone, unpacked from Debian's prometheus package into the
# repository's .tools/bin: installing the package would also enable and
# start a Prometheus server on this machine, which the tests do not need.
if [ "$want_promtool" = 1 ] && ! [ -x "$(dirname "$0")/../.tools/bin/promtool" ]; then
  tools="$(cd "$(dirname "$0")/.." && pwd)/.tools"
  work=$(mktemp -d)
  if ! (cd "$work" && apt-get download prometheus >/dev/null 2>&1); then
    $SUDO apt-get update -qq
    (cd "$work" && apt-get download prometheus >/dev/null)
  fi
  dpkg-deb -x "$work"/prometheus_*.deb "$work/root"
  mkdir -p "$tools/bin"
  cp "$work/root/usr/bin/promtool" "$tools/bin/promtool"
  rm -rf "$work"
  echo "install-deps: promtool in $tools/bin ($("$tools/bin/promtool" --version 2>&1 | head -n 1))"
fi
