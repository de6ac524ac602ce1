#!/usr/bin/env bash
# Sets up everything, builds, and runs every test (CTest + GoogleTest, and
# the web panel in chromium); then the same tests under AddressSanitizer +
# UBSan; then 30 s of fuzzing the request parser. Any failure, sanitizer
# report or fuzzer crash fails it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh --browser
npm ci --prefix tests/e2e --no-audit --no-fund --loglevel=error
bash scripts/build.sh -DUMBRA_BUILD_TESTS=ON
(cd build && ctest --output-on-failure -j"$(nproc)")
bash scripts/sanitize.sh
bash scripts/fuzz.sh 30
