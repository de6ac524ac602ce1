#!/usr/bin/env bash
# Sets up everything, builds, and runs every test (CTest + GoogleTest); then
# the same tests under AddressSanitizer + UBSan; then 30 s of fuzzing the
# request parser. Any failure, sanitizer report or fuzzer crash fails it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh -DUMBRA_BUILD_TESTS=ON
(cd build && ctest --output-on-failure -j"$(nproc)")
bash scripts/sanitize.sh
bash scripts/fuzz.sh 30
