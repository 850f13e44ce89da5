#!/usr/bin/env bash
# Partition: worker "late" (host w1) holds a lease when its link is cut. Its lease expires, worker "prompt" (w2)
# renders the tile and the job completes bitwise identical; when the link returns, late's upload of the tile (retried
# all along) is answered as a duplicate, and late then renders a second job by itself without a restart.
# Mid-tile is made certain, not timed: late freezes itself (SIGSTOP, tests/lib/freeze.sh) after rendering and
# before uploading, the link is cut while it is frozen, and only then is it continued.
source "$(dirname "$0")/../farm/common.sh"
source "$(dirname "$0")/common.sh"
start_short_lease_farm w3
start_frozen_worker w1 late
cut w1
kill -CONT "$FROZEN_PID"
wait_for log_has "$WORK/late.log" "$FROZEN_TILE lease=.*upload attempt 1 failed" || fail "late's upload did not fail while cut off"
wait_for log_has "$WORK/serve.log" "lease\(s\) expired" || fail "late's lease did not expire"

worker_on w2 prompt "$URL" "${WORKER[@]}"
PROMPT=$WORKER_PID
wait "$SUBMIT_PID" || fail "submit exited with $? while late was cut off"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the job differs from the single-process render"
log_has "$WORK/prompt.log" "$FROZEN_TILE lease=.*upload accepted" || fail "the cut-off worker's $FROZEN_TILE was not rendered by prompt"
log_has "$WORK/late.log" "upload (accepted|duplicate)" && fail "late reached the coordinator while cut off"

reconnect w1
wait_for log_has "$WORK/late.log" "$FROZEN_TILE lease=.*upload duplicate" || fail "late's upload after the partition was not a duplicate"
[ "$(count "$WORK/late.log" "upload accepted")" = 0 ] || fail "late's stale tile was accepted"
merged_once 6

# Late carries on by itself: prompt stops, a second job is rendered by late alone.
kill -TERM "$PROMPT"
wait "$PROMPT" || fail "prompt exited with $?"
expect_exit 0 "$WORK/submit2.log" -- on w3 "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" "${SUBMIT[@]}" \
  -o "$WORK/out2.exr"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out2.exr" || fail "the second job differs"
[ "$(count "$WORK/late.log" "upload accepted")" = 6 ] || fail "late did not render the second job's 6 tiles"
kill -0 "$FROZEN_PID" || fail "late exited"
echo "PASS"
