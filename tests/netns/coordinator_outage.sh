#!/usr/bin/env bash
# The coordinator unreachable for longer than a lease (its link cut), then back: worker "held" (w1) holds a lease when
# the link goes down, worker "fresh" (w2) starts during the outage; both retry with backoff while cut off, the held
# lease expires, and after the link returns both reconnect by themselves: the job completes bitwise identical, every
# tile is merged exactly once (by the coordinator's log; a second upload of a tile is answered as a duplicate).
# The outage outlasts a lease by construction: the link comes back only after the coordinator has logged the held
# lease's expiry, which needs a whole lease without heartbeats.
source "$(dirname "$0")/../farm/common.sh"
source "$(dirname "$0")/common.sh"
# The client runs on the coordinator's own host, so it keeps its connection through the outage.
start_short_lease_farm c
start_frozen_worker w1 held
cut c
kill -CONT "$FROZEN_PID"
worker_on w2 fresh "$URL" "${WORKER[@]}"
wait_for log_has "$WORK/held.log" "upload attempt 1 failed" || fail "held's upload did not fail during the outage"
wait_for log_has "$WORK/fresh.log" "coordinator unreachable \(register\)" || fail "fresh did not notice the outage"
wait_for log_has "$WORK/serve.log" "lease\(s\) expired" || fail "the held lease did not expire during the outage"
log_has "$WORK/fresh.log" "registered as" && fail "fresh registered through a cut link"
reconnect c

wait "$SUBMIT_PID" || fail "submit exited with $? after the outage"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "the job differs from the single-process render"
wait_for log_has "$WORK/fresh.log" "registered as" || fail "fresh did not register after the outage"
log_has "$WORK/fresh.log" "coordinator reachable again" || fail "fresh did not log its reconnection"
wait_for log_has "$WORK/held.log" "upload (accepted|duplicate)" || fail "held's upload was not answered after the outage"
merged_once 6
kill -0 "$FROZEN_PID" || fail "held exited"
echo "PASS"
