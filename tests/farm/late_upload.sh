#!/usr/bin/env bash
# A worker frozen (SIGSTOP) between rendering a tile and uploading it, past its lease: the tile is re-leased and
# rendered by another worker; after SIGCONT the late upload is acknowledged (accepted or duplicate), the job's result
# is identical to the single-process render, and the late worker carries on and stops cleanly.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 24 16 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
start_serve --lease-seconds 2 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 8 -o "$WORK/out.exr" -q

FAIL_POINTS="worker.upload=1*stop" start_worker late --threads 1
LATE=$WORKER_PID
wait_for is_stopped "$LATE" || fail "the late worker never stopped itself"
# The tile rendered last before the stop is the one waiting for its upload.
TILE=$(grep -Eo "tile=[0-9]+ lease=[^:]+: rendered in" "$WORK/late.log" | tail -n1 | grep -Eo "tile=[0-9]+")
[ -n "$TILE" ] || fail "the late worker stopped before rendering a tile"
log_has "$WORK/late.log" "fail point worker.upload: hit 1: stopping" || fail "the late worker did not stop at worker.upload"

start_worker prompt --threads 1
wait "$SUBMIT_PID" || fail "submit exited with $? while a worker was frozen"
log_has "$WORK/prompt.log" "$TILE lease=.*upload accepted" || fail "the frozen worker's $TILE was not re-leased"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"

kill -CONT "$LATE"
wait_for log_has "$WORK/late.log" "$TILE lease=.*upload (accepted|duplicate)" || fail "late upload not acknowledged"
log_has "$WORK/late.log" "$TILE lease=.*upload duplicate" || fail "the late upload of a done tile was not a duplicate"
kill -TERM "$LATE"
wait "$LATE" || fail "late worker exited with $?"
echo "PASS"
