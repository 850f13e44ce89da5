#!/usr/bin/env bash
# A worker asked to stop (one SIGTERM) while its coordinator is gone gives up the upload it cannot deliver and exits
# 0 by itself, without a second signal: after --stop-timeout, logging "giving up the upload of tile N of job J". The
# coordinator is frozen (SIGSTOP: connections are accepted, nothing is answered) or killed (connections are refused),
# per the argument. The upload is pending by construction: it is held at fail point worker.upload until the
# coordinator is gone and the SIGTERM sent.
source "$(dirname "$0")/common.sh"
CASE=${5:?usage: stop_timeout.sh TESSERA EXR_COMPARE SHARED TESSERA_FP stopped|killed}

write_sphere_scene "$WORK/s.json" 16 16 4
start_serve --lease-seconds 30 --heartbeat-seconds 1
JOB=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 16 --detach 2>"$WORK/submit.log") || fail "submit failed"
FAIL_POINTS="worker.upload=pause($WORK/go)" start_worker w --threads 2 --stop-timeout 2
W=$WORKER_PID
wait_for paused "$WORK/w.log" worker.upload || fail "the worker did not hold its upload"
case $CASE in
  stopped) kill -STOP "$SERVE_PID"; wait_for is_stopped "$SERVE_PID" || fail "the coordinator did not stop" ;;
  killed) kill -KILL "$SERVE_PID"; wait "$SERVE_PID" 2>/dev/null || true ;;
  *) fail "unknown case $CASE" ;;
esac
kill -TERM "$W"
release go
rc=0
wait "$W" || rc=$?
[ "$rc" = 0 ] || fail "the worker exited $rc after one SIGTERM, not 0"
log_has "$WORK/w.log" "tile=0 .*giving up the upload of tile 0 of job $JOB: stopping, and (the coordinator has not taken it within --stop-timeout \(2.0 s\)|its lease ran out)" \
  || fail "the worker did not say it gave up the upload"
log_has "$WORK/w.log" "tile=0 .*upload (accepted|acknowledged)" && fail "the upload was acknowledged by a coordinator that was gone"
log_has "$WORK/w.log" "asked to stop again" && fail "the worker needed a second signal"
log_has "$WORK/w.log" "stopping: 0 tiles uploaded, 1 dropped" || fail "the exit summary does not count the tile dropped"
echo "PASS"
