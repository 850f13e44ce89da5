#!/usr/bin/env bash
# A worker asks for its next lease near the end of each render (the round trip overlaps the render), so it can hold a
# lease it has not started. That lease is not lost, whatever happens to the worker:
#   CASE   what happens while the worker holds a prefetched lease           the prefetched tile
#   kill   SIGKILL                                                          expires; another worker renders it
#   drain  an operator drains the worker                                    the drained worker renders it (it holds it)
#   stop   SIGTERM (finish the tile in hand, then exit)                     handed back at once; another worker renders it
# The state is made certain, not timed: the worker's first upload is held (fail point worker.upload), so it renders
# tile 1 (leased while tile 0 rendered), asks for tile 2 near the end of that render, and then waits for the upload
# with tiles 1 and 2 in hand. With two threads (drain, stop) the worker also begins rendering a tile as soon as its
# lease arrives, so tile 2's render has begun: drained, that render is the one uploaded; stopped, it is cancelled and
# the tile handed back. Each job ends bitwise identical to the single-process render, every tile acknowledged.
# Usage: prefetch.sh TESSERA EXR_COMPARE COURSE_DIR TESSERA_FP CASE
source "$(dirname "$0")/common.sh"
CASE=${5:?prefetch.sh needs a CASE}
case $CASE in kill | drain | stop) ;; *) fail "unknown case $CASE" ;; esac

write_sphere_scene "$WORK/s.json" 32 32 16  # 4 tiles of 16x16
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --threads 1
# Short leases only where an expiry is the way back; elsewhere a lost lease would stall the test until its budget.
if [ "$CASE" = kill ]; then start_serve --lease-seconds 2 --heartbeat-seconds 1; else start_serve --heartbeat-seconds 1; fi
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 16 -o "$WORK/out.exr" -q

THREADS=2
[ "$CASE" != kill ] || THREADS=1
FAIL_POINTS="worker.upload=pause($WORK/go)" start_worker victim --threads "$THREADS"
VICTIM=$WORKER_PID
wait_for paused "$WORK/victim.log" worker.upload || fail "the victim's first upload was not held"
second_prefetch() { [ "$(grep -c 'granted while rendering' "$WORK/victim.log")" -ge 2 ]; }
wait_for second_prefetch || fail "the victim did not ask for a lease while rendering its second tile"
log_has "$WORK/victim.log" "tile=1 lease=[^:]+: rendered in" || fail "the victim's second tile was not tile 1"
LINE=$(grep 'granted while rendering' "$WORK/victim.log" | sed -n 2p)
LEASE=$(echo "$LINE" | grep -Eo "next lease [^ ]+" | cut -d' ' -f3)
TILE=$(echo "$LINE" | grep -Eo "\(tile [0-9]+" | cut -d' ' -f2)
[ "$TILE" = 2 ] || fail "the prefetched tile is $TILE, not 2"
log_has "$WORK/victim.log" "tile=2 lease=$LEASE: leased" && fail "the victim took up the prefetched tile while its upload was held"
if [ "$THREADS" = 2 ]; then
  echo "$LINE" | grep -q "its render begun" || fail "the two-thread victim did not begin the prefetched tile's render"
fi

case $CASE in
  kill)
    kill -KILL "$VICTIM"
    wait "$VICTIM" 2>/dev/null || true
    start_worker survivor --threads 1
    SURVIVOR=$WORKER_PID
    wait "$SUBMIT_PID" || fail "submit exited with $?"
    log_has "$WORK/serve.log" "tile 2 worker [^ ]+: lease $LEASE expired" || fail "the prefetched lease $LEASE did not expire"
    log_has "$WORK/survivor.log" "tile=2 lease=.*upload accepted" || fail "the survivor did not render the prefetched tile"
    ;;
  drain)
    WID=$(grep -Eo "registered as [^ ]+" "$WORK/victim.log" | head -n1 | cut -d' ' -f3)
    "$TESSERA" workers drain "$WID" --coordinator "$URL" >"$WORK/drain.log" 2>&1 || fail "drain failed"
    release go
    wait_for log_has "$WORK/victim.log" "tile=2 lease=$LEASE: upload accepted" ||
      fail "the drained worker did not render and upload the tile it held"
    log_has "$WORK/victim.log" "tile=2 lease=$LEASE: rendered in .*begun ahead" || fail "tile 2 was not the render begun ahead"
    start_worker survivor --threads 1
    SURVIVOR=$WORKER_PID
    wait "$SUBMIT_PID" || fail "submit exited with $?"
    log_has "$WORK/victim.log" "tile=3 " && fail "the drained worker took a new tile"
    log_has "$WORK/survivor.log" "tile=3 lease=.*upload accepted" || fail "the survivor did not render tile 3"
    ! log_has "$WORK/serve.log" "expired" || fail "a lease expired"
    ;;
  stop)
    kill -TERM "$VICTIM"
    release go
    wait "$VICTIM" || fail "the victim exited with $? on SIGTERM"
    log_has "$WORK/victim.log" "tile=2 lease=$LEASE: tile handed back" || fail "the prefetched tile was not handed back"
    log_has "$WORK/victim.log" "tile=1 lease=.*upload accepted" || fail "the tile in hand was not finished and uploaded"
    start_worker survivor --threads 1
    SURVIVOR=$WORKER_PID
    wait "$SUBMIT_PID" || fail "submit exited with $?"
    log_has "$WORK/survivor.log" "tile=2 lease=.*upload accepted" || fail "the survivor did not render the handed-back tile"
    ! log_has "$WORK/serve.log" "expired" || fail "a lease expired"
    ;;
esac
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the result differs from the single-process render"
for t in 0 1 2 3; do
  acks=$(cat "$WORK"/victim.log "$WORK"/survivor.log | grep -Ec "tile=$t lease=.*: upload (accepted|duplicate)" || true)
  [ "$acks" -ge 1 ] || fail "tile $t was never acknowledged"
done
kill -TERM "$SURVIVOR"
wait "$SURVIVOR" || fail "the surviving worker exited with $? on SIGTERM"
echo "PASS"
