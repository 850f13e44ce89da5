#!/usr/bin/env bash
# The coordinator killed with SIGKILL in the middle of a job and started again on the same data folder and port: the
# job resumes, the workers reconnect by themselves (no new registration), tiles stored before the kill are not
# rendered again (every tile is rendered once, plus at most one per worker for the tiles in flight at the kill), and
# the result is bitwise identical to a single-process render. The job is mid-way at the kill by construction: after
# two tiles (one by each worker) each worker holds its next tile (fail point worker.render, in that tile's render
# begun ahead: the workers run two threads) until the restart. (The first tile's render is never held up by the
# next one's, which waits apart from it; a render begun ahead of another begun ahead has no such guarantee, so
# neither worker renders two tiles before its hold.)
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 64 48 16
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --threads 1
TILES=12  # 64x48 in 16-pixel tiles
start_serve --lease-seconds 10 --heartbeat-seconds 1
ADDRESS=$(head -n1 "$WORK/ready")
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 16 -o "$WORK/out.exr"
# The workers start once submit has its answer: the kill must find the job submitted, not its submission in flight.
wait_for log_has "$WORK/submit.log" "submitted .* as j-" || fail "the job was not submitted"
FAIL_POINTS="worker.render=1*off->pause($WORK/go)" start_worker w1 --threads 2
FAIL_POINTS="worker.render=1*off->pause($WORK/go)" start_worker w2 --threads 2

merged() { grep -c ": merged" "$WORK/serve.log" 2>/dev/null || true; }
held() { paused "$WORK/w1.log" && paused "$WORK/w2.log" && [ "$(merged)" -ge 2 ]; }
wait_for held || fail "the workers did not render 2 tiles and hold their next ones"
kill -KILL "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
BEFORE=$(merged)
[ "$BEFORE" = 2 ] || fail "$BEFORE tiles merged before the kill, expected 2"
log_has "$WORK/serve.log" "job .*: done" && fail "the job finished before the kill"
# Down until both workers notice (a heartbeat of the held tile fails), then back on the same port.
notices() { log_has "$WORK/w1.log" "unreachable|failed" && log_has "$WORK/w2.log" "unreachable|failed"; }
wait_for notices || fail "the workers did not notice the coordinator was gone"
LISTEN=$ADDRESS start_serve --lease-seconds 10 --heartbeat-seconds 1
log_has "$WORK/serve.log" "resuming 0 queued and 1 running job" || fail "the restarted coordinator did not resume the job"
release go

wait "$SUBMIT_PID" || fail "submit exited with $? across the restart"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs after a coordinator restart"

RENDERED=$(cat "$WORK/w1.log" "$WORK/w2.log" | grep -c ": rendered in")
echo "tiles rendered in total: $RENDERED for $TILES tiles ($BEFORE stored before the kill)"
[ "$RENDERED" -ge "$TILES" ] || fail "only $RENDERED renders for $TILES tiles"
[ "$RENDERED" -le $((TILES + 2)) ] || fail "$RENDERED renders for $TILES tiles: stored tiles were rendered again"
for w in w1 w2; do
  [ "$(grep -c "registered as" "$WORK/$w.log")" = 1 ] || fail "$w registered again instead of resuming its id"
done
# after_outage LOG: true when the worker got an upload acknowledged after its first failed request.
after_outage() { awk '/unreachable|failed/ {down = 1} down && /upload (accepted|duplicate)/ {ok = 1} END {exit !ok}' "$1"; }
after_outage "$WORK/w1.log" && after_outage "$WORK/w2.log" || fail "a worker delivered no tile after the restart"
echo "PASS"
