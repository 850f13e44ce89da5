#!/usr/bin/env bash
# tessera submit follows its job on GET /v1/events instead of polling: the coordinator's metrics count one event
# stream and only a few GET /v1/jobs/{id} for a job of 12 tiles. With --max-event-streams 0 the stream is refused
# (503) and submit falls back to polling: the job still completes with the same result.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/scene.json" 48 32 2
"$TESSERA" render "$WORK/scene.json" -o "$WORK/ref.exr" -q --seed 5
start_serve
start_worker w1 --threads 1
"$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --tile 12 --seed 5 -o "$WORK/out.exr" >"$WORK/submit1.log" 2>&1 ||
  fail "submit failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"
curl -sf "$URL/metrics" >"$WORK/metrics1.txt" || fail "no metrics"
grep -q 'tessera_http_request_duration_seconds_count{route="GET /v1/events"} 1$' "$WORK/metrics1.txt" ||
  fail "submit did not open one event stream: $(grep 'v1/events' "$WORK/metrics1.txt")"
polls=$(sed -n 's/^tessera_http_request_duration_seconds_count{route="GET \/v1\/jobs\/{id}"} \([0-9]*\)$/\1/p' "$WORK/metrics1.txt")
[ "${polls:-0}" -le 3 ] || fail "submit polled the job $polls times while following events"
log_has "$WORK/submit1.log" "polling" && fail "submit fell back to polling with events available"
kill -TERM "$SERVE_PID"
wait "$SERVE_PID" || true

start_serve --max-event-streams 0  # on a new port: the first worker cannot follow, a second one renders
start_worker w2 --threads 1
"$TESSERA" submit "$WORK/scene.json" --coordinator "$URL" --tile 12 --seed 5 -o "$WORK/out2.exr" >"$WORK/submit2.log" 2>&1 ||
  fail "submit without event streams failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out2.exr" || fail "result without event streams differs"
log_has "$WORK/submit2.log" "no event stream \(503" || fail "submit did not say it polls: $(cat "$WORK/submit2.log")"
echo "PASS"
