#!/usr/bin/env bash
# Builds every test with AddressSanitizer + UndefinedBehaviorSanitizer in
# ./build-asan (scripts/asan-build.sh) and runs them. Any report fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
# Only what ctest runs: the benchmarks' own tools are not built again here.
bash scripts/asan-build.sh umbra_tests
cd build-asan
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
ctest --output-on-failure -j"$(nproc)"
