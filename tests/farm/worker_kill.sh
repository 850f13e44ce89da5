#!/usr/bin/env bash
# A worker killed with SIGKILL in the middle of a tile: its lease expires (the coordinator logs it), another worker
# renders that very tile, and the job completes bitwise identical to the single-process render. The surviving worker
# exits 0 on SIGTERM. "In the middle of a tile" by construction: the victim holds its first tile at fail point
# worker.render and is killed there.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 32 16
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --threads 1
start_serve --lease-seconds 2 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 16 -o "$WORK/out.exr" -q

FAIL_POINTS=worker.render=pause start_worker victim --threads 2
VICTIM=$WORKER_PID
wait_for paused "$WORK/victim.log" || fail "the victim held no tile"
kill -KILL "$VICTIM"
wait "$VICTIM" 2>/dev/null || true
log_has "$WORK/victim.log" "upload" && fail "the victim uploaded something before it was killed"
TILE=$(grep -Eo "tile=[0-9]+ lease=[^:]+: leased window" "$WORK/victim.log" | head -n1)
LEASE=$(echo "$TILE" | grep -Eo "lease=[^:]+" | cut -d= -f2)
TILE=$(echo "$TILE" | grep -Eo "tile=[0-9]+")
[ -n "$LEASE" ] || fail "no lease in the victim's log"

start_worker survivor --threads 2
SURVIVOR=$WORKER_PID
wait "$SUBMIT_PID" || fail "submit exited with $?"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs after a worker was killed"
log_has "$WORK/serve.log" "${TILE/=/ } worker [^ ]+: lease $LEASE expired" || fail "the victim's lease $LEASE ($TILE) did not expire"
log_has "$WORK/survivor.log" "$TILE lease=.*upload accepted" || fail "the survivor did not render the victim's $TILE"

kill -TERM "$SURVIVOR"
wait "$SURVIVOR" || fail "the surviving worker exited with $? on SIGTERM"
log_has "$WORK/survivor.log" "stopping: [0-9]+ tiles uploaded" || fail "no exit summary"
echo "PASS"
