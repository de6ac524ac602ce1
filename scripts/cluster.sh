#!/usr/bin/env bash
# N umbra-servers on loopback behind HAProxy, in the foreground:
#   scripts/cluster.sh N PORT [umbra-server flags...]
# HAProxy listens on PORT (all addresses: put a firewall in front, or bind
# it to one in deploy/haproxy.cfg); the servers on PORT+1 ... PORT+N, with
# one --model-store folder (.cluster/models) so that a model uploaded to
# any is found by every one. Ctrl-C or SIGTERM stops them all.
set -euo pipefail
cd "$(dirname "$0")/.."
count="${1:?usage: scripts/cluster.sh N PORT [umbra-server flags...]}"
port="${2:?usage: scripts/cluster.sh N PORT [umbra-server flags...]}"
shift 2
bash scripts/install-deps.sh --cluster
[ -x build/server/umbra-server ] || bash scripts/build.sh
mkdir -p .cluster/models
config=.cluster/haproxy.cfg
cp deploy/haproxy.cfg "$config"
pids=()
stop() {
  trap - INT TERM EXIT
  kill -TERM "${pids[@]}" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap stop INT TERM EXIT
for i in $(seq 1 "$count"); do
  build/server/umbra-server --port $((port + i)) --model-store .cluster/models --quiet "$@" &
  pids+=($!)
  echo "    server render$i 127.0.0.1:$((port + i))" >> "$config"
done
UMBRA_BIND=":$port" UMBRA_DIR="$PWD/deploy" haproxy -f "$config" -db &
pids+=($!)
echo "cluster: $count umbra-servers behind HAProxy on http://localhost:$port/ (Ctrl-C stops them)"
wait -n "${pids[@]}"
