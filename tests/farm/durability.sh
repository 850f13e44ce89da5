#!/usr/bin/env bash
# Durability at each step of an upload that matters, by fail points in the coordinator (tessera-failpoints):
#   CASE          fail point (4th upload: tile 3)  what happens                    tile 3 after the failure
#   commit_abort  store.tile_commit  abort          crash inside the commit        accepted (its commit was lost)
#   commit_error  store.tile_commit  error          the commit fails: 500          accepted on the retry (no restart)
#   sync_abort    store.sync         abort          crash after commit, before ack duplicate (its commit survived)
#   sync_fails    store.sync         return         fdatasync fails: the coordinator stops (abort), as designed
#   paste_abort   assembly.paste     abort          crash while merging            accepted
#   paste_error   assembly.paste     error          the merge fails: 500           accepted on the retry
#   write_abort   assembly.write_result abort       crash writing the result       (tile 11, the last: duplicate;
#                                                                                    the restart writes the result)
#   write_error   assembly.write_result error       the job fails and says why     (submit exits 1; no upload fails)
# One worker renders the 12 tiles in order; after a crash the coordinator starts again (release binary) on the same
# data folder and port. Every job that can finish does, bitwise identical to a single-process render, with every
# tile rendered once and acknowledged exactly once (nothing lost, nothing acknowledged twice; counted from the logs).
# Usage: durability.sh TESSERA EXR_COMPARE COURSE_DIR TESSERA_FP CASE
source "$(dirname "$0")/common.sh"
CASE=${5:?durability.sh needs a CASE}
# HIT: the tile whose upload the fail point hits; ANSWER: how that upload is answered in the end.
# The coordinator syncs once for the job's creation, then once per upload: the 4th upload is the 5th sync.
case $CASE in
  commit_abort) POINTS="store.tile_commit=3*off->abort" CRASH=1 HIT=3 ANSWER=accepted ;;
  commit_error) POINTS="store.tile_commit=3*off->1*error->off" CRASH=0 HIT=3 ANSWER=accepted ;;
  sync_abort) POINTS="store.sync=4*off->abort" CRASH=1 HIT=3 ANSWER=duplicate ;;
  sync_fails) POINTS="store.sync=4*off->return" CRASH=1 HIT=3 ANSWER=duplicate ;;
  paste_abort) POINTS="assembly.paste=3*off->abort" CRASH=1 HIT=3 ANSWER=accepted ;;
  paste_error) POINTS="assembly.paste=3*off->1*error->off" CRASH=0 HIT=3 ANSWER=accepted ;;
  write_abort) POINTS="assembly.write_result=abort" CRASH=1 HIT=11 ANSWER=duplicate ;;
  write_error) POINTS="assembly.write_result=error" CRASH=0 HIT= ANSWER= ;;
  *) fail "unknown case $CASE" ;;
esac
TILES=12  # 32x24 in 8-pixel tiles

write_sphere_scene "$WORK/s.json" 32 24 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
FAIL_POINTS=$POINTS start_serve --lease-seconds 30 --heartbeat-seconds 1
ADDRESS=$(head -n1 "$WORK/ready")
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 8 -o "$WORK/out.exr"
# The worker starts once submit has its answer: a crash before that would fail the submission, not an upload.
wait_for log_has "$WORK/submit.log" "submitted .* as j-" || fail "the job was not submitted"
start_worker w --threads 1

if [ "$CRASH" = 1 ]; then
  rc=0
  wait "$SERVE_PID" || rc=$?
  [ "$rc" = 134 ] || fail "the coordinator exited with $rc, not 134 (SIGABRT)"
  log_has "$WORK/serve.log" "fail point ${POINTS%%=*}: hit [0-9]+: (abort|return)" || fail "the fail point was not hit"
  [ "$CASE" != sync_fails ] || log_has "$WORK/serve.log" "cannot flush .* to disk \(Input/output error\); stopping" ||
    fail "a failed flush did not stop the coordinator with its reason"
  wait_for log_has "$WORK/w.log" "upload attempt 1 failed" || fail "the worker did not see its upload fail"
  mv "$WORK/serve.log" "$WORK/serve-1.log"
  # Restored leases get a fresh deadline: short here, so that a lease granted as the coordinator died, whose answer
  # never reached the worker, gives its tile back within seconds (heartbeats every second keep the others).
  LISTEN=$ADDRESS start_serve --lease-seconds 5 --heartbeat-seconds 1
  log_has "$WORK/serve.log" "resuming 0 queued and 1 running job" || fail "the restarted coordinator did not resume the job"
  [ "$CASE" != write_abort ] || log_has "$WORK/serve.log" "every tile was done before the restart; writing the result" ||
    fail "the restart did not write the result of a job whose tiles were all done"
fi

if [ "$CASE" = write_error ]; then
  expect_exit 1 "$WORK/submit-wait.log" -- wait "$SUBMIT_PID"
  log_has "$WORK/submit.log" "failed: writing the result failed: injected error at fail point assembly.write_result" ||
    fail "submit did not say why the job failed"
  [ ! -e "$WORK/out.exr" ] || fail "a failed job wrote an output"
else
  wait "$SUBMIT_PID" || fail "submit exited with $?"
  "$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the result differs from the single-process render"
fi

# In write_abort the restarted coordinator finishes the job by itself, so submit can return before the worker's retried
# upload of tile 11 is answered (its retry waits a back-off): that answer is waited for before anything is counted.
[ -z "$HIT" ] || wait_for log_has "$WORK/w.log" "tile=$HIT lease=.*: upload $ANSWER" ||
  fail "tile $HIT's upload was not answered '$ANSWER'"
# Every tile rendered once and acknowledged exactly once; merged at most once over both coordinator runs.
for t in $(seq 0 $((TILES - 1))); do
  rendered=$(grep -c "tile=$t lease=.*: rendered in" "$WORK/w.log" || true)
  acks=$(grep -Ec "tile=$t lease=.*: upload (accepted|duplicate)" "$WORK/w.log" || true)
  merged=$(cat "$WORK"/serve*.log | grep -c "tile $t worker .*: merged" || true)
  [ "$rendered" = 1 ] || fail "tile $t rendered $rendered times"
  [ "$acks" = 1 ] || fail "tile $t acknowledged $acks times"
  [ "$merged" -le 1 ] || fail "tile $t merged $merged times"
done
# The upload the fail point hit failed first and was answered as the case says; no other upload failed.
if [ -n "$HIT" ]; then
  log_has "$WORK/w.log" "tile=$HIT lease=.*: upload attempt 1 (failed|answered 500)" || fail "tile $HIT's upload did not fail first"
fi
for t in $(seq 0 $((TILES - 1))); do
  [ "$t" = "$HIT" ] || ! log_has "$WORK/w.log" "tile=$t lease=.*: upload attempt" || fail "tile $t's upload failed too"
done
echo "PASS"
