#!/usr/bin/env bash
# A webhook receiver that never answers does not hold up the farm: its socket takes connections and never reads them,
# deliveries wait up to --webhook-timeout-seconds (600), so every sender thread hangs on one while 24 jobs are
# submitted, rendered and done. No delivery attempt has ended when the last job is done (the sends are still hung),
# yet every job finished and the delivery log lists an event per job, still pending.
source "$(dirname "$0")/common.sh"

python3 - "$WORK/port" >"$WORK/blackhole.log" 2>&1 <<'PY' &
import socket, sys, time
s = socket.socket()
s.bind(("127.0.0.1", 0))
s.listen(1024)  # never accepted: the kernel completes the connections, nobody answers
open(sys.argv[1] + ".tmp", "w").write(str(s.getsockname()[1]))
import os
os.rename(sys.argv[1] + ".tmp", sys.argv[1])
time.sleep(3600)
PY
PIDS+=("$!")
wait_for test -s "$WORK/port" || fail "the silent receiver did not start"
start_serve --webhook "http://127.0.0.1:$(cat "$WORK/port")/hook" --webhook-timeout-seconds 600
write_sphere_scene "$WORK/s.json" 16 16 1
start_worker w --threads 1
JOBS=()
for i in $(seq 24); do
  JOBS+=("$("$TESSERA" submit "$WORK/s.json" --coordinator "$URL" --tile 16 --detach 2>>"$WORK/submit.log")") \
    || fail "submit $i failed"
done
all_done() { [ "$("$TESSERA" jobs ls --state done --coordinator "$URL" 2>/dev/null | grep -c ' done ')" = 24 ]; }
wait_for all_done || fail "the jobs did not all finish while the webhook receiver hung"
curl -sS -f "$URL/v1/webhooks/deliveries" >"$WORK/deliveries.json" || fail "GET /v1/webhooks/deliveries failed"
python3 - "$WORK/deliveries.json" <<'PY' || fail "the delivery log is not 24 pending, unanswered deliveries: $(head -c 600 "$WORK/deliveries.json")"
import json, sys
rows = json.load(open(sys.argv[1]))["deliveries"]
assert len(rows) == 24, len(rows)
assert all(d["event"] == "job.done" and d["state"] == "pending" and d["attempts"] == 0 for d in rows), rows
PY
echo "PASS"
