#!/usr/bin/env bash
# Sets up everything, builds, and runs every test (CTest + GoogleTest, and
# the web panel in chromium); then the same tests under AddressSanitizer +
# UBSan; then 30 s of fuzzing the request parser, the sun-hours parser, the HTTP reader, the
# glTF loader, the CityJSON reader and the conversion of other formats. Any failure, sanitizer
# report or fuzzer crash fails it.
# Each phase prints how long it took (CI has about 15 minutes on 2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
phase_start=$SECONDS
phase() {
  echo "test.sh: $1 took $((SECONDS - phase_start)) s (total $SECONDS s)"
  phase_start=$SECONDS
}
bash scripts/install-deps.sh --browser --fuzz --metrics --cluster
npm ci --prefix tests/e2e --no-audit --no-fund --loglevel=error
phase "setup"
bash scripts/build.sh -DUMBRA_BUILD_TESTS=ON
phase "build"
(cd build && ctest --output-on-failure -j"$(nproc)")
phase "tests"
bash scripts/sanitize.sh
phase "sanitizer build and tests"
bash scripts/fuzz.sh 30
phase "fuzzing"
