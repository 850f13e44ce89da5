#!/usr/bin/env bash
# Cancelling a running job (DELETE /v1/jobs/{id}): submit reports it and exits 1; the worker, in the middle of a
# tile that takes longer than a heartbeat period, gets 410 on its next heartbeat, stops rendering and drops the tile,
# and stays available: a following job completes identically.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/slow.json" 64 32 4096
write_sphere_scene "$WORK/quick.json" 16 12 2
"$TESSERA" render "$WORK/quick.json" -o "$WORK/quick-ref.exr" -q
start_serve --lease-seconds 5 --heartbeat-seconds 1
start_worker w --threads 1
start_submit "$WORK/submit-slow.log" "$WORK/slow.json" --tile 32 -o "$WORK/slow.exr"
wait_for log_has "$WORK/w.log" "upload accepted" || fail "no tile finished"
JOB=$(grep -Eo "as j-[^ ]+" "$WORK/submit-slow.log" | head -n1 | cut -c4-)
[ -n "$JOB" ] || fail "no job id in submit's output"
curl -sS -f -X DELETE "$URL/v1/jobs/$JOB" >"$WORK/delete.json" || fail "DELETE failed"
grep -q '"cancelled"' "$WORK/delete.json" || fail "DELETE did not answer the cancelled job"

if wait "$SUBMIT_PID"; then fail "submit of a cancelled job exited 0"; fi
log_has "$WORK/submit-slow.log" "was cancelled" || fail "submit did not say the job was cancelled"
[ ! -e "$WORK/slow.exr" ] || fail "an output was written for a cancelled job"
wait_for log_has "$WORK/w.log" "tile=1 .*lease revoked, tile dropped" || fail "the worker did not drop its tile"
log_has "$WORK/w.log" "tile=1 .*heartbeat answered 410" || fail "the tile was not stopped by a 410 heartbeat"
log_has "$WORK/w.log" "tile=1 .*rendered in" && fail "the revoked tile was rendered to the end"

"$TESSERA" submit "$WORK/quick.json" --coordinator "$URL" --tile 5 -o "$WORK/quick.exr" -q >"$WORK/submit-quick.log" 2>&1 \
  || fail "the next job failed"
"$EXR_COMPARE" "$WORK/quick-ref.exr" "$WORK/quick.exr" || fail "next job differs"
echo "PASS"
