#!/usr/bin/env bash
# systemd-analyze verify on deploy/umbra@.service, with ExecStart pointed
# at the binary just built (verify checks that the program exists). Any
# complaint fails the test.
#   tests/verify_unit.sh UMBRA_SERVER_BINARY UNIT_FILE
set -euo pipefail
binary="$1"
unit="$2"
command -v systemd-analyze >/dev/null || { echo "systemd-analyze not found: bash scripts/install-deps.sh --cluster" >&2; exit 1; }
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
sed "s|/usr/local/bin/umbra-server|$binary|" "$unit" > "$dir/umbra@.service"
said=$(cd "$dir" && systemd-analyze verify "$dir/umbra@8081.service" 2>&1) || { echo "$said"; exit 1; }
if [ -n "$said" ]; then
  echo "$said"
  exit 1
fi
echo "verify_unit: umbra@.service is valid"
