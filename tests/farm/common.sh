# Shared helpers of the farm tests (sourced). Arguments of every test: TESSERA EXR_COMPARE COURSE_DIR TESSERA_FP
# (COURSE_DIR: the course scenes, scenes/course/ in the repository; TESSERA_FP: the test binary tessera-failpoints,
# run instead of TESSERA by processes given FAIL_POINTS).
# Every process a test starts is recorded in PIDS and stopped on exit (SIGCONT, SIGTERM, then SIGKILL), by pid.
# A test never outlives its budget (TESSERA_TEST_BUDGET seconds, set by CMake 10 s under ctest's TIMEOUT): waits give
# up at the deadline with their own message, and a watchdog stops whatever still runs then, with the logs.
set -euo pipefail
TESSERA=$1
EXR_COMPARE=$2
COURSE=$3
TESSERA_FP=${4:-}
ulimit -c 0  # processes crashed on purpose (fail point abort) leave no core files
BUDGET=${TESSERA_TEST_BUDGET:-50}
# TESSERA_TEST_SPP_SCALE (N or 1/N, default 1) multiplies every spp these tests render with (see spp below), to show
# that no outcome depends on how long a render takes.
SPP_SCALE=${TESSERA_TEST_SPP_SCALE:-1}
case $SPP_SCALE in
  */*) SPP_NUM=${SPP_SCALE%%/*} SPP_DEN=${SPP_SCALE#*/} ;;
  *) SPP_NUM=$SPP_SCALE SPP_DEN=1 ;;
esac
[[ $SPP_NUM =~ ^[1-9][0-9]*$ && $SPP_DEN =~ ^[1-9][0-9]*$ ]] ||
  { echo "TESSERA_TEST_SPP_SCALE must be N or 1/N (got '$SPP_SCALE')" >&2; exit 2; }
DEADLINE=$((SECONDS + BUDGET - 2))  # waits give up 2 s before the watchdog, so their own message is the one printed
# shellcheck source-path=SCRIPTDIR source=../lib/proc.sh
source "$(dirname "${BASH_SOURCE[0]}")/../lib/proc.sh"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/tessera-farm-test.XXXXXX")
PIDS=()
FAILED=0

cleanup() {
  local p
  kill "$WATCHDOG" 2>/dev/null || true
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

# The watchdog: at the budget's end it tells this shell (USR1, which fails the test naming the command it was in)
# and, a second later, stops this shell's children so that a foreground command cannot hold the shell.
trap 'fail "out of time: still running \"$BASH_COMMAND\" ${BUDGET} s in (TESSERA_TEST_BUDGET)"' USR1
(
  trap - USR1
  for _ in $(seq $((BUDGET * 10))); do sleep 0.1; done
  kill -USR1 $$ 2>/dev/null || exit 0
  sleep 1
  for c in $(ps -o pid= --ppid $$); do [ "$c" = "$BASHPID" ] || kill -TERM "$c" 2>/dev/null || true; done
) >/dev/null 2>&1 &
WATCHDOG=$!

# wait_for COMMAND... : retries the command every 0.05 s until it succeeds (0) or the test's deadline passes (1).
wait_for() {
  while [ "$SECONDS" -lt "$DEADLINE" ]; do "$@" && return 0; sleep 0.05; done
  "$@"
}

# exec_tessera ARGS...: replaces the calling (background) subshell with `tessera ARGS...`, or, when FAIL_POINTS is
# set, with tessera-failpoints under TESSERA_FAIL_POINTS=$FAIL_POINTS (failpoint/failpoint.h describes the setting),
# so that $! is the process itself. Only for `exec_tessera ... &`.
exec_tessera() {
  if [ -n "${FAIL_POINTS:-}" ]; then
    export TESSERA_FAIL_POINTS=$FAIL_POINTS
    exec "$TESSERA_FP" "$@"
  else
    exec "$TESSERA" "$@"
  fi
}

# release NAME: creates $WORK/NAME, which a fail point set to pause($WORK/NAME) waits for.
release() { touch "$WORK/$1"; }

# paused LOG [POINT]: true when the log shows the fail point (default worker.render) paused.
paused() { log_has "$1" "fail point ${2:-worker.render}: hit [0-9]+: paused"; }

# start_serve [serve flags...]: starts the coordinator on a free loopback port (with FAIL_POINTS: the test binary);
# sets SERVE_PID and URL.
start_serve() {
  rm -f "$WORK/ready"
  exec_tessera serve --listen "${LISTEN:-127.0.0.1:0}" --ready-file "$WORK/ready" --data "$WORK/data" "$@" \
    >>"$WORK/serve.log" 2>&1 &
  SERVE_PID=$!
  PIDS+=("$SERVE_PID")
  serve_ready() { test -s "$WORK/ready" || ! kill -0 "$SERVE_PID" 2>/dev/null; }
  wait_for serve_ready && test -s "$WORK/ready" || fail "the coordinator did not become ready"
  URL="http://$(head -n1 "$WORK/ready")"
}

# start_worker NAME [worker flags...]: starts a worker logging to $WORK/NAME.log (with FAIL_POINTS: the test
# binary); sets WORKER_PID.
start_worker() {
  local name=$1
  shift
  exec_tessera worker --coordinator "$URL" --cache "$WORK/cache-$name" --name "$name" "$@" >"$WORK/$name.log" 2>&1 &
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

# spp N [MIN]: N samples per pixel scaled by TESSERA_TEST_SPP_SCALE, at least MIN (default 1).
spp() {
  local n=$(($1 * SPP_NUM / SPP_DEN)) min=${2:-1}
  echo $((n < min ? min : n))
}

# write_sphere_scene FILE WIDTH HEIGHT SPP [MIN_SPP]: a small analytic scene (no assets), at spp SPP (scaled, at least
# MIN_SPP).
write_sphere_scene() {
  cat >"$1" <<JSON
{"integrator": {"type": "intersection_test", "spp": $(spp "$4" "${5:-1}"), "point_light_position": [0, 3, 3],
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
# and EXR assets) at a small size and spp SPP (scaled).
write_cbox_scene() {
  mkdir -p "$1"
  cp -r "$COURSE/assets" "$1/"
  python3 - "$COURSE/${5:-cbox_refract_textured.json}" "$1/scene.json" "$2" "$3" "$(spp "$4")" <<'PY'
import json, sys
src, dst, w, h, spp = sys.argv[1:]
scene = json.load(open(src))
scene["film"]["resolution"] = [int(w), int(h)]
scene["integrator"]["spp"] = int(spp)
json.dump(scene, open(dst, "w"), indent=1)
PY
}
