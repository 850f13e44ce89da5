# Shared helpers of the farm tests (sourced). Arguments of every test: TESSERA EXR_COMPARE SHARED_DIR.
# Every process a test starts is recorded in PIDS and stopped on exit (SIGCONT, SIGTERM, then SIGKILL), by pid.
set -euo pipefail
TESSERA=$1
EXR_COMPARE=$2
SHARED=$3
# shellcheck source-path=SCRIPTDIR source=../lib/proc.sh
source "$(dirname "${BASH_SOURCE[0]}")/../lib/proc.sh"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-farm-test.XXXXXX")
PIDS=()
FAILED=0

cleanup() {
  local p
  for p in "${PIDS[@]}"; do kill -CONT "$p" 2>/dev/null || true; done   # a stopped process could not act on SIGTERM
  stop_pids 50 "${PIDS[@]}"
  if [ "$FAILED" = 0 ] && [ -z "${KEEP_LOGS:-}" ]; then rm -rf "$WORK"; else echo "logs kept in $WORK" >&2; fi
}
trap cleanup EXIT

fail() {
  FAILED=1
  echo "FAIL: $*" >&2
  local f
  for f in "$WORK"/*.log; do [ -f "$f" ] && { echo "--- $f" >&2; tail -n 25 "$f" >&2; }; done
  exit 1
}

# expect_exit CODE LOG -- COMMAND...: runs the command with its stdout and stderr to LOG; fails the test unless it
# exits with status CODE.
expect_exit() {
  local want=$1 log=$2 rc=0
  [ "${3:-}" = -- ] || fail "expect_exit: usage: expect_exit CODE LOG -- COMMAND..."
  shift 3
  "$@" >"$log" 2>&1 || rc=$?
  [ "$rc" = "$want" ] || fail "exit status $rc, not $want, from: $*"
}

# wait_for COMMAND... : retries the command every 0.05 s for up to 30 s.
wait_for() {
  for _ in $(seq 600); do "$@" && return 0; sleep 0.05; done
  return 1
}

# start_serve [serve flags...]: starts the coordinator on a free loopback port; sets SERVE_PID and URL.
start_serve() {
  rm -f "$WORK/ready"
  "$TESSERA" serve --listen "${LISTEN:-127.0.0.1:0}" --ready-file "$WORK/ready" --data "$WORK/data" "$@" \
    >>"$WORK/serve.log" 2>&1 &
  SERVE_PID=$!
  PIDS+=("$SERVE_PID")
  serve_ready() { test -s "$WORK/ready" || ! kill -0 "$SERVE_PID" 2>/dev/null; }
  wait_for serve_ready && test -s "$WORK/ready" || fail "the coordinator did not become ready"
  URL="http://$(head -n1 "$WORK/ready")"
}

# start_worker NAME [worker flags...]: starts a worker logging to $WORK/NAME.log; sets WORKER_PID.
start_worker() {
  local name=$1
  shift
  "$TESSERA" worker --coordinator "$URL" --cache "$WORK/cache-$name" --name "$name" "$@" >"$WORK/$name.log" 2>&1 &
  WORKER_PID=$!
  PIDS+=("$WORKER_PID")
}

# start_submit LOG SCENE [submit flags...]: starts `tessera submit SCENE` against $URL in the background, its output
# to LOG; sets SUBMIT_PID.
start_submit() {
  local log=$1 scene=$2
  shift 2
  "$TESSERA" submit "$scene" --coordinator "$URL" "$@" >"$log" 2>&1 &
  SUBMIT_PID=$!
  PIDS+=("$SUBMIT_PID")
}

# log_has FILE PATTERN: true when the (extended) regex occurs in the file.
log_has() { grep -Eq -- "$2" "$1" 2>/dev/null; }

# process_state PID: the one-letter state from /proc (T when stopped).
process_state() { awk '{print $3}' "/proc/$1/stat" 2>/dev/null; }

# is_stopped PID: true when the process is stopped (SIGSTOP).
is_stopped() { [ "$(process_state "$1")" = T ]; }

# write_sphere_scene FILE WIDTH HEIGHT SPP: a small analytic scene (no assets).
write_sphere_scene() {
  cat >"$1" <<JSON
{"integrator": {"type": "intersection_test", "spp": $4, "point_light_position": [0, 3, 3],
                "point_light_flux": [40, 40, 40]},
 "film": {"resolution": [$2, $3]},
 "camera": {"position": [0, 0.3, 4], "look_at": [0, 0, 0], "fov": 45},
 "textures": {"white": {"type": "constant", "color": [0.8, 0.7, 0.6]},
              "blue": {"type": "constant", "color": [0.2, 0.3, 0.9]}},
 "materials": {"m": {"type": "diffuse", "texture_name": "white"}, "b": {"type": "diffuse", "texture_name": "blue"},
               "glass": {"type": "refraction", "eta": 1.5}},
 "objects": [{"type": "sphere", "center": [-0.6, 0, 0], "radius": 0.7, "material_name": "m"},
             {"type": "sphere", "center": [0.7, 0, 0.3], "radius": 0.5, "material_name": "glass"},
             {"type": "sphere", "center": [0, -101, 0], "radius": 100, "material_name": "b"}]}
JSON
}

# write_cbox_scene DIR WIDTH HEIGHT SPP [COURSE_SCENE]: a course scene (default: the textured Cornell box, with OBJ
# and EXR assets) at a small size.
write_cbox_scene() {
  mkdir -p "$1"
  cp -r "$SHARED/compat/rdr171/assets" "$1/"
  python3 - "$SHARED/compat/rdr171/${5:-cbox_refract_textured.json}" "$1/scene.json" "$2" "$3" "$4" <<'PY'
import json, sys
src, dst, w, h, spp = sys.argv[1:]
scene = json.load(open(src))
scene["film"]["resolution"] = [int(w), int(h)]
scene["integrator"]["spp"] = int(spp)
json.dump(scene, open(dst, "w"), indent=1)
PY
}
