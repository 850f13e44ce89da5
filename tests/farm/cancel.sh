#!/usr/bin/env bash
# Cancelling a running job (DELETE /v1/jobs/{id}): submit reports it and exits 1; the worker (two threads, so the
# second tile's render is begun ahead), whose second tile is held (fail point worker.render) until its heartbeat is
# answered 410, stops that tile and drops it, and stays
# available: a following job completes identically. The hold ends only through the cancel, so the heartbeat always
# comes while the tile is in progress, whatever the machine's speed.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/slow.json" 64 32 16
write_sphere_scene "$WORK/quick.json" 16 12 2
"$TESSERA" render "$WORK/quick.json" -o "$WORK/quick-ref.exr" -q
start_serve --lease-seconds 5 --heartbeat-seconds 1
FAIL_POINTS="worker.render=1*off->1*pause->off" start_worker w --threads 2
start_submit "$WORK/submit-slow.log" "$WORK/slow.json" --tile 32 -o "$WORK/slow.exr"
wait_for log_has "$WORK/w.log" "tile=0 .*upload accepted" || fail "no tile finished"
wait_for paused "$WORK/w.log" || fail "the second tile was not held"
# The hold is in the render of tile 1, begun ahead (head start) while tile 0 rendered: it is taken up once tile 0's
# render and heartbeats have ended, so the heartbeat that meets the cancel is tile 1's own.
wait_for log_has "$WORK/w.log" "tile=1 .*leased window" || fail "the held tile is not tile 1"
# submit prints the id once the coordinator's answer arrives, which may come after the first tile was merged.
wait_for log_has "$WORK/submit-slow.log" "as j-" || fail "submit printed no job id"
JOB=$(grep -Eo "as j-[^ ]+" "$WORK/submit-slow.log" | head -n1 | cut -c4-)
[ -n "$JOB" ] || fail "no job id in submit's output"
curl -sS -f -X DELETE "$URL/v1/jobs/$JOB" >"$WORK/delete.json" || fail "DELETE failed"
grep -q '"cancelled"' "$WORK/delete.json" || fail "DELETE did not answer the cancelled job"

rc=0
wait "$SUBMIT_PID" || rc=$?
[ "$rc" = 1 ] || fail "submit of a cancelled job exited $rc, not 1"
log_has "$WORK/submit-slow.log" "was cancelled" || fail "submit did not say the job was cancelled"
[ ! -e "$WORK/slow.exr" ] || fail "an output was written for a cancelled job"
wait_for log_has "$WORK/w.log" "tile=1 .*lease revoked, tile dropped" || fail "the worker did not drop its tile"
log_has "$WORK/w.log" "tile=1 .*heartbeat answered 410" || fail "the tile was not stopped by a 410 heartbeat"
log_has "$WORK/w.log" "fail point worker.render: pause cancelled" || fail "the hold did not end through the cancel"
log_has "$WORK/w.log" "tile=1 .*rendered in" && fail "the revoked tile was rendered to the end"

"$TESSERA" submit "$WORK/quick.json" --coordinator "$URL" --tile 5 -o "$WORK/quick.exr" -q >"$WORK/submit-quick.log" 2>&1 \
  || fail "the next job failed"
"$EXR_COMPARE" "$WORK/quick-ref.exr" "$WORK/quick.exr" || fail "next job differs"
echo "PASS"
