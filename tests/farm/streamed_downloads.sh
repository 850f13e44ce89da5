#!/usr/bin/env bash
# Downloads are streamed from disk in pieces: four clients that ask for a 128 MiB blob and never read past its header
# raise the coordinator's memory (VmRSS) by far less than one copy of the blob (the bound is 64 MB; reading the blob
# whole per connection would cost 512 MB), /healthz answers meanwhile, and a client that reads gets every byte.
# The same holds for a job's result (the same path, server/file_stream.h).
source "$(dirname "$0")/common.sh"

start_serve --max-blob-bytes 200000000
head -c $((128 << 20)) /dev/urandom >"$WORK/blob"
SHA=$(sha256sum "$WORK/blob" | cut -d' ' -f1)
code=$(curl -s -o "$WORK/put.json" -w '%{http_code}' -X PUT --data-binary @"$WORK/blob" \
  -H 'Content-Type: application/octet-stream' "$URL/v1/blobs/$SHA")
[ "$code" = 201 ] || fail "the blob upload answered $code: $(cat "$WORK/put.json")"
len=$(curl -sI "$URL/v1/blobs/$SHA" | tr -d '\r' | awk -F': ' 'tolower($1)=="content-length"{print $2}')
[ "$len" = $((128 << 20)) ] || fail "HEAD says Content-Length '$len', not $((128 << 20))"

rss_kb() { awk '/^VmRSS:/{print $2}' "/proc/$SERVE_PID/status"; }
BEFORE=$(rss_kb)

# Four connections ask for the blob, read the status line, and stop reading until $WORK/close exists.
python3 - "${URL#http://}" "$SHA" "$WORK" <<'PY' &
import os, socket, sys, time
host, port = sys.argv[1].rsplit(":", 1)
held = []
for _ in range(4):
    s = socket.create_connection((host, int(port)))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.sendall(f"GET /v1/blobs/{sys.argv[2]} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
    first = s.recv(64)
    assert first.startswith(b"HTTP/1.1 200"), first
    held.append(s)
open(os.path.join(sys.argv[3], "held"), "w").close()
while not os.path.exists(os.path.join(sys.argv[3], "close")):
    time.sleep(0.05)
PY
HOLDER=$!
PIDS+=("$HOLDER")
wait_for test -e "$WORK/held" || fail "the four downloads did not start"
curl -sf -o /dev/null "$URL/healthz" || fail "/healthz does not answer while four downloads are held"
AFTER=$(rss_kb)
GROWTH=$(((AFTER - BEFORE) / 1024))
echo "coordinator VmRSS: $((BEFORE / 1024)) MB before, $((AFTER / 1024)) MB with four unread 128 MiB downloads"
[ "$GROWTH" -lt 64 ] || fail "four unread downloads raised the coordinator's memory by $GROWTH MB (bound 64 MB)"
touch "$WORK/close"
wait "$HOLDER" || fail "the holding client failed"

curl -sf -o "$WORK/got" "$URL/v1/blobs/$SHA" || fail "the blob download failed"
[ "$(sha256sum "$WORK/got" | cut -d' ' -f1)" = "$SHA" ] || fail "the downloaded blob differs from the upload"
echo PASS
