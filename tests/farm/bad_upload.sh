#!/usr/bin/env bash
# Result uploads the coordinator must refuse or settle: a tile with a NaN and a tile of the wrong size are answered
# 422, counted as a failure of that worker, rendered again and the job completes identical to a single-process render;
# an upload sent twice is acknowledged as a duplicate and merged once; a worker whose every upload is bad ends in a
# failed job whose recorded error says why.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 24 16 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
start_serve --lease-seconds 5 --heartbeat-seconds 1

# job_field JOB KEY: one field of GET /v1/jobs/JOB.
job_field() { curl -sS "$URL/v1/jobs/$1" | python3 -c "import json,sys; print(json.load(sys.stdin)['$2'])"; }

# A lone worker whose every upload carries a NaN: blocklisted after two failures, and as the only worker present it
# fails the job, with the reason recorded.
FAIL_POINTS="worker.upload.corrupt=return(nan)" start_worker bad --threads 1
BAD=$WORKER_PID
expect_exit 1 "$WORK/submit-bad.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 \
  -o "$WORK/never.exr" -q
JOB=$(curl -sS "$URL/v1/jobs" | python3 -c "import json,sys; print(json.load(sys.stdin)['jobs'][0]['id'])")
[ "$(job_field "$JOB" state)" = failed ] || fail "job $JOB is not failed"
job_field "$JOB" error | grep -q "is not finite" || fail "the failure reason does not name the bad pixel: $(job_field "$JOB" error)"
log_has "$WORK/bad.log" "refused the result as invalid" || fail "the worker did not see the 422"
[ -e "$WORK/never.exr" ] && fail "a failed job wrote an output file"
kill -TERM "$BAD"
wait "$BAD" || fail "the bad worker exited with $?"

# run_case NAME FAIL_POINTS: one worker with these fail points renders a fresh job, which must come out identical.
run_case() {
  local name=$1
  FAIL_POINTS=$2 start_worker "$name" --threads 1
  local pid=$WORKER_PID
  "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 -o "$WORK/$name.exr" -q >"$WORK/submit-$name.log" 2>&1 ||
    fail "$name: submit failed"
  "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/$name.exr" || fail "$name: result differs"
  kill -TERM "$pid"
  wait "$pid" || fail "$name: worker exited with $?"
}

run_case nan "worker.upload.corrupt=1*return(nan)"
log_has "$WORK/serve.log" "worker .*: invalid result: pixel \([0-9]+, [0-9]+\) is not finite" || fail "no NaN refusal logged"
log_has "$WORK/nan.log" "refused the result as invalid: invalid result: pixel" || fail "nan: the worker did not see the 422"

run_case size "worker.upload.corrupt=1*return(size)"
log_has "$WORK/serve.log" "invalid result: data window is \[[0-9, ]+\), expected the tile's" || fail "no size refusal logged"

run_case twice "worker.upload.repeat=1*return"
log_has "$WORK/twice.log" "upload accepted" || fail "twice: first upload not accepted"
log_has "$WORK/twice.log" "upload duplicate" || fail "twice: the repeated upload was not acknowledged as a duplicate"
[ "$(grep -c "duplicate result acknowledged" "$WORK/serve.log")" -ge 1 ] || fail "the coordinator logged no duplicate"
echo "PASS"
