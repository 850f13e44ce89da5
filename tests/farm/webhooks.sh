#!/usr/bin/env bash
# Webhooks delivered at least once, exactly once after de-duplication: a local receiver checks every delivery's
# signature and answers 500 to its first two. Job A's end is committed with its outbox row, then the coordinator is
# SIGKILLed while the sender holds the delivery (fail point webhook.deliver); restarted on the same data folder, it
# delivers it (after the two 500s, with backoff). Job B names its own address (submit --notify, allowed by
# --webhook-allow) and is cancelled: both addresses hear it under one event id. Job C waits for B and is blocked at
# submission: job.blocked. Sequence D asks for its frames too (submit --notify URL --notify-frames): its address hears
# frame.done for each frame, then job.done; --notify-frames without --notify is refused. An address outside the
# allow-list is refused at submission. GET /v1/webhooks/deliveries lists each delivery with its attempts and last
# answer.
source "$(dirname "$0")/common.sh"

echo "test-secret-$$" >"$WORK/secret"
python3 "$(dirname "$0")/webhook_receiver.py" "$WORK/port" "$WORK/received.jsonl" "test-secret-$$" 2 \
  >"$WORK/receiver.log" 2>&1 &
PIDS+=("$!")
wait_for test -s "$WORK/port" || fail "the receiver did not start"
HOOK="http://127.0.0.1:$(cat "$WORK/port")"
SERVE_FLAGS=(--webhook "$HOOK/farm" --webhook-allow "$HOOK/jobs/" --webhook-secret-file "$WORK/secret"
             --webhook-retry-seconds 0.2)

write_sphere_scene "$WORK/s.json" 16 16 1
for n in 1 2; do write_sphere_scene "$WORK/f_$n.json" 16 16 1; done
FAIL_POINTS="webhook.deliver=pause($WORK/never)" start_serve "${SERVE_FLAGS[@]}"
ADDRESS=$(head -n1 "$WORK/ready")
A=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 16 --detach 2>>"$WORK/submit.log") || fail "submit A"
start_worker w --threads 1
wait_for paused "$WORK/serve.log" webhook.deliver || fail "the sender did not reach its delivery of A's end"
kill -KILL "$SERVE_PID"
wait "$SERVE_PID" 2>/dev/null || true
[ ! -s "$WORK/received.jsonl" ] || fail "a delivery went out before the kill"

LISTEN=$ADDRESS start_serve "${SERVE_FLAGS[@]}"
expect_exit 2 "$WORK/refused.log" -- "$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --notify "http://evil.example/x" --detach
log_has "$WORK/refused.log" "webhook address 'http://evil.example/x' is not allowed" \
  || fail "an address outside the allow-list was not refused with a sentence"
# B is cancelled before the worker (stopped meanwhile) can take it; C waits for B, so it is blocked at once.
kill -STOP "$WORKER_PID"
B=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 16 --notify "$HOOK/jobs/b" --detach 2>>"$WORK/submit.log") \
  || fail "submit B"
"$TESSERA" jobs cancel "$B" --coordinator "$URL" >"$WORK/cancel.log" 2>&1 || fail "jobs cancel B"
C=$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 16 --after "$B" --detach 2>>"$WORK/submit.log") \
  || fail "submit C"
kill -CONT "$WORKER_PID"
D=$("$TESSERA" submit "$WORK/f_#.json" --frames 1-2 --coordinator "$URL" --tile 16 --notify "$HOOK/jobs/d" \
      --notify-frames --detach 2>>"$WORK/submit.log") || fail "submit D"
expect_exit 2 "$WORK/frames-refused.log" -- "$TESSERA" submit "$WORK/f_#.json" --frames 1-2 --coordinator "$URL" \
  --notify-frames --detach
log_has "$WORK/frames-refused.log" "'notify_frames' needs 'notify'" || fail "--notify-frames without --notify was not refused"

# Every event once after de-duplication by (id, address); every signature right; the ids in the header and body agree.
summary() {
  python3 - "$WORK/received.jsonl" <<'PY'
import collections, json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
bad = [r for r in rows if not r["signature_ok"] or r["id"] != r["header_id"]]
ok = {(r["id"], r["path"]): r for r in rows if r["answered"] == 200}
events = collections.Counter((r["event"], r["job"], r["path"]) for r in ok.values())
print(len(bad), len(rows), " ".join(sorted(f"{e}:{j}:{p}:{n}" for (e, j, p), n in events.items())))
PY
}
want=$(printf '%s\n' "job.blocked:$C:/farm:1" "job.cancelled:$B:/farm:1" "job.cancelled:$B:/jobs/b:1" \
  "job.done:$A:/farm:1" "frame.done:$D.f1:/jobs/d:1" "frame.done:$D.f2:/jobs/d:1" "job.done:$D:/farm:1" \
  "job.done:$D:/jobs/d:1" | LC_ALL=C sort | paste -sd' ')
all_heard() { [ "$(summary | cut -d' ' -f3-)" = "$want" ]; }
wait_for all_heard || fail "the receiver heard $(summary), not: $want"
read -r BAD TOTAL _ <<<"$(summary)"
[ "$BAD" = 0 ] || fail "$BAD deliveries had a wrong signature or id"
[ "$TOTAL" = 10 ] || fail "$TOTAL requests for 8 deliveries and two 500s, not 10"
python3 - "$WORK/received.jsonl" "$B" <<'PY' || fail "B's two deliveries do not share one event id"
import json, sys
ids = {json.loads(l)["id"] for l in open(sys.argv[1]) if json.loads(l)["job"] == sys.argv[2]}
sys.exit(len(ids) != 1)
PY
log_has "$WORK/received.jsonl" "\"result\": \"/v1/jobs/$A/result.exr\"" || fail "A's event has no result link"
log_has "$WORK/received.jsonl" "\"result\": \"/v1/jobs/$D/frames/2/result.exr\"" \
  || fail "D's frame.done has no link to the frame's result"

curl -sS -f "$URL/v1/webhooks/deliveries" >"$WORK/deliveries.json" || fail "GET /v1/webhooks/deliveries failed"
python3 - "$WORK/deliveries.json" "$TOTAL" <<'PY' || fail "the delivery log does not account for every attempt: $(cat "$WORK/deliveries.json")"
import json, sys
rows = json.load(open(sys.argv[1]))["deliveries"]
assert len(rows) == 8, rows
assert all(d["state"] == "delivered" and d["last_status"] == 200 and d["next_ms"] is None for d in rows), rows
# Each request the receiver took is one attempt: the two answered 500 were tried again.
assert sum(d["attempts"] for d in rows) == int(sys.argv[2]) == 10, rows
PY
echo "PASS"
