#!/usr/bin/env bash
# Builds the given targets in ./build-asan: clang with AddressSanitizer +
# UndefinedBehaviorSanitizer, and libFuzzer's coverage hooks, so that one
# tree serves both scripts/sanitize.sh (the tests) and scripts/fuzz.sh (the
# fuzz targets) and the libraries are compiled once for both.
#   scripts/asan-build.sh TARGET...
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh --fuzz
cmake -S . -B build-asan -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DUMBRA_SANITIZE=ON -DUMBRA_FUZZ=ON -DUMBRA_BUILD_TESTS=ON >/dev/null
cmake --build build-asan -j"$(nproc)" --target "$@"
