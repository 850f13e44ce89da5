# Shared setup of the shell benchmarks (sourced after BUILD and COURSE are set): T (the tessera binary), a temporary
# WORK folder, PIDS (every background process, stopped with SIGTERM on exit, then WORK is removed), scene() and
# start_serve().
# Argument: NAME, the benchmark's name in WORK's folder name (tessera-NAME-bench.XXXXXX).
# shellcheck shell=bash
# shellcheck disable=SC2034  # T is used by the sourcing script
T="$BUILD/cli/tessera"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-$1-bench.XXXXXX")
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

# scene NAME WIDTH HEIGHT SPP: the course's textured Cornell box at a chosen size and spp, as $WORK/NAME/scene.json
# (with its assets).
scene() {
  mkdir -p "$WORK/$1"
  cp -r "$COURSE/assets" "$WORK/$1/"
  python3 - "$COURSE/cbox_refract_textured.json" "$WORK/$1/scene.json" "$2" "$3" "$4" <<'PY'
import json, sys
src, dst, w, h, spp = sys.argv[1:]
s = json.load(open(src)); s["film"]["resolution"] = [int(w), int(h)]; s["integrator"]["spp"] = int(spp)
json.dump(s, open(dst, "w"))
PY
}

# start_serve [serve flags...]: starts `tessera serve` on a free loopback port with its data in $WORK/data, logging to
# $WORK/serve.log, and waits (at most 10 s) for its address; sets SERVE_PID and URL, or exits with the log's end.
start_serve() {
  "$T" serve --listen 127.0.0.1:0 --ready-file "$WORK/ready" --data "$WORK/data" "$@" >"$WORK/serve.log" 2>&1 &
  SERVE_PID=$!
  PIDS+=("$SERVE_PID")
  for _ in $(seq 200); do [ -s "$WORK/ready" ] && break; sleep 0.05; done
  if ! [ -s "$WORK/ready" ]; then
    echo "tessera serve did not start: $(tail -n 3 "$WORK/serve.log")" >&2
    exit 1
  fi
  URL="http://$(head -n1 "$WORK/ready")"
}
