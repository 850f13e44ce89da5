#!/usr/bin/env bash
# The coordinator goes away (SIGKILL) while workers wait for work and comes back later on the same data folder and
# port: the idle workers keep retrying, pick up the job submitted after the restart, and it completes bitwise
# identical to a single-process render; they keep the ids they registered with before.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 32 24 16
"$TESSERA" render "$WORK/s.json" -o "$WORK/ref.exr" -q
start_serve --lease-seconds 5 --heartbeat-seconds 1
ADDRESS=$(head -n1 "$WORK/ready")
start_worker w1 --threads 1
start_worker w2 --threads 1
both_registered() { log_has "$WORK/w1.log" "registered as" && log_has "$WORK/w2.log" "registered as"; }
wait_for both_registered || fail "the workers did not register"

kill -KILL "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
both_notice() { log_has "$WORK/w1.log" "unreachable" && log_has "$WORK/w2.log" "unreachable"; }
wait_for both_notice || fail "the idle workers did not notice the coordinator was gone"

LISTEN=$ADDRESS start_serve --lease-seconds 5 --heartbeat-seconds 1
"$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 8 -o "$WORK/out.exr" -q >"$WORK/submit.log" 2>&1 ||
  fail "submit after the restart failed"
"$EXR_COMPARE" "$WORK/ref.exr" "$WORK/out.exr" || fail "result differs"
for w in w1 w2; do
  [ "$(grep -c "registered as" "$WORK/$w.log")" = 1 ] || fail "$w registered again instead of keeping its id"
done
log_has "$WORK/w1.log" "upload accepted" || log_has "$WORK/w2.log" "upload accepted" || fail "no worker rendered"
echo "PASS"
