#!/usr/bin/env bash
# Worker shutdown: one SIGTERM in the middle of a tile finishes and uploads it, then exits 0; two SIGTERMs cancel the
# render, hand the tile back through /release and exit 0; a worker started while the coordinator is down keeps
# retrying and, once a coordinator listens on that address, registers and renders. The job ends identical.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 64 32 1536
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q

# A coordinator that is not there yet: find a free port by starting and stopping one.
start_serve
PORT=${URL##*:}
kill -TERM "$SERVE_PID"
wait "$SERVE_PID" || fail "the coordinator did not exit 0 on SIGTERM"
start_worker patient --threads 1
PATIENT=$WORKER_PID
wait_for log_has "$WORK/patient.log" "coordinator unreachable" || fail "the worker did not notice the missing coordinator"
sleep 1
kill -0 "$PATIENT" || fail "the worker exited while the coordinator was down"
kill -STOP "$PATIENT"   # keep it out of the shutdown checks below until they are done

LISTEN=127.0.0.1:$PORT start_serve --lease-seconds 30 --heartbeat-seconds 1
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 32 -o "$WORK/out.exr" -q

start_worker once --threads 1
ONCE=$WORKER_PID
wait_for log_has "$WORK/once.log" "tile=0 .*leased window" || fail "worker 'once' leased nothing"
kill -TERM "$ONCE"
wait "$ONCE" || fail "worker 'once' exited with $? after one SIGTERM"
log_has "$WORK/once.log" "tile=0 .*upload accepted" || fail "one SIGTERM did not let the tile finish and upload"

start_worker twice --threads 1
TWICE=$WORKER_PID
wait_for log_has "$WORK/twice.log" "tile=1 .*leased window" || fail "worker 'twice' leased nothing"
kill -TERM "$TWICE"
sleep 0.2
kill -TERM "$TWICE"
wait "$TWICE" || fail "worker 'twice' exited with $? after two SIGTERMs"
log_has "$WORK/twice.log" "tile=1 .*tile handed back" || fail "two SIGTERMs did not hand the tile back"
log_has "$WORK/twice.log" "tile=1 .*rendered in" && fail "the handed-back tile was rendered to the end"

# With a 30 s lease, only the release makes tile 1 available again this soon.
kill -CONT "$PATIENT"
wait "$SUBMIT_PID" || fail "submit exited with $?"
log_has "$WORK/patient.log" "reachable again" || fail "the patient worker did not report the coordinator back"
log_has "$WORK/patient.log" "tile=1 .*upload accepted" || fail "the patient worker did not render the released tile"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"
echo "PASS"
