#!/usr/bin/env bash
# Builds every test with AddressSanitizer + UndefinedBehaviorSanitizer in
# ./build-asan and runs them. Any report fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DUMBRA_SANITIZE=ON -DUMBRA_BUILD_TESTS=ON >/dev/null
# Only what ctest runs: the benchmarks' own tools are not built again here.
cmake --build build-asan -j"$(nproc)" --target umbra_tests
cd build-asan
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
ctest --output-on-failure -j"$(nproc)"
