#!/usr/bin/env bash
# N umbra-servers on loopback behind HAProxy, in the foreground, supervised:
#   scripts/cluster.sh N PORT [umbra-server flags...]
# HAProxy listens on 127.0.0.1:PORT (UMBRA_CLUSTER_HOST=ADDRESS to listen
# elsewhere, e.g. 0.0.0.0: then the server flags must hold --tokens FILE or
# --no-auth, and --allowed-hosts with the names clients use; see
# docs/operations.md#several-servers-behind-haproxy);
# the servers on 127.0.0.1:PORT+1 ... PORT+N, with one --model-store folder
# so that a model uploaded to any is found by every one.
#
# A server or HAProxy that exits (killed, crashed, drained by a SIGTERM sent
# to it alone) is started again after a backoff: 1 s, doubling up to 30 s,
# back to 1 s once it has run for a minute. The others keep serving
# meanwhile, and HAProxy sends nothing to a server until its health check
# passes. Only Ctrl-C or SIGTERM to this script stops them all: each server
# drains (answers what it has received) and exits.
#
# Environment (all optional):
#   UMBRA_CLUSTER_DIR   state folder: haproxy.cfg, models/, and NAME.pid holding
#                       the current PID of render1..renderN and haproxy
#                       (default .cluster in the repository)
#   UMBRA_SERVER        the umbra-server binary (default build/server/umbra-server,
#                       built first if missing)
#   UMBRA_CLUSTER_HOST  HAProxy's listening address (default 127.0.0.1)
set -euo pipefail
cd "$(dirname "$0")/.."
usage="usage: scripts/cluster.sh N PORT [umbra-server flags...]"
count="${1:?$usage}"
port="${2:?$usage}"
shift 2
if ! [[ "$count" =~ ^[1-9][0-9]?$ ]] || ! [[ "$port" =~ ^[1-9][0-9]*$ ]] || ((port + count > 65535)); then
  echo "$usage (N 1..99, PORT+N at most 65535)" >&2
  exit 2
fi
dir="${UMBRA_CLUSTER_DIR:-.cluster}"
server="${UMBRA_SERVER:-build/server/umbra-server}"
host="${UMBRA_CLUSTER_HOST:-127.0.0.1}"

# The servers listen on loopback, but HAProxy exposes them: the rule a
# server applies to its own --host applies to HAProxy's address.
loopback() { [[ "$1" =~ ^(localhost|::1|\[::1\]|127\.[0-9]{1,3}\.[0-9]{1,3}\.[0-9]{1,3})$ ]]; }
if ! loopback "$host" && ! printf '%s\n' "$@" | grep -qx -e --tokens -e --no-auth; then
  echo "cluster: HAProxy on $host is reachable from other machines: give the servers --tokens FILE" \
    "(or --no-auth to let anyone render and upload), and --allowed-hosts with the names clients use" >&2
  exit 2
fi

bash scripts/install-deps.sh --cluster >/dev/null
[ -x "$server" ] || bash scripts/build.sh
# Debian puts haproxy in /usr/sbin, which a user's PATH may lack.
haproxy="$(command -v haproxy || echo /usr/sbin/haproxy)"
mkdir -p "$dir/models"
dir="$(cd "$dir" && pwd)"
config="$dir/haproxy.cfg"
cp deploy/haproxy.cfg "$config"
for i in $(seq 1 "$count"); do
  echo "    server render$i 127.0.0.1:$((port + i))" >>"$config"
done
# A sun-hours job's id begins with its server's --name: its GET and DELETE
# go back to that server (docs/operations.md#sun-hours-jobs).
for i in $(seq 1 "$count"); do
  echo "    use-server render$i if { path_beg /api/sun-hours/jobs/render$i. }" >>"$config"
done

# supervise NAME COMMAND...: runs COMMAND in the background, writes its PID
# to $dir/NAME.pid, and starts it again whenever it exits, until this
# subshell gets SIGTERM: then it passes the signal on, waits for COMMAND to
# finish (a server drains first) and exits 0. If COMMAND's first run
# exits with an error status (not killed by a signal) within $first_run_s
# seconds, what it was given cannot work (an unknown flag, a port in use,
# no binary): it exits 1 instead, and the script stops everything.
first_run_s=10
supervise() {
  local name=$1
  shift
  local child="" pause="" stopping=0 backoff=1 runs=0 started status
  trap 'stopping=1; kill -TERM $child $pause 2>/dev/null || true' TERM
  while [ "$stopping" = 0 ]; do
    started=$SECONDS
    "$@" &
    child=$!
    runs=$((runs + 1))
    echo "$child" >"$dir/$name.pid"
    status=0
    wait "$child" || status=$?
    # A trapped signal ends `wait` early: wait for the child itself.
    while kill -0 "$child" 2>/dev/null; do wait "$child" || true; done
    child=""  # its PID may be reused now: never signal it again
    [ "$stopping" = 0 ] || break
    if ((runs == 1 && status > 0 && status < 128 && SECONDS - started < first_run_s)); then
      echo "cluster: $name exited (status $status) $((SECONDS - started)) s after its first start: stopping" >&2
      rm -f "$dir/$name.pid"
      exit 1
    fi
    if ((SECONDS - started >= 60)); then backoff=1; fi
    echo "cluster: $name exited (status $status) after $((SECONDS - started)) s; starting it again in $backoff s" >&2
    sleep "$backoff" &
    pause=$!
    wait "$pause" || true
    kill "$pause" 2>/dev/null || true  # when a signal ended the wait
    pause=""
    backoff=$((backoff * 2 > 30 ? 30 : backoff * 2))
  done
  rm -f "$dir/$name.pid"
}

supervisors=()
stopping=0
stop() {
  trap - INT TERM EXIT
  stopping=1
  echo "cluster: stopping (each server answers what it has received first)" >&2
  kill -TERM "${supervisors[@]}" 2>/dev/null || true
  wait || true
}
trap stop INT TERM EXIT
for i in $(seq 1 "$count"); do
  supervise "render$i" "$server" --port $((port + i)) --name "render$i" --model-store "$dir/models" --quiet "$@" &
  supervisors+=($!)
done
UMBRA_BIND="$host:$port" UMBRA_DIR="$PWD/deploy" supervise haproxy "$haproxy" -f "$config" -db &
supervisors+=($!)
echo "cluster: $count umbra-servers behind HAProxy on http://$host:$port/ (Ctrl-C stops them)"
# A supervisor ends by itself only when what it runs cannot start: then
# everything stops, exit 1. Else this waits until a signal runs stop().
if wait -n "${supervisors[@]}" && [ "$stopping" = 0 ]; then :; fi
if [ "$stopping" = 0 ]; then
  stop
  exit 1
fi
