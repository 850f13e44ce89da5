#!/usr/bin/env bash
# Worker shutdown: one SIGTERM in the middle of a tile finishes and uploads it, then exits 0; two SIGTERMs cancel the
# render, hand the tile back through /release and exit 0; a worker started while the coordinator is down keeps
# retrying and, once a coordinator listens on that address, registers and renders. The job ends identical.
# "In the middle of a tile" by construction: the tiles are held at fail point worker.render until the test has seen
# the worker take each signal (its log), released by a file for one SIGTERM and by the cancel itself for two.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 64 32 16
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q

# A coordinator that is not there yet: find a free port by starting and stopping one.
start_serve
PORT=${URL##*:}
kill -TERM "$SERVE_PID"
wait "$SERVE_PID" || fail "the coordinator did not exit 0 on SIGTERM"
start_worker patient --threads 2
PATIENT=$WORKER_PID
wait_for log_has "$WORK/patient.log" "coordinator unreachable" || fail "the worker did not notice the missing coordinator"
kill -STOP "$PATIENT"   # keep it out of the shutdown checks below until they are done
settled() { [ "$(process_state "$PATIENT")" != R ] && [ "$(process_state "$PATIENT")" != S ]; }
wait_for settled
is_stopped "$PATIENT" || fail "the worker exited while the coordinator was down (state $(process_state "$PATIENT"))"

LISTEN=127.0.0.1:$PORT start_serve --lease-seconds 30 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 32 -o "$WORK/out.exr" -q

FAIL_POINTS="worker.render=pause($WORK/go-once)" start_worker once --threads 2
ONCE=$WORKER_PID
wait_for paused "$WORK/once.log" || fail "worker 'once' did not hold a tile"
log_has "$WORK/once.log" "tile=0 .*leased window" || fail "worker 'once' holds another tile than 0"
kill -TERM "$ONCE"
wait_for log_has "$WORK/once.log" "tile=0 .*asked to stop, finishing this tile first" || fail "'once' did not take the SIGTERM"
release go-once
wait "$ONCE" || fail "worker 'once' exited with $? after one SIGTERM"
log_has "$WORK/once.log" "tile=0 .*upload accepted" || fail "one SIGTERM did not let the tile finish and upload"

FAIL_POINTS="worker.render=pause" start_worker twice --threads 2
TWICE=$WORKER_PID
wait_for paused "$WORK/twice.log" || fail "worker 'twice' did not hold a tile"
log_has "$WORK/twice.log" "tile=1 .*leased window" || fail "worker 'twice' holds another tile than 1"
kill -TERM "$TWICE"
wait_for log_has "$WORK/twice.log" "tile=1 .*asked to stop, finishing" || fail "'twice' did not take the first SIGTERM"
kill -TERM "$TWICE"
wait "$TWICE" || fail "worker 'twice' exited with $? after two SIGTERMs"
log_has "$WORK/twice.log" "tile=1 .*asked to stop again, cancelling" || fail "the second SIGTERM did not cancel"
log_has "$WORK/twice.log" "tile=1 .*tile handed back" || fail "two SIGTERMs did not hand the tile back"
log_has "$WORK/twice.log" "tile=1 .*rendered in" && fail "the handed-back tile was rendered to the end"

# With a 30 s lease, only the release makes tile 1 available again this soon.
kill -CONT "$PATIENT"
wait "$SUBMIT_PID" || fail "submit exited with $?"
log_has "$WORK/patient.log" "reachable again" || fail "the patient worker did not report the coordinator back"
log_has "$WORK/patient.log" "tile=1 .*upload accepted" || fail "the patient worker did not render the released tile"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"
echo "PASS"
