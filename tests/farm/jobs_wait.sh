#!/usr/bin/env bash
# Waiting for a job from another command, and stopping a wait without stopping the job: Ctrl-C (SIGINT) to `submit`
# and SIGTERM to `jobs wait` end the wait with exit status 130 and a sentence naming the job and how to fetch it,
# while the job keeps running; `jobs wait ID -o FILE` then saves the result, bitwise the single-process render, and
# again at once once the job is done. An unknown id, an output that cannot be written, and -o with another action
# exit 2 before any wait; a cancelled job exits 1. The job is held at its second tile (fail point worker.render)
# until every interrupted wait has been checked, so the waits always meet a running job, whatever the machine's speed.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 24 2
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
start_serve
FAIL_POINTS="worker.render=1*off->pause($WORK/go)" start_worker w --threads 2

job_state() { curl -sS -f "$URL/v1/jobs/$1" | python3 -c 'import json, sys; print(json.load(sys.stdin)["state"])'; }

# submit -o, interrupted once it waits (its progress bar has started): 130, the job left running.
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 8 -o "$WORK/submit.exr"
wait_for log_has "$WORK/submit.log" "[0-9]+/12 tiles" || fail "submit shows no progress"
JOB=$(grep -Eo "as j-[^ ]+" "$WORK/submit.log" | head -n1 | cut -c4-)
[ -n "$JOB" ] || fail "no job id in submit's output"
wait_for paused "$WORK/w.log" || fail "the second tile was not held"
kill -INT "$SUBMIT_PID"
rc=0
wait "$SUBMIT_PID" || rc=$?
[ "$rc" = 130 ] || fail "submit interrupted while waiting exited $rc, not 130"
log_has "$WORK/submit.log" "stopped waiting: $JOB is still running on the coordinator \(tessera jobs wait $JOB -o FILE" ||
  fail "submit did not say the job goes on"
[ ! -e "$WORK/submit.exr" ] || fail "an interrupted submit wrote its output"
[ "$(job_state "$JOB")" = running ] || fail "the job is $(job_state "$JOB") after submit's interrupt, not running"

# jobs wait, stopped by SIGTERM once it waits: 130, the job still running.
"$TESSERA" jobs wait "$JOB" --coordinator "$URL" >"$WORK/wait1.log" 2>&1 &
WAIT1=$!
PIDS+=("$WAIT1")
wait_for log_has "$WORK/wait1.log" "[0-9]+/12 tiles" || fail "jobs wait shows no progress"
kill -TERM "$WAIT1"
rc=0
wait "$WAIT1" || rc=$?
[ "$rc" = 130 ] || fail "jobs wait stopped by SIGTERM exited $rc, not 130"
log_has "$WORK/wait1.log" "stopped waiting: $JOB is still running" || fail "jobs wait did not say the job goes on"
[ "$(job_state "$JOB")" = running ] || fail "the job is $(job_state "$JOB") after a stopped wait, not running"

# Refused before any wait: an unknown id, an output folder that does not exist, -o with another action.
expect_exit 2 "$WORK/unknown.log" -- "$TESSERA" jobs wait j-no-such-job --coordinator "$URL" -o "$WORK/x.exr"
log_has "$WORK/unknown.log" "no job j-no-such-job" || fail "the unknown id is not named"
expect_exit 2 "$WORK/folder.log" -- "$TESSERA" jobs wait "$JOB" --coordinator "$URL" -o "$WORK/missing/x.exr"
log_has "$WORK/folder.log" "does not exist" || fail "the missing folder is not named"
expect_exit 2 "$WORK/ls-o.log" -- "$TESSERA" jobs ls --coordinator "$URL" -o "$WORK/x.exr"
log_has "$WORK/ls-o.log" "-o goes with jobs wait" || fail "-o with ls is not refused"
[ ! -e "$WORK/x.exr" ] || fail "a refused wait wrote a file"

# jobs wait -o through the end: the result, bitwise the single-process render; again at once once done.
"$TESSERA" jobs wait "$JOB" --coordinator "$URL" -o "$WORK/out.exr" >"$WORK/wait2.log" 2>&1 &
WAIT2=$!
PIDS+=("$WAIT2")
wait_for log_has "$WORK/wait2.log" "[0-9]+/12 tiles" || fail "the second jobs wait shows no progress"
[ ! -e "$WORK/out.exr" ] || fail "jobs wait wrote the output before the job was done"
release go
wait "$WAIT2" || fail "jobs wait -o failed: $(tail -n 3 "$WORK/wait2.log")"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the waited-for result differs from the single-process render"
expect_exit 0 "$WORK/wait3.log" -- "$TESSERA" jobs wait "$JOB" --coordinator "$URL" -o "$WORK/again.exr" -q
cmp -s "$WORK/out.exr" "$WORK/again.exr" || fail "the done job's result fetched again differs"

# A cancelled job: exit 1, said. With the worker stopped, the job stays queued until the cancel.
stop_pids 50 "$WORKER_PID"
CANCELLED=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --detach)
"$TESSERA" jobs cancel "$CANCELLED" --coordinator "$URL" >"$WORK/cancel.log" 2>&1 || fail "jobs cancel failed"
expect_exit 1 "$WORK/wait-cancelled.log" -- "$TESSERA" jobs wait "$CANCELLED" --coordinator "$URL" -o "$WORK/c.exr"
log_has "$WORK/wait-cancelled.log" "was cancelled" || fail "jobs wait did not say the job was cancelled"
[ ! -e "$WORK/c.exr" ] || fail "an output was written for a cancelled job"
echo "PASS"
