#!/usr/bin/env bash
# Purging jobs (DELETE /v1/jobs/{id}?purge=true, `tessera jobs rm ID --purge`):
# (a) three jobs of a course scene with assets are rendered; the data folder's bytes go up, and after purging them
#     (blob grace period 0) they go back down to within 64 KiB of the empty coordinator's; listings page and filter;
# (b) job A is purged while a worker holds an upload of job B (paused by a fail point before the upload): B finishes
#     and equals a single-process render bitwise;
# (c) job C is purged while a worker holds an upload of one of its tiles: purging it running is refused with a
#     sentence, after cancel it is purged, and the late upload is answered 404 (the worker drops the tile and goes on);
#     nothing of C is left and the coordinator logged no internal error.
source "$(dirname "$0")/common.sh"

bytes() { du -sb "$WORK/data" | cut -f1; }
state_of() { "$TESSERA" jobs show "$1" --coordinator "$URL" 2>/dev/null | grep -Eo '"state": "[a-z]+"' | cut -d'"' -f4; }
is_done() { [ "$(state_of "$1")" = done ]; }

write_cbox_scene "$WORK/cbox" 48 48 2
write_sphere_scene "$WORK/s.json" 32 16 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --seed 5
start_serve --blob-grace-minutes 0
EMPTY=$(bytes)

# (a) The data folder goes back down.
JOBS=()
for seed in 1 2 3; do
  JOBS+=("$("$TESSERA" submit "$WORK/cbox/scene.json" --coordinator "$URL" --tile 16 --seed "$seed" --detach \
    2>>"$WORK/submit.log")") || fail "submit failed"
done
start_worker w1 --threads 2
W1=$WORKER_PID
for j in "${JOBS[@]}"; do wait_for is_done "$j" || fail "job $j did not finish"; done
FULL=$(bytes)
"$TESSERA" jobs ls --coordinator "$URL" --state done --limit 2 >"$WORK/ls.log" 2>&1 || fail "jobs ls --limit failed"
[ "$(grep -c " done " "$WORK/ls.log")" = 2 ] || fail "jobs ls --state done --limit 2 did not list 2 jobs"
CURSOR=$(grep -Eo -- "--after [^ ]+" "$WORK/ls.log" | cut -d' ' -f2)
[ -n "$CURSOR" ] || fail "jobs ls --limit 2 printed no cursor for the third job"
"$TESSERA" jobs ls --coordinator "$URL" --after "$CURSOR" >"$WORK/ls2.log" 2>&1 || fail "jobs ls --after failed"
log_has "$WORK/ls2.log" "^${JOBS[0]} +done" || fail "the page after the cursor does not hold the oldest job"
for j in "${JOBS[@]}"; do
  "$TESSERA" jobs rm "$j" --purge --coordinator "$URL" >>"$WORK/rm.log" 2>&1 || fail "jobs rm --purge $j failed"
done
AFTER=$(bytes)
echo "data folder: empty coordinator $EMPTY bytes, 3 jobs rendered $FULL bytes, after purging them $AFTER bytes"
[ "$FULL" -gt $((EMPTY + 200000)) ] || fail "3 rendered jobs added only $((FULL - EMPTY)) bytes"
[ "$AFTER" -le $((EMPTY + 65536)) ] || fail "after purging, the data folder is $((AFTER - EMPTY)) bytes above empty"
[ -z "$(find "$WORK/data/blobs" -type f)" ] || fail "blobs of the purged jobs are left: $(find "$WORK/data/blobs" -type f)"
expect_exit 2 "$WORK/show-purged.log" -- "$TESSERA" jobs show "${JOBS[0]}" --coordinator "$URL"
log_has "$WORK/show-purged.log" "no job ${JOBS[0]}" || fail "a purged job is still known"
kill -TERM "$W1"
wait "$W1" || fail "worker w1 exited with $?"

# (b) Purge of job A while a worker holds an upload of job B.
A=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 5 --detach 2>>"$WORK/submit.log") || fail "submit A"
start_worker w2 --threads 1
W2=$WORKER_PID
wait_for is_done "$A" || fail "job A did not finish"
kill -TERM "$W2"
wait "$W2" || fail "worker w2 exited with $?"
FAIL_POINTS="worker.upload=1*pause($WORK/go-b)" start_worker held --threads 1
HELD=$WORKER_PID
B=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 5 --detach 2>>"$WORK/submit.log") || fail "submit B"
wait_for paused "$WORK/held.log" worker.upload || fail "the worker never held its upload of job B"
log_has "$WORK/held.log" "job=$B " || fail "the held upload is not of job B"
"$TESSERA" jobs rm "$A" --purge --coordinator "$URL" >"$WORK/rm-a.log" 2>&1 || fail "purging A during B's upload failed"
log_has "$WORK/rm-a.log" "^$A: purged \(was done\)" || fail "jobs rm --purge did not report A purged"
release go-b
wait_for is_done "$B" || fail "job B did not finish after A was purged"
curl -sS -f -o "$WORK/b.exr" "$URL/v1/jobs/$B/result.exr" || fail "no result for B"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/b.exr" || fail "B differs from a single-process render after A was purged"
[ ! -e "$WORK/data/jobs/$A" ] || fail "A's result folder is left"

# (c) Purge of job C during an upload of C itself.
kill -TERM "$HELD"
wait "$HELD" || fail "the held worker exited with $?"
C=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 5 --detach 2>>"$WORK/submit.log") \
  || fail "submit C"
FAIL_POINTS="worker.upload=1*pause($WORK/go-c)" start_worker late --threads 1
LATE=$WORKER_PID
wait_for paused "$WORK/late.log" worker.upload || fail "the worker never held its upload of job C"
TILE=$(grep -Eo "job=$C tile=[0-9]+ lease=[^:]+: rendered in" "$WORK/late.log" | head -n1 | grep -Eo "lease=[^:]+")
[ -n "$TILE" ] || fail "the held upload is not of job C"
expect_exit 2 "$WORK/rm-running.log" -- "$TESSERA" jobs rm "$C" --purge --coordinator "$URL"
log_has "$WORK/rm-running.log" "only done, failed or cancelled jobs can be purged" \
  || fail "purging a running job did not say why it was refused"
"$TESSERA" jobs cancel "$C" --coordinator "$URL" >"$WORK/cancel-c.log" 2>&1 || fail "cancel C failed"
"$TESSERA" jobs rm "$C" --purge --coordinator "$URL" >"$WORK/rm-c.log" 2>&1 || fail "purging C failed"
release go-c
wait_for log_has "$WORK/late.log" "$TILE: the coordinator does not know the lease any more; tile dropped" \
  || fail "the late upload of the purged job was not answered 404"
kill -0 "$LATE" || fail "the worker stopped after its upload was refused"
expect_exit 2 "$WORK/show-c.log" -- "$TESSERA" jobs show "$C" --coordinator "$URL"
[ ! -e "$WORK/data/jobs/$C" ] || fail "C's result folder is left"
curl -sS "$URL/v1/jobs" | grep -q "\"$C\"" && fail "the job list still names C"
log_has "$WORK/serve.log" "internal error" && fail "the coordinator logged an internal error"
kill -TERM "$LATE"
wait "$LATE" || fail "the late worker exited with $?"
echo "PASS"
