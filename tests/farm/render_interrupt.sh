#!/usr/bin/env bash
# render --workers stops its coordinator (threads of its own) and its worker processes whatever happens: after Ctrl-C
# (SIGINT) in the middle of a render it exits 130, its workers stop cleanly (none has to be killed) and none of them is
# left; a scene the coordinator refuses is reported with the coordinator's message (exit 2) and leaves no worker behind
# either; so does a render whose workers die (exit 1, the logs kept); a finished render (whose workers are killed once
# the result is saved) leaves neither a worker nor its folder.
# "In the middle" by construction: the render runs as tessera-failpoints with every tile held at worker.render (the
# workers inherit the setting), and the interrupt comes once both workers hold one; the hold ends with the cancel.
source "$(dirname "$0")/common.sh"

children_of() { ps -o pid= --ppid "$1" 2>/dev/null | tr -d ' '; }
# Processes of this test's renders: the commands and their workers (forked copies, whose command line is the
# command's, or `tessera worker`s naming the render's folder) all name this test's folder.
leftovers() { pgrep -f -- "$WORK/" || true; }
export TMPDIR=$WORK

write_sphere_scene "$WORK/slow.json" 64 64 16
TESSERA_FAIL_POINTS=worker.render=pause "$TESSERA_FP" render "$WORK/slow.json" -o "$WORK/slow.exr" --workers 2 --threads 2 \
  --farm-tile 16 >"$WORK/render.log" 2>&1 &
RENDER=$!
PIDS+=("$RENDER")
has_two_children() { [ "$(children_of "$RENDER" | wc -l)" -ge 2 ]; }
wait_for has_two_children || fail "render --workers did not start 2 workers"
wait_for log_has "$WORK/render.log" "submitted" || fail "nothing submitted"
both_held() { [ "$(cat "$WORK"/tessera-render-*/worker-*.log 2>/dev/null | grep -c "fail point worker.render: hit 1: paused")" = 2 ]; }
wait_for both_held || fail "the workers did not both hold a tile"
KIDS=$(children_of "$RENDER")
kill -INT "$RENDER"
rc=0
wait "$RENDER" || rc=$?
[ $rc = 130 ] || fail "interrupted render exited with $rc, not 130"
for k in $KIDS; do
  if kill -0 "$k" 2>/dev/null; then fail "child $k of the interrupted render is still running"; fi
done
[ -z "$(leftovers)" ] || fail "processes of the interrupted render are still running: $(leftovers)"
[ ! -e "$WORK/slow.exr" ] || fail "an interrupted render wrote its output"
log_has "$WORK/render.log" "was killed" && fail "a child had to be killed: $(grep "was killed" "$WORK/render.log")"

write_sphere_scene "$WORK/bad.json" 8 8 1
sed -i 's/"radius": 0.7/"radius": -1/' "$WORK/bad.json"
expect_exit 2 "$WORK/render-bad.log" -- "$TESSERA" render "$WORK/bad.json" -o "$WORK/bad.exr" --workers 1
log_has "$WORK/render-bad.log" "radius" || fail "the coordinator's message was not shown"
[ -z "$(leftovers)" ] || fail "processes of the failed render are still running: $(leftovers)"

# The workers dying while the coordinator checks the submission (held at submit.validate until a file appears; the
# workers are SIGKILLed, then the check released): the render fails (exit 1) saying so, shows its logs and keeps
# them, and leaves nothing running.
write_sphere_scene "$WORK/lost.json" 16 16 2
TESSERA_FAIL_POINTS="submit.validate=pause($WORK/go)" "$TESSERA_FP" render "$WORK/lost.json" -o "$WORK/lost.exr" \
  --workers 1 >"$WORK/render-lost.log" 2>&1 &
RENDER=$!
PIDS+=("$RENDER")
checking() { paused "$(compgen -G "$WORK/tessera-render-*/serve.log" | head -n1)" submit.validate; }
wait_for checking || fail "the coordinator did not hold the submission's check"
KIDS=$(children_of "$RENDER")
[ -n "$KIDS" ] || fail "no worker to kill"
kill -KILL $KIDS
touch "$WORK/go"
rc=0
wait "$RENDER" || rc=$?
[ $rc = 1 ] || fail "a render whose workers died exited with $rc, not 1"
log_has "$WORK/render-lost.log" "worker 0 \(killed by signal 9\)" ||
  fail "the worker's death was not reported: $(cat "$WORK/render-lost.log")"
log_has "$WORK/render-lost.log" "logs kept in $WORK/tessera-render-" || fail "the logs were not kept"
[ -z "$(leftovers)" ] || fail "processes of the render whose workers died are still running: $(leftovers)"
[ ! -e "$WORK/lost.exr" ] || fail "a failed render wrote its output"
rm -rf "$WORK"/tessera-render-*

write_sphere_scene "$WORK/done.json" 16 16 2
"$TESSERA" render "$WORK/done.json" -o "$WORK/done.exr" --workers 2 --farm-tile 8 >"$WORK/render-done.log" 2>&1 ||
  fail "render --workers failed"
"$TESSERA" render "$WORK/done.json" -o "$WORK/done-ref.exr" -q
"$EXR_COMPARE" "$WORK/done-ref.exr" "$WORK/done.exr" || fail "the finished farm render differs"
[ -z "$(leftovers)" ] || fail "processes of the finished render are still running: $(leftovers)"
compgen -G "$WORK/tessera-render-*" >/dev/null && fail "the finished render left its folder: $(ls -d "$WORK"/tessera-render-*)"
echo "PASS"
