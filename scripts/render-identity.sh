#!/usr/bin/env bash
# A refactor must not change a single output byte. This renders every scene
# in bench/scenes in every output (color, shadow, depth, exact, error) with
# the server built from REV and with the working tree's, and compares the
# PNGs byte for byte.
#
# Usage: scripts/render-identity.sh [--before REV] [--size WxH] [--keep DIR]
#   --before REV  the build to compare against (default HEAD: the last commit
#                 against uncommitted changes)
#   --size WxH    override each scene's image size (default: as the scene has
#                 it, 960x540 when it has none)
#   --keep DIR    leave the PNGs in DIR/before and DIR/after
# Exit status 0 when every PNG is identical, 1 when any differs or fails. A
# scene the build before refuses with 400 (it uses a field or object type
# added since) is counted as new, not as a difference.
# REV is built in a git worktree under the keep folder (./build-identity by
# default, reused between runs); the working tree in its build-worktree
# (./build, with its own options, is left alone).
set -euo pipefail
cd "$(dirname "$0")/.."
before=HEAD size="" keep=build-identity
while [ $# -gt 0 ]; do
  case "$1" in
    --before) before="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    *) echo "unknown option: $1 (see the usage at the top of $0)" >&2; exit 2 ;;
  esac
done
if [ -n "$size" ] && ! [[ "$size" =~ ^[0-9]+x[0-9]+$ ]]; then
  echo "--size takes WxH, e.g. 480x270" >&2; exit 2
fi
rev=$(git rev-parse --verify "$before^{commit}")
mkdir -p "$keep"
keep=$(cd "$keep" && pwd)

build_server() {  # source dir, build dir
  cmake -S "$1" -B "$2" -DCMAKE_BUILD_TYPE=Release -DUMBRA_BUILD_TESTS=OFF >/dev/null
  cmake --build "$2" -j"$(nproc)" --target umbra-server >/dev/null
}

echo "building $rev (before)..."
tree="$keep/src-$rev"
if [ ! -d "$tree" ]; then
  git worktree add --detach "$tree" "$rev" >/dev/null 2>&1
fi
build_server "$tree" "$keep/build-$rev"
echo "building the working tree (after)..."
build_server . "$keep/build-worktree"

render() {  # server binary, output folder
  rm -rf "$2"; mkdir -p "$2"
  python3 - "$1" "$2" "$size" <<'EOF'
import json, os, socket, subprocess, sys, time, urllib.request, glob
server, out, size = sys.argv[1], sys.argv[2], sys.argv[3]
s = socket.socket(); s.bind(("127.0.0.1", 0)); port = s.getsockname()[1]; s.close()
proc = subprocess.Popen([server, "--port", str(port), "--max-run-ms", "600000", "--max-request-ms", "600000",
                         "--deadline-ms", "600000"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
try:
    for _ in range(300):
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/api/health", timeout=1); break
        except Exception: time.sleep(0.1)
    failed = 0
    for path in sorted(glob.glob("bench/scenes/*.json")):
        scene = json.load(open(path))
        if size:
            w, h = size.split("x"); scene["width"], scene["height"] = int(w), int(h)
        name = os.path.basename(path)[:-5]
        for output in ["color", "shadow", "depth", "exact", "error"]:
            body = dict(scene, output=output)
            req = urllib.request.Request(f"http://127.0.0.1:{port}/api/render", json.dumps(body).encode(),
                                         {"Content-Type": "application/json"})
            try:
                png = urllib.request.urlopen(req, timeout=900).read()
                open(f"{out}/{name}.{output}.png", "wb").write(png)
            except Exception as e:
                detail = e.read().decode(errors="replace") if hasattr(e, "read") else ""
                if getattr(e, "code", 0) == 400:
                    # A scene this build cannot read (a field or type added
                    # since): listed, and compared as new, not as a failure.
                    open(f"{out}/refused.txt", "a").write(f"{name}.{output}.png {detail}\n")
                    continue
                failed += 1
                print(f"  {name} {output}: {e} {detail}", file=sys.stderr)
    sys.exit(1 if failed else 0)
finally:
    proc.terminate(); proc.wait()
EOF
}

status=0
echo "rendering with $rev..."
render "$keep/build-$rev/server/umbra-server" "$keep/before" || status=1
echo "rendering with the working tree..."
render "$keep/build-worktree/server/umbra-server" "$keep/after" || status=1

same=0 differ=0 new=0
for f in "$keep"/before/*.png; do
  name=$(basename "$f")
  if [ ! -f "$keep/after/$name" ]; then
    echo "missing after: $name"; differ=$((differ + 1))
  elif cmp -s "$f" "$keep/after/$name"; then
    same=$((same + 1))
  else
    echo "differs: $name"; differ=$((differ + 1))
  fi
done
for f in "$keep"/after/*.png; do
  name=$(basename "$f")
  [ -f "$keep/before/$name" ] && continue
  if grep -q "^$name " "$keep/before/refused.txt" 2>/dev/null; then
    new=$((new + 1))
  else
    echo "missing before: $name"; differ=$((differ + 1))
  fi
done
[ "$new" -eq 0 ] || echo "$new PNGs new: scenes the build before refuses (400; see $keep/before/refused.txt)"
echo "$same PNGs identical, $differ different or missing (before $rev, after the working tree)"
[ "$differ" -eq 0 ] && [ "$status" -eq 0 ]
