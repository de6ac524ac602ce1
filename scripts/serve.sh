#!/usr/bin/env bash
# Sets up everything and runs umbra-server on the default scene.
# Usage: scripts/serve.sh [umbra-server options, e.g. --port 9000]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh -DUMBRA_BUILD_TESTS=OFF
exec build/server/umbra-server "$@"
