#!/usr/bin/env bash
# Retry keeps the done tiles (POST /v1/jobs/{id}/retry, `tessera jobs retry`): two tiles are rendered and uploaded by
# hand (`render --crop` writes exactly a tile's EXR), the job is cancelled and retried, and a real worker then leases
# only the tiles that were not done; the result equals a single-process render bitwise. Retrying a running job is
# refused with a sentence.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 16 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --seed 3
start_serve
JOB=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 3 --detach 2>"$WORK/submit.log") \
  || fail "submit failed"

# A worker by hand: register, lease two tiles, upload each as `render --crop` writes it.
REG=$(curl -sS -f -X POST -d '{"name": "by-hand"}' "$URL/v1/workers")
WID=$(echo "$REG" | grep -Eo '"id":"[^"]+"' | cut -d'"' -f4)
[ -n "$WID" ] || fail "no worker id"
AS_WORKER=(-H "X-Tessera-Worker-Secret: $(echo "$REG" | grep -Eo '"secret":"[^"]+"' | cut -d'"' -f4)")
for _ in 1 2; do
  LEASE_JSON=$(curl -sS -f -X POST "${AS_WORKER[@]}" "$URL/v1/workers/$WID/lease") || fail "no lease"
  LEASE=$(echo "$LEASE_JSON" | grep -Eo '"lease":"[^"]+"' | cut -d'"' -f4)
  read -r X0 Y0 X1 Y1 <<<"$(echo "$LEASE_JSON" | grep -Eo '"window":\[[0-9,]+\]' | grep -Eo '[0-9]+' | tr '\n' ' ')"
  "$TESSERA" render "$WORK/s.json" -o "$WORK/tile.exr" -q --seed 3 --crop "$X0" "$Y0" "$X1" "$Y1"
  curl -sS -f -X PUT "${AS_WORKER[@]}" --data-binary @"$WORK/tile.exr" -H 'Content-Type: image/x-exr' \
    "$URL/v1/leases/$LEASE/result" \
    | grep -q accepted || fail "the hand-rendered tile was not accepted"
done

expect_exit 2 "$WORK/retry-running.log" -- "$TESSERA" jobs retry "$JOB" --coordinator "$URL"
log_has "$WORK/retry-running.log" "is running: only failed or cancelled jobs can be retried" \
  || fail "retrying a running job did not say why it was refused"
"$TESSERA" jobs cancel "$JOB" --coordinator "$URL" >"$WORK/cancel.log" 2>&1 || fail "jobs cancel failed"
"$TESSERA" jobs ls --coordinator "$URL" >"$WORK/ls.log" 2>&1 || fail "jobs ls failed"
log_has "$WORK/ls.log" "$JOB +cancelled .* 2/8 " || fail "jobs ls does not show the cancelled job with 2/8 tiles"

"$TESSERA" jobs retry "$JOB" --coordinator "$URL" >"$WORK/retry.log" 2>&1 || fail "jobs retry failed"
log_has "$WORK/retry.log" "^$JOB: running again, 6 of 8 tiles to render" || fail "retry did not keep the 2 done tiles"

start_worker w --threads 1
job_done() { "$TESSERA" jobs show "$JOB" --coordinator "$URL" 2>/dev/null | grep -q '"state": "done"'; }
wait_for job_done || fail "the retried job did not finish"
[ "$(grep -c "leased window" "$WORK/w.log")" = 6 ] || fail "the worker leased $(grep -c "leased window" "$WORK/w.log") tiles, not the 6 missing ones"
curl -sS -f -o "$WORK/out.exr" "$URL/v1/jobs/$JOB/result.exr" || fail "no result"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the retried job's result differs from a single-process render"
# The listing gives the finished job's render time and its rays per second over it.
"$TESSERA" jobs ls --coordinator "$URL" >"$WORK/ls-done.log" 2>&1 || fail "jobs ls failed"
log_has "$WORK/ls-done.log" "^$JOB +done +local +-?[0-9]+ +8/8 +[0-9.]+s +[0-9]+\.[0-9] " \
  || fail "jobs ls does not show the done job's time and Mrays/s: $(cat "$WORK/ls-done.log")"
echo "PASS"
