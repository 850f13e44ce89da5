#!/usr/bin/env bash
# A chain of jobs through the binary: A -> B -> C (`submit --after`). B and C wait while A is queued; A fails (its
# only worker fails its tile twice, fail point worker.render, and is blocklisted) and B and C are blocked, each with
# the reason, in `jobs ls` and `jobs show`; a purge of A is refused while it holds them back; the coordinator is
# restarted and they are still blocked; `jobs retry A` puts them back to waiting, and the worker (now let through)
# renders A, then B, then C, each starting only after the one before it was done. An unknown id is refused at
# submission with a sentence.
source "$(dirname "$0")/common.sh"

write_sphere_scene "$WORK/s.json" 16 16 1
start_serve
ADDRESS=$(head -n1 "$WORK/ready")
submit() { "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 16 --detach "$@" 2>>"$WORK/submit.log"; }
A=$(submit --name A) || fail "submit A failed"
B=$(submit --name B --after "$A") || fail "submit B failed"
C=$(submit --name C --after "$B") || fail "submit C failed"
show() { "$TESSERA" jobs show "$1" --coordinator "$URL" 2>/dev/null; }
field() { show "$1" | python3 -c "import json, sys; print(json.load(sys.stdin).get('$2'))"; }
[ "$(field "$B" state)" = waiting ] || fail "B is $(field "$B" state), not waiting"
[ "$(field "$B" reason)" = "waiting for $A" ] || fail "B's reason: $(field "$B" reason)"
[ "$(field "$A" dependents)" = "['$B']" ] || fail "A's dependents: $(field "$A" dependents)"
"$TESSERA" jobs ls --coordinator "$URL" >"$WORK/ls.log" 2>&1 || fail "jobs ls failed"
log_has "$WORK/ls.log" "^$C +waiting " || fail "jobs ls does not show C waiting"
log_has "$WORK/ls.log" "after $B: waiting for $B" || fail "jobs ls does not say what C waits for"

expect_exit 2 "$WORK/unknown.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --after "$A,j-nope" --detach
log_has "$WORK/unknown.log" "cannot wait for j-nope: no such job on this coordinator" \
  || fail "an unknown dependency was not refused with a sentence"

FAIL_POINTS="worker.render=2*error->pause($WORK/go)" start_worker w --threads 1
a_failed() { [ "$(field "$A" state)" = failed ]; }
wait_for a_failed || fail "A did not fail"
[ "$(field "$B" state)" = blocked ] || fail "B is $(field "$B" state) after A failed"
log_has <(field "$B" reason) "^dependency $A failed: every registered worker .*injected error" \
  || fail "B's reason does not quote A's failure: $(field "$B" reason)"
log_has <(field "$C" reason) "^dependency $B is blocked: dependency $A failed" || fail "C's reason: $(field "$C" reason)"
"$TESSERA" jobs ls --coordinator "$URL" >"$WORK/ls-blocked.log" 2>&1 || fail "jobs ls failed"
log_has "$WORK/ls-blocked.log" "^$C +blocked " || fail "jobs ls does not show C blocked"

"$TESSERA" jobs rm "$A" --purge --coordinator "$URL" >"$WORK/purge.log" 2>&1 && fail "A was purged while it blocks B"
log_has "$WORK/purge.log" "job $A holds back $B" || fail "the purge's refusal does not name B"

# Blocked across a restart of the coordinator (same data folder and address: the worker carries on).
kill -TERM "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
LISTEN=$ADDRESS start_serve
[ "$(field "$C" state)" = blocked ] || fail "C is $(field "$C" state) after a restart, not blocked"
log_has <(field "$B" reason) "^dependency $A failed" \
  || fail "B's reason after the restart: $(field "$B" reason)"

"$TESSERA" jobs retry "$A" --coordinator "$URL" >"$WORK/retry.log" 2>&1 || fail "jobs retry A failed"
[ "$(field "$B" state)" = waiting ] || fail "B is $(field "$B" state) after A's retry, not waiting"
[ "$(field "$C" state)" = waiting ] || fail "C is $(field "$C" state) after A's retry, not waiting"
release go
c_done() { [ "$(field "$C" state)" = done ]; }
wait_for c_done || fail "C did not finish"
# Each started only once the one it waits for was done.
for pair in "$A $B" "$B $C"; do
  read -r first then <<<"$pair"
  finished=$(field "$first" finished_ms)
  started=$(field "$then" started_ms)
  [ "$started" -ge "$finished" ] || fail "$then started at $started, before $first was done at $finished"
done
echo "PASS"
