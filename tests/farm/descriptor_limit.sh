#!/usr/bin/env bash
# The connection limit fits the descriptor limit: a coordinator started with 128 open files at most (hard limit) and
# the default --max-connections 1024 says so and serves at most 64 connections (64 descriptors kept for the database
# and files). Keep-alive connections up to that limit are held; the next is answered 503 at once, no accept fails, and once
# they close /healthz answers again.
source "$(dirname "$0")/common.sh"

(ulimit -n 128 && exec "$TESSERA" serve --listen 127.0.0.1:0 --ready-file "$WORK/ready" --data "$WORK/data") \
  >>"$WORK/serve.log" 2>&1 &
SERVE_PID=$!
PIDS+=("$SERVE_PID")
wait_for test -s "$WORK/ready" || fail "the coordinator did not become ready"
URL="http://$(head -n1 "$WORK/ready")"
log_has "$WORK/serve.log" "--max-connections 1024 does not fit the limit of 128 open files .*serving at most 64 connections" \
  || fail "the coordinator did not lower its connection limit to the descriptors it has"

# 64 keep-alive connections, each after one answered request, held open by one Python process until $WORK/close exists.
python3 - "${URL#http://}" "$WORK" <<'PY' &
import os, socket, sys, time
host, port = sys.argv[1].rsplit(":", 1)
held = []
for _ in range(64):
    s = socket.create_connection((host, int(port)))
    s.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")  # a request answered: not an idle connection to displace
    assert s.recv(4096).startswith(b"HTTP/1.1 200")
    held.append(s)
open(os.path.join(sys.argv[2], "held"), "w").close()
while not os.path.exists(os.path.join(sys.argv[2], "close")):
    time.sleep(0.05)
PY
HOLDER=$!
PIDS+=("$HOLDER")
wait_for test -e "$WORK/held" || fail "the 64 connections were not made"
refused() { curl -s -o "$WORK/over.json" -w '%{http_code}' "$URL/healthz" | grep -q 503; }
wait_for refused || fail "a connection over the limit was not answered 503: $(cat "$WORK/over.json")"
log_has "$WORK/over.json" "too many connections" || fail "the 503 does not say why: $(cat "$WORK/over.json")"
touch "$WORK/close"
wait "$HOLDER"
healthy() { curl -sf -o /dev/null "$URL/healthz"; }
wait_for healthy || fail "/healthz does not answer once the connections closed"
log_has "$WORK/serve.log" "accept failed" && fail "an accept failed: $(grep 'accept failed' "$WORK/serve.log" | head -3)"
echo PASS
