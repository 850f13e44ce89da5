#!/usr/bin/env bash
# render --workers in a process that runs another thread from its start (a library preloaded for the test starts
# one): its workers cannot be forked copies of it, so they are `tessera worker` processes started with exec, and the
# render gives the single process's pixels. Seen while a tile is held at worker.render: the workers' command lines
# are `tessera worker`'s; released, the render finishes and leaves nothing running.
source "$(dirname "$0")/common.sh"
THREAD_LIB=$5
export TMPDIR=$WORK

write_sphere_scene "$WORK/s.json" 32 32 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/single.exr" -q
LD_PRELOAD=$THREAD_LIB TESSERA_FAIL_POINTS="worker.render=pause($WORK/go)" "$TESSERA_FP" render "$WORK/s.json" \
  -o "$WORK/farm.exr" --workers 2 --farm-tile 16 -q >"$WORK/render.log" 2>&1 &
RENDER=$!
PIDS+=("$RENDER")
exec_workers() { [ "$(pgrep -f -- " worker --coordinator http://127.0.0.1:[0-9]+ .*--cache $WORK/" | wc -l)" = 2 ]; }
wait_for exec_workers || fail "no two workers started with exec: $(ps -o pid,args --ppid "$RENDER" 2>/dev/null)"
touch "$WORK/go"
rc=0
wait "$RENDER" || rc=$?
[ $rc = 0 ] || fail "render --workers with exec'd workers exited with $rc: $(cat "$WORK/render.log")"
"$EXR_COMPARE" "$WORK/single.exr" "$WORK/farm.exr" || fail "the render through exec'd workers differs"
[ -z "$(pgrep -f -- "$WORK/" || true)" ] || fail "processes of the render are still running: $(pgrep -af -- "$WORK/")"
echo "PASS"
