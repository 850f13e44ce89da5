#!/usr/bin/env bash
# Uploads run beside the render loop: while a worker's first upload is held (fail point worker.upload), the worker
# leases and renders its next tile. Killed with SIGKILL in that state (an upload in flight, a second tile rendered
# and waiting to be sent), it loses no tile: both leases expire, another worker renders those very tiles, and the
# job completes bitwise identical to the single-process render.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 32 16
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --threads 1
start_serve --lease-seconds 2 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 16 -o "$WORK/out.exr" -q

FAIL_POINTS="worker.upload=pause" start_worker victim --threads 1
VICTIM=$WORKER_PID
wait_for paused "$WORK/victim.log" worker.upload || fail "the victim's first upload was not held"
rendered_two() { [ "$(grep -c 'rendered in' "$WORK/victim.log")" -ge 2 ]; }
wait_for rendered_two || fail "the victim did not render a second tile while its first upload was held"
kill -KILL "$VICTIM"
wait "$VICTIM" 2>/dev/null || true
log_has "$WORK/victim.log" "upload (accepted|acknowledged)" && fail "the victim uploaded something before it was killed"
mapfile -t LEASES < <(grep -Eo "tile=[0-9]+ lease=[^:]+: rendered in" "$WORK/victim.log" | head -n2)
[ "${#LEASES[@]}" -eq 2 ] || fail "the victim's log does not show two rendered tiles"

start_worker survivor --threads 1
SURVIVOR=$WORKER_PID
wait "$SUBMIT_PID" || fail "submit exited with $?"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs after a worker with an upload in flight was killed"
for entry in "${LEASES[@]}"; do
  TILE=$(echo "$entry" | grep -Eo "tile=[0-9]+")
  LEASE=$(echo "$entry" | grep -Eo "lease=[^:]+" | cut -d= -f2)
  log_has "$WORK/serve.log" "${TILE/=/ } worker [^ ]+: lease $LEASE expired" || fail "lease $LEASE ($TILE) did not expire"
  log_has "$WORK/survivor.log" "$TILE lease=.*upload accepted" || fail "the survivor did not render $TILE"
done
kill -TERM "$SURVIVOR"
wait "$SURVIVOR" || fail "the surviving worker exited with $? on SIGTERM"
echo "PASS"
