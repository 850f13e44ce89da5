#!/usr/bin/env bash
# Token refusals are rate-limited per address: with --max-refusals-per-minute 5, five requests with a wrong token get
# 401, and the next connection from the same address gets 429 with Retry-After and a sentence, before its request is
# read, while the coordinator keeps serving: its log says so in a bounded number of lines.
source "$(dirname "$0")/common.sh"

head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/client.token"
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$WORK/worker.token"
chmod 600 "$WORK/client.token" "$WORK/worker.token"
start_serve --client-token-file "$WORK/client.token" --worker-token-file "$WORK/worker.token" --max-refusals-per-minute 5

status() { curl -s -o "$WORK/answer.json" -D "$WORK/headers" -w '%{http_code}' -H "Authorization: Bearer $1" "$URL/v1/jobs"; }
for i in 1 2 3 4 5; do
  code=$(status wrong-token-of-twenty-chars)
  [ "$code" = 401 ] || fail "wrong token $i answered $code, not 401: $(cat "$WORK/answer.json")"
done
code=$(status wrong-token-of-twenty-chars)
[ "$code" = 429 ] || fail "the sixth wrong token answered $code, not 429: $(cat "$WORK/answer.json")"
log_has "$WORK/answer.json" "too many refused credentials from 127.0.0.1" || fail "the 429 does not say why: $(cat "$WORK/answer.json")"
grep -qi '^retry-after: [1-9]' "$WORK/headers" || fail "the 429 has no Retry-After: $(cat "$WORK/headers")"
# The probe that needs no token still answers from another address (::1 when the coordinator listens there is not
# needed: /healthz from the same address is refused too, which is the point of a per-address limit).
code=$(curl -s -o /dev/null -w '%{http_code}' "$URL/healthz")
[ "$code" = 429 ] || fail "/healthz from the blocked address answered $code, not 429"
kill -0 "$SERVE_PID" || fail "the coordinator died"
echo PASS
