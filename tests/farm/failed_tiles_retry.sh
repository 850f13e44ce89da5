#!/usr/bin/env bash
# The retry proof: a fail point (worker.render.fail_tiles) makes tiles 5 and 6 fail on every worker, so the job fails
# part-way; the tiles endpoint shows each failure with the log lines its worker sent. The coordinator and the workers
# are restarted without the fail point, `tessera jobs retry` queues the job again, and the tiles endpoint and the
# workers' logs show that only the tiles that were not done were leased again. The result equals a single-process
# render bitwise.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 16 4  # 8 tiles of 8x8
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q --seed 3
start_serve --worker-failure-limit 2 --tile-failure-workers 2
ADDRESS=$(head -n1 "$WORK/ready")
# Both workers register before the job exists: were one alone when it failed tiles 5 and 6, it would be blocklisted
# with no other worker present and the job would fail before the second worker ever leased a tile.
# One thread each: the count of tiles done before the failure (below) relies on a worker rendering one tile at a
# time, which a second thread (its next tile's render begun ahead of the lease round trip) would not hold to.
for w in a b; do FAIL_POINTS='worker.render.fail_tiles=return(5,6)' start_worker "$w" --threads 1; done
for w in a b; do wait_for log_has "$WORK/$w.log" "registered as" || fail "worker $w did not register"; done
JOB=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 --seed 3 --detach 2>"$WORK/submit.log") \
  || fail "submit failed"
job_state() { "$TESSERA" jobs show "$JOB" --coordinator "$URL" 2>/dev/null | grep -q "\"state\": \"$1\""; }
wait_for job_state failed || fail "the job did not fail"
for w in a b; do wait_for log_has "$WORK/$w.log" "failure reported" || fail "worker $w reported no failure"; done
kill -TERM "${PIDS[@]:1}" 2>/dev/null || true
for p in "${PIDS[@]:1}"; do wait_for bash -c "! kill -0 $p 2>/dev/null" || fail "worker $p did not stop"; done

"$TESSERA" jobs tiles "$JOB" --coordinator "$URL" >"$WORK/tiles-failed.txt" 2>&1 || fail "jobs tiles failed"
log_has "$WORK/tiles-failed.txt" "^tile [56] failed on w-[^ ]+ \\([ab]\\): fail point worker.render.fail_tiles" \
  || fail "the tile table does not show the failures"
log_has "$WORK/tiles-failed.txt" "^  \\| .*cannot render the tile: fail point worker.render.fail_tiles" \
  || fail "the tile table does not show the log lines the worker sent"
DONE_BEFORE=$(grep -cE '^ +[0-9]+ done ' "$WORK/tiles-failed.txt" || true)
[ "$DONE_BEFORE" -le 6 ] || fail "$DONE_BEFORE tiles done before the failure"
# Tiles are leased in index order, so tiles 0-4 were leased before either worker could fail 5 or 6, and each worker
# renders one tile at a time: both had rendered all theirs before the job failed. Each may still have had its last
# upload in flight (one at most), so at least 3 are done whatever the machine's speed, and the check of their kept
# attempts below always has tiles to check.
[ "$DONE_BEFORE" -ge 3 ] || fail "only $DONE_BEFORE tiles done before the failure: nothing for the kept-attempts check"
# Each done tile's index and attempts (counted from the end: the worker column is "id (name)", two words).
grep -E '^ +[0-9]+ done ' "$WORK/tiles-failed.txt" | awk '{print $1, $(NF - 3)}' >"$WORK/done-before.txt"

# Restart the coordinator on the same data and port, without fail points anywhere.
kill -TERM "$SERVE_PID"
wait_for bash -c "! kill -0 $SERVE_PID 2>/dev/null" || fail "the coordinator did not stop"
LISTEN=$ADDRESS start_serve
"$TESSERA" jobs retry "$JOB" --coordinator "$URL" >"$WORK/retry.log" 2>&1 || fail "jobs retry failed"
MISSING=$((8 - DONE_BEFORE))
log_has "$WORK/retry.log" "^$JOB: running again, $MISSING of 8 tiles to render" || fail "retry: $(cat "$WORK/retry.log")"
start_worker c --threads 2
wait_for job_state done || fail "the retried job did not finish"
LEASED=$(grep -c "leased window" "$WORK/c.log")
[ "$LEASED" = "$MISSING" ] || fail "the worker leased $LEASED tiles after the retry, not the $MISSING missing ones"
"$TESSERA" jobs tiles "$JOB" --coordinator "$URL" >"$WORK/tiles-done.txt" 2>&1 || fail "jobs tiles failed"
# The tiles done before the failure kept their attempt counts (not leased again); every tile is done.
while read -r idx attempts; do
  log_has "$WORK/tiles-done.txt" "^ +$idx done .* $attempts +[0-9.]+ +[0-9]+ +0$" \
    || fail "tile $idx, done before the failure, was leased again: $(grep -E "^ +$idx " "$WORK/tiles-done.txt")"
done <"$WORK/done-before.txt"
[ "$(grep -cE '^ +[0-9]+ done ' "$WORK/tiles-done.txt")" = 8 ] || fail "not every tile is done"
curl -sS -f -o "$WORK/out.exr" "$URL/v1/jobs/$JOB/result.exr" || fail "no result"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the retried job's result differs from a single-process render"
echo "PASS (done before the failure: $DONE_BEFORE, leased after the retry: $LEASED)"
