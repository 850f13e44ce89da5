#!/usr/bin/env bash
# A worker killed with SIGKILL in the middle of a tile: the lease expires, another worker renders the tile, and the
# job completes bitwise identical to the single-process render. The surviving worker exits 0 on SIGTERM.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 32 1024
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --threads 1
start_serve --lease-seconds 2 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 16 -o "$WORK/out.exr" -q

start_worker victim --threads 1
VICTIM=$WORKER_PID
wait_for log_has "$WORK/victim.log" "leased window" || fail "the victim leased nothing"
kill -KILL "$VICTIM"
wait "$VICTIM" 2>/dev/null || true
log_has "$WORK/victim.log" "upload (accepted|duplicate)" && echo "note: the victim finished a tile before it was killed"

start_worker survivor --threads 1
SURVIVOR=$WORKER_PID
wait "$SUBMIT_PID" || fail "submit exited with $?"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs after a worker was killed"

kill -TERM "$SURVIVOR"
wait "$SURVIVOR" || fail "the surviving worker exited with $? on SIGTERM"
log_has "$WORK/survivor.log" "stopping: [0-9]+ tiles uploaded" || fail "no exit summary"
echo "PASS"
