#!/usr/bin/env bash
# Sets up everything, builds, and runs every test (CTest + GoogleTest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh -DUMBRA_BUILD_TESTS=ON
cd build
ctest --output-on-failure -j"$(nproc)"
