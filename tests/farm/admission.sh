#!/usr/bin/env bash
# Scene validation at submission runs on its own admission pool (serve --max-validations, --validation-queue), never
# on a request handler thread. With a single handler thread (--threads 1) and one submission held inside its
# validation (fail point submit.validate, paused until a file exists) and a third one waiting for its turn, the
# coordinator still registers a worker, leases it a tile of another job, answers its heartbeat and lists the jobs; a
# fourth submission, beyond the bound (1 validation, 1 waiting), gets 503 with Retry-After at once. Released, the held
# and the waiting submissions are queued, and all three jobs render bitwise identical to a single-process render.
# Nothing here waits on a clock: the held validation stays held until the test releases it.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 16 16 2
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
python3 -c "import json,sys; print(json.dumps({'scene': json.load(open(sys.argv[1])), 'assets': {}}))" "$WORK/s.json" \
  >"$WORK/job.json"
FAIL_POINTS="submit.validate=1*off->1*pause($WORK/go)->off" start_serve --threads 1 --max-validations 1 \
  --validation-queue 1
JOB_A=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --detach 2>"$WORK/submit-a.log") \
  || fail "the first submission failed"

"$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --detach >"$WORK/b.id" 2>"$WORK/submit-b.log" &
SUBMIT_B=$!
PIDS+=("$SUBMIT_B")
wait_for paused "$WORK/serve.log" submit.validate || fail "the second submission never reached its validation"
post_job() { curl -sS -o "$WORK/$1.json" -D "$WORK/$1.headers" -w '%{http_code}' -X POST \
  -H 'Content-Type: application/json' --data-binary @"$WORK/job.json" "$URL/v1/jobs"; }
post_job c >"$WORK/c.code" &
POST_C=$!
PIDS+=("$POST_C")
wait_for log_has "$WORK/serve.log" "waiting for a scene check \(1 submission\(s\) ahead\)" \
  || fail "the third submission did not wait for its turn"

# While it is held: a worker's whole conversation with the coordinator is answered (the request handler is free).
REG=$(curl -sS -f -X POST -d '{"name": "by-hand"}' "$URL/v1/workers")
WID=$(echo "$REG" | grep -Eo '"id":"[^"]+"' | cut -d'"' -f4)
[ -n "$WID" ] || fail "no worker registration while a validation was held"
AS_WORKER=(-H "X-Tessera-Worker-Secret: $(echo "$REG" | grep -Eo '"secret":"[^"]+"' | cut -d'"' -f4)")
LEASE_JSON=$(curl -sS -f -X POST "${AS_WORKER[@]}" "$URL/v1/workers/$WID/lease") || fail "no lease while a validation was held"
echo "$LEASE_JSON" | grep -q "\"job\":\"$JOB_A\"" || fail "the lease is not of the first job: $LEASE_JSON"
LEASE=$(echo "$LEASE_JSON" | grep -Eo '"lease":"[^"]+"' | cut -d'"' -f4)
curl -sS -f -X POST "${AS_WORKER[@]}" -d '{"rays": 1}' "$URL/v1/leases/$LEASE/heartbeat" | grep -q deadline_ms \
  || fail "no heartbeat answer while a validation was held"
curl -sS -f "$URL/v1/jobs" | grep -q "$JOB_A" || fail "no job list while a validation was held"

# A fourth submission is over the bound: 503 with Retry-After, answered at once (not queued behind the held one).
CODE=$(post_job d)
[ "$CODE" = 503 ] || fail "a submission beyond the admission bound got $CODE, not 503: $(cat "$WORK/d.json")"
grep -qi '^retry-after: 1' "$WORK/d.headers" || fail "the 503 has no Retry-After: $(cat "$WORK/d.headers")"
grep -q 'submissions are being checked or waiting' "$WORK/d.json" || fail "the 503 does not say why: $(cat "$WORK/d.json")"
log_has "$WORK/serve.log" "fail point submit.validate: hit 2: paused" || fail "the held submission was not the second"
[ -s "$WORK/c.code" ] && fail "the waiting submission was answered while the one ahead of it was held"
[ -e "$WORK/go" ] && fail "released too early"

release go
wait "$SUBMIT_B" || fail "the held submission failed once released: $(cat "$WORK/submit-b.log")"
JOB_B=$(cat "$WORK/b.id")
[ -n "$JOB_B" ] && [ "$JOB_B" != "$JOB_A" ] || fail "no second job id"
wait "$POST_C" || fail "the waiting submission's request failed"
[ "$(cat "$WORK/c.code")" = 201 ] || fail "the waiting submission got $(cat "$WORK/c.code"): $(cat "$WORK/c.json")"
JOB_C=$(grep -Eo '"id":"[^"]+"' "$WORK/c.json" | cut -d'"' -f4)
[ -n "$JOB_C" ] || fail "no third job id"

curl -sS -f -X POST "${AS_WORKER[@]}" "$URL/v1/leases/$LEASE/release" | grep -q released || fail "the hand-held lease was not released"
start_worker w --threads 1
job_done() { curl -sS -f "$URL/v1/jobs/$1" | grep -q '"state":"done"'; }
for job in "$JOB_A" "$JOB_B" "$JOB_C"; do
  wait_for job_done "$job" || fail "job $job did not finish"
  curl -sS -f -o "$WORK/$job.exr" "$URL/v1/jobs/$job/result.exr" || fail "no result for $job"
  "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/$job.exr" || fail "job $job differs from the single-process render"
done
echo "PASS"
