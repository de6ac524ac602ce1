#!/usr/bin/env bash
# The same load against 1 and then 3 umbra-servers behind HAProxy
# (scripts/cluster.sh), with umbra-load-bench's default frame (960x540, the
# light moving), 16 clients: writes bench/results/cluster-1.md and
# cluster-3.md. On a 2-core machine llvmpipe already keeps both cores busy
# with one server, so three cannot render faster: what this shows is that
# the balancer loses nothing and what it costs.
#   bench/cluster-bench.sh [SECONDS]   (default 10)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-10}"
[ -x build/bench/umbra-load-bench ] || bash scripts/build.sh
port=18400
for n in 1 3; do
  bash scripts/cluster.sh "$n" "$port" > ".cluster-bench-$n.log" 2>&1 &
  cluster=$!
  for _ in $(seq 1 100); do
    curl -sf "http://127.0.0.1:$port/api/health" >/dev/null 2>&1 && break
    sleep 0.1
  done
  sleep 1.5  # every server checked up
  build/bench/umbra-load-bench --url "127.0.0.1:$port" --seconds "$seconds" --clients 16 \
    --out "bench/results/cluster-$n.md"
  kill -TERM "$cluster"
  wait "$cluster" || true
  rm -f ".cluster-bench-$n.log"
done
