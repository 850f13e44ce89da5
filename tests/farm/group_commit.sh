#!/usr/bin/env bash
# Group commit: an upload's tile is committed at once, but its answer waits for a flush of the log that began after the
# commit; uploads that arrive while a flush runs share the next one. The flush of the first upload is held at the fail
# point store.sync (pause) while three workers' uploads arrive, so three tiles are committed and none is flushed:
# no worker has an answer, the job counts none of them as done (they show as merging), and the coordinator has not
# logged them merged. Then:
#   CASE     what happens                       then
#   release  the flush goes on                  the first tile is answered; the other two share the next flush
#   crash    SIGKILL of the coordinator         a restart finds the three tiles stored; their retries are answered
#                                               duplicate, and nothing acknowledged is lost
# The job ends bitwise identical to the single-process render, every tile acknowledged exactly once.
# Usage: group_commit.sh TESSERA EXR_COMPARE COURSE_DIR TESSERA_FP CASE
source "$(dirname "$0")/common.sh"
CASE=${5:?group_commit.sh needs a CASE}
case $CASE in release | crash) ;; *) fail "unknown case $CASE" ;; esac
TILES=12  # 32x24 in 8-pixel tiles

write_sphere_scene "$WORK/s.json" 32 24 4
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
# Flush 1 is the job's creation; flush 2, the first upload's, waits for $WORK/go.
FAIL_POINTS="store.sync=1*off->pause($WORK/go)" start_serve --lease-seconds 30 --heartbeat-seconds 1
ADDRESS=$(head -n1 "$WORK/ready")
start_submit "$WORK/submit.log" "$WORK/s.json" --tile 8 -o "$WORK/out.exr"
wait_for log_has "$WORK/submit.log" "submitted .* as j-" || fail "the job was not submitted"
JOB=$(grep -Eo "as j-[^ ]+" "$WORK/submit.log" | head -n1 | cut -d' ' -f2)
for w in a b c; do start_worker "$w" --threads 1; done

wait_for paused "$WORK/serve.log" store.sync || fail "the first upload's flush was not held"
merging() { [ "$("$TESSERA" jobs tiles "$JOB" --coordinator "$URL" 2>/dev/null | grep -cw merging)" -ge 3 ]; }
wait_for merging || fail "three uploads were not committed while the flush was held"
"$TESSERA" jobs show "$JOB" --coordinator "$URL" >"$WORK/show.json" || fail "jobs show failed"
python3 - "$WORK/show.json" <<'PY' || fail "the job counts unflushed tiles as done"
import json, sys
assert json.load(open(sys.argv[1]))["tiles"]["done"] == 0
PY
for w in a b c; do
  ! log_has "$WORK/$w.log" "upload (accepted|duplicate)" || fail "worker $w was answered before its tile was flushed"
done
! log_has "$WORK/serve.log" ": merged" || fail "a tile was logged merged before its flush"

if [ "$CASE" = crash ]; then
  kill -KILL "$SERVE_PID"
  wait "$SERVE_PID" 2>/dev/null || true
  mv "$WORK/serve.log" "$WORK/serve-1.log"
  # Restored leases get a fresh deadline: short here, so that a lease granted as the coordinator died, whose answer
  # never reached the worker, gives its tile back within seconds (heartbeats every second keep the others).
  LISTEN=$ADDRESS start_serve --lease-seconds 5 --heartbeat-seconds 1
  log_has "$WORK/serve.log" "resuming 0 queued and 1 running job" || fail "the restarted coordinator did not resume the job"
else
  release go
fi
wait "$SUBMIT_PID" || fail "submit exited with $?"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the result differs from the single-process render"

for t in $(seq 0 $((TILES - 1))); do
  acks=$(cat "$WORK"/[abc].log | grep -Ec "tile=$t lease=.*: upload (accepted|duplicate)" || true)
  merged=$(cat "$WORK"/serve*.log | grep -c "tile $t worker .*: merged" || true)
  [ "$acks" = 1 ] || fail "tile $t acknowledged $acks times"
  [ "$merged" -le 1 ] || fail "tile $t merged $merged times"
done
if [ "$CASE" = crash ]; then
  dups=$(cat "$WORK"/[abc].log | grep -c "upload duplicate" || true)
  [ "$dups" -ge 3 ] || fail "only $dups of the three held uploads were answered duplicate after the restart"
else
  # Without sharing, the job would take 1 + 12 + 1 flushes (creation, uploads, end): the two uploads that arrived
  # while the first one's flush was held shared one.
  flushes=$((1 + $(grep -c "fail point store.sync: hit" "$WORK/serve.log")))
  [ "$flushes" -le 13 ] || fail "$flushes flushes: the uploads that waited together did not share one"
fi
echo "PASS"
